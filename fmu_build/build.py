"""Build a plant FMU from ``models/<name>``: generate, compile with the system gcc, zip.

The same C sources build an FMI 2.0 or an FMI 3.0 co-simulation FMU: the model and the shared
slave (``models/common/slave.c``) with the API file of the version (``fmi2_slave.c`` or
``fmi3_slave.c``), described by the same variable table.

The FMU is rebuilt only when an input changed: the model's sources, the shared C code, the
variable and unit tables, this package, the FMI headers, the compiler flags or the FMI version.
A fingerprint of all of them names the build.

Where things are:

- the C sources: ``models/`` of a source checkout, or ``fmu_build/models/`` inside an installed
  wheel (pyproject.toml maps the one onto the other);
- the FMUs: by default in a per-user cache, ``$TWIN_COSIM_CACHE`` or else
  ``$XDG_CACHE_HOME/twin-cosim`` (``~/.cache/twin-cosim``), as
  ``fmu/<model>-<fingerprint>/<file>``, so that several checkouts or versions of the project
  share it without overwriting each other's FMUs; or ``<out>/<file>`` with its fingerprint in
  ``<file>.sha256`` when an output folder is given. The file is ``<model>.fmu`` for FMI 2.0 and
  ``<model>-fmi3.fmu`` for FMI 3.0 (:func:`fmu_file_name`), so both versions sit side by side.

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
DEFAULT_FMI_VERSION = 2
# The folder of the binary inside the FMU, per FMI version (the platform's name in each).
BINARY_FOLDERS = {2: "linux64", 3: "x86_64-linux"}
FMI_VERSIONS = tuple(BINARY_FOLDERS)
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


def _check_version(fmi_version: int) -> None:
    if fmi_version not in FMI_VERSIONS:
        raise BuildError(
            f"FMI version {fmi_version!r} is not supported: expected one of {list(FMI_VERSIONS)}"
        )


def fmi_headers_dir(fmi_version: int = DEFAULT_FMI_VERSION) -> Path:
    """The FMI headers of a version that the installed fmpy ships (``fmpy/c-code``), found
    without importing fmpy (a command that finds its FMU built does not load it)."""
    _check_version(fmi_version)
    spec = importlib.util.find_spec("fmpy")
    if spec is None or not spec.submodule_search_locations:
        raise BuildError(f"fmpy is not installed: its FMI {fmi_version}.0 headers are needed")
    path = Path(spec.submodule_search_locations[0]) / "c-code"
    header = f"fmi{fmi_version}Functions.h"
    if not (path / header).is_file():
        raise BuildError(f"{path}: {header} not found; is fmpy installed completely?")
    return path


def fmu_file_name(model: str, fmi_version: int = DEFAULT_FMI_VERSION) -> str:
    """``<model>.fmu`` for FMI 2.0, ``<model>-fmi3.fmu`` for FMI 3.0."""
    _check_version(fmi_version)
    return f"{model}.fmu" if fmi_version == 2 else f"{model}-fmi{fmi_version}.fmu"


def binary_path(model: str, fmi_version: int = DEFAULT_FMI_VERSION) -> str:
    """Path of the shared library inside the FMU: ``binaries/<platform>/<model>.so``."""
    _check_version(fmi_version)
    return f"binaries/{BINARY_FOLDERS[fmi_version]}/{model}.so"


def available_models() -> list[str]:
    """Names of the models under ``models/`` (folders with a variables.yaml)."""
    return sorted(p.parent.name for p in MODELS_DIR.glob("*/variables.yaml"))


def _model_dir(model: str) -> Path:
    path = MODELS_DIR / model
    if not (path / "variables.yaml").is_file():
        raise BuildError(f"unknown model {model!r}: expected one of {available_models()}")
    return path


def _c_sources(model_dir: Path, fmi_version: int) -> list[Path]:
    """The C files of one version's binary: models/common's, without the other versions' API
    files (``fmi<N>_slave.c``), then the model's."""
    other_apis = {f"fmi{v}_slave.c" for v in FMI_VERSIONS if v != fmi_version}
    common = [p for p in sorted(COMMON_DIR.glob("*.c")) if p.name not in other_apis]
    return common + sorted(model_dir.glob("*.c"))


def _c_headers(model_dir: Path) -> list[Path]:
    return sorted(COMMON_DIR.glob("*.h")) + sorted(model_dir.glob("*.h"))


def _inputs(model_dir: Path, fmi_version: int) -> list[Path]:
    sources = _c_sources(model_dir, fmi_version) + _c_headers(model_dir)
    tables = [model_dir / "variables.yaml", COMMON_DIR / "units.yaml", model_dir / "README.md"]
    tools = sorted(Path(__file__).parent.glob("*.py"))
    headers = sorted(fmi_headers_dir(fmi_version).glob(f"fmi{fmi_version}*.h"))
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


def fingerprint(model: str, fmi_version: int = DEFAULT_FMI_VERSION) -> str:
    """SHA-256 over every input of the build, the compiler flags and the FMI version."""
    digest = hashlib.sha256(" ".join(CFLAGS).encode())
    digest.update(f"FMI {fmi_version}".encode())
    for path in _inputs(_model_dir(model), fmi_version):
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
    fmi_version: int = DEFAULT_FMI_VERSION,
) -> Path:
    """Build the FMU of ``model`` unless an identical build already exists.

    Parameters
    ----------
    model
        Name of a folder under ``models/``.
    out_dir
        Where the FMU (:func:`fmu_file_name`) goes; None: the per-user cache (:func:`cache_dir`),
        in a folder named by the fingerprint of the sources.
    force
        Rebuild even when the fingerprint matches.
    announce
        Say on stderr when the FMU is compiled (for builds the user did not ask for).
    fmi_version
        2 (FMI 2.0) or 3 (FMI 3.0) co-simulation.

    Returns
    -------
    Path
        The .fmu file.
    """
    model_dir = _model_dir(model)
    current = fingerprint(model, fmi_version)
    file_name = fmu_file_name(model, fmi_version)
    if out_dir is None:
        fmu_path = cache_dir() / "fmu" / f"{model}-{current[:16]}" / file_name
        stamp = None
        up_to_date = fmu_path.is_file()
    else:
        fmu_path = Path(out_dir) / file_name
        stamp = fmu_path.with_suffix(".fmu.sha256")
        up_to_date = fmu_path.is_file() and stamp.is_file() and stamp.read_text() == current
    if up_to_date and not force:
        return fmu_path
    if announce:
        option = "" if fmi_version == DEFAULT_FMI_VERSION else f" --fmi {fmi_version}"
        print(
            f"twin: building the {model} FMU (FMI {fmi_version}.0) from its C sources (once per "
            f"source version; 'twin build {model}{option}' does it ahead): {fmu_path}",
            file=sys.stderr,
        )
    _write_atomically(fmu_path, _pack(model, model_dir, fmi_version))
    if stamp is not None:
        _write_atomically(stamp, current.encode())
    return fmu_path


def _pack(model: str, model_dir: Path, fmi_version: int) -> bytes:
    """Generate, compile and zip the FMU of ``model`` for an FMI version; the archive's bytes."""
    from fmu_build import generate
    from fmu_build.model_description import build_description, model_description
    from fmu_build.variable_table import load_variable_table

    table = load_variable_table(model_dir / "variables.yaml", COMMON_DIR / "units.yaml")
    readme = model_dir / "README.md"
    c_sources = _c_sources(model_dir, fmi_version)
    source_names = [p.name for p in c_sources]
    with tempfile.TemporaryDirectory(prefix=f"{model}-fmu-") as tmp:
        staging = Path(tmp) / "fmu"
        sources_dir = staging / "sources"
        binary = staging / binary_path(model, fmi_version)
        docs_dir = staging / "documentation"
        for folder in (sources_dir, binary.parent, docs_dir):
            folder.mkdir(parents=True)
        for path in c_sources + _c_headers(model_dir):
            shutil.copy(path, sources_dir / path.name)
        (sources_dir / "model_variables.h").write_text(generate.variables_header(table))
        (sources_dir / "model_variable_table.h").write_text(generate.variable_table_header(table))
        if fmi_version == 3:
            build_xml = build_description(table, source_names)
            (sources_dir / "buildDescription.xml").write_text(build_xml)
        (staging / "modelDescription.xml").write_text(
            model_description(table, source_names, fmi_version)
        )
        readme_text = readme.read_text() if readme.exists() else table.description
        (docs_dir / "index.html").write_text(generate.documentation_html(table, readme_text))
        _compile(
            table,
            [sources_dir / name for name in source_names],
            [sources_dir, fmi_headers_dir(fmi_version)],
            binary,
        )
        archive_path = Path(tmp) / fmu_file_name(model, fmi_version)
        with zipfile.ZipFile(archive_path, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(staging.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(staging).as_posix())
        return archive_path.read_bytes()
