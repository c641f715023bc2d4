"""Build a plant FMU from ``models/<name>``: generate, compile with the system gcc, zip.

The FMU is rebuilt only when an input changed: the model's sources, the shared C code, the
variable and unit tables, this package, the FMI headers or the compiler flags. A fingerprint of
all of them names the build.

Where things are:

- the C sources: ``models/`` of a source checkout, or ``fmu_build/models/`` inside an installed
  wheel (pyproject.toml maps the one onto the other);
- the FMUs: by default in a per-user cache, ``$TWIN_COSIM_CACHE`` or else
  ``$XDG_CACHE_HOME/twin-cosim`` (``~/.cache/twin-cosim``), as
  ``fmu/<model>-<fingerprint>/<model>.fmu``, so that several checkouts or versions of the
  project share it without overwriting each other's FMUs; or ``<out>/<model>.fmu`` with its
  fingerprint in ``<model>.fmu.sha256`` when an output folder is given.

Every file is written under a unique temporary name and renamed into place (atomic on POSIX), so
that concurrent builds of the same model never expose a partial FMU.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmu_build.variable_table import VariableTable


def _models_dir() -> Path:
    """``fmu_build/models`` in an installed wheel, else ``models/`` of the source checkout."""
    packaged = Path(__file__).resolve().parent / "models"
    return packaged if packaged.is_dir() else Path(__file__).resolve().parents[1] / "models"


MODELS_DIR = _models_dir()
COMMON_DIR = MODELS_DIR / "common"
DEFAULT_MODEL = "drive2mass"
CACHE_ENV = "TWIN_COSIM_CACHE"
CFLAGS = (
    "-std=c99",
    "-O2",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-pedantic",
    "-fPIC",
    "-shared",
    "-fvisibility=hidden",
)


class BuildError(RuntimeError):
    """Generating, compiling or packing an FMU failed; the message says which step and why."""


def fmi_headers_dir() -> Path:
    """The FMI 2.0 headers that the installed fmpy ships (``fmpy/c-code``), found without
    importing fmpy (a command that finds its FMU built does not load it)."""
    spec = importlib.util.find_spec("fmpy")
    if spec is None or not spec.submodule_search_locations:
        raise BuildError("fmpy is not installed: its FMI 2.0 headers are needed")
    path = Path(spec.submodule_search_locations[0]) / "c-code"
    if not (path / "fmi2Functions.h").is_file():
        raise BuildError(f"{path}: fmi2Functions.h not found; is fmpy installed completely?")
    return path


def available_models() -> list[str]:
    """Names of the models under ``models/`` (folders with a variables.yaml)."""
    return sorted(p.parent.name for p in MODELS_DIR.glob("*/variables.yaml"))


def _model_dir(model: str) -> Path:
    path = MODELS_DIR / model
    if not (path / "variables.yaml").is_file():
        raise BuildError(f"unknown model {model!r}: expected one of {available_models()}")
    return path


def _inputs(model_dir: Path) -> list[Path]:
    sources = sorted(model_dir.glob("*.[ch]")) + sorted(COMMON_DIR.glob("*.[ch]"))
    tables = [model_dir / "variables.yaml", COMMON_DIR / "units.yaml", model_dir / "README.md"]
    tools = sorted(Path(__file__).parent.glob("*.py"))
    headers = sorted(fmi_headers_dir().glob("fmi2*.h"))
    return sources + [p for p in tables if p.exists()] + tools + headers


def cache_dir() -> Path:
    """The per-user folder of built FMUs: ``$TWIN_COSIM_CACHE``, else the XDG cache folder."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "twin-cosim"


def _write_atomically(path: Path, content: bytes) -> None:
    """Write ``content`` to a unique temporary file beside ``path``, then rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(content)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def fingerprint(model: str) -> str:
    """SHA-256 over every input of the build and the compiler flags."""
    digest = hashlib.sha256(" ".join(CFLAGS).encode())
    for path in _inputs(_model_dir(model)):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _compile(
    table: VariableTable, sources: list[Path], include_dirs: list[Path], output: Path
) -> None:
    command = ["gcc", *CFLAGS, *(f"-I{d}" for d in include_dirs), "-o", str(output)]
    command += [str(s) for s in sources] + ["-lm"]
    try:
        result = subprocess.run(command, capture_output=True, text=True, check=False)
    except FileNotFoundError as exc:
        raise BuildError(
            "gcc not found: install the system C compiler (apt-get install gcc)"
        ) from exc
    if result.returncode != 0:
        raise BuildError(f"compiling {table.name} failed:\n{result.stderr}")


def build_fmu(
    model: str = DEFAULT_MODEL,
    out_dir: Path | None = None,
    force: bool = False,
    announce: bool = False,
) -> Path:
    """Build the FMU of ``model`` unless an identical build already exists.

    Parameters
    ----------
    model
        Name of a folder under ``models/``.
    out_dir
        Where ``<model>.fmu`` goes; None: the per-user cache (:func:`cache_dir`), in a folder
        named by the fingerprint of the sources.
    force
        Rebuild even when the fingerprint matches.
    announce
        Say on stderr when the FMU is compiled (for builds the user did not ask for).

    Returns
    -------
    Path
        The .fmu file.
    """
    model_dir = _model_dir(model)
    current = fingerprint(model)
    if out_dir is None:
        fmu_path = cache_dir() / "fmu" / f"{model}-{current[:16]}" / f"{model}.fmu"
        stamp = None
        up_to_date = fmu_path.is_file()
    else:
        fmu_path = Path(out_dir) / f"{model}.fmu"
        stamp = fmu_path.with_suffix(".fmu.sha256")
        up_to_date = fmu_path.is_file() and stamp.is_file() and stamp.read_text() == current
    if up_to_date and not force:
        return fmu_path
    if announce:
        print(
            f"twin: building the {model} FMU from its C sources (once per source version; "
            f"'twin build {model}' does it ahead): {fmu_path}",
            file=sys.stderr,
        )
    _write_atomically(fmu_path, _pack(model, model_dir))
    if stamp is not None:
        _write_atomically(stamp, current.encode())
    return fmu_path


def _pack(model: str, model_dir: Path) -> bytes:
    """Generate, compile and zip the FMU of ``model``; the archive's bytes."""
    from fmu_build import generate
    from fmu_build.variable_table import load_variable_table

    table = load_variable_table(model_dir / "variables.yaml", COMMON_DIR / "units.yaml")
    readme = model_dir / "README.md"
    with tempfile.TemporaryDirectory(prefix=f"{model}-fmu-") as tmp:
        staging = Path(tmp) / "fmu"
        sources_dir = staging / "sources"
        binary_dir = staging / "binaries" / "linux64"
        docs_dir = staging / "documentation"
        for folder in (sources_dir, binary_dir, docs_dir):
            folder.mkdir(parents=True)
        c_sources = sorted(COMMON_DIR.glob("*.c")) + sorted(model_dir.glob("*.c"))
        for path in sorted(COMMON_DIR.glob("*.[ch]")) + sorted(model_dir.glob("*.[ch]")):
            shutil.copy(path, sources_dir / path.name)
        (sources_dir / "model_variables.h").write_text(generate.variables_header(table))
        (sources_dir / "model_variable_table.h").write_text(generate.variable_table_header(table))
        (staging / "modelDescription.xml").write_text(
            generate.model_description(table, [p.name for p in c_sources])
        )
        readme_text = readme.read_text() if readme.exists() else table.description
        (docs_dir / "index.html").write_text(generate.documentation_html(table, readme_text))
        _compile(
            table,
            [sources_dir / p.name for p in c_sources],
            [sources_dir, fmi_headers_dir()],
            binary_dir / f"{model}.so",
        )
        archive_path = Path(tmp) / f"{model}.fmu"
        with zipfile.ZipFile(archive_path, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(staging.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(staging).as_posix())
        return archive_path.read_bytes()
