"""Build a plant FMU from ``models/<name>``: generate, compile with the system gcc, zip.

The FMU is rebuilt only when an input changed: the model's sources, the shared C code, the
variable and unit tables, this package, the FMI headers or the compiler flags. A fingerprint of
all of them is stored next to the .fmu.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

import fmpy

from fmu_build import generate
from fmu_build.variable_table import VariableTable, load_variable_table

REPO_ROOT = Path(__file__).resolve().parents[1]
MODELS_DIR = REPO_ROOT / "models"
COMMON_DIR = MODELS_DIR / "common"
DEFAULT_OUT_DIR = REPO_ROOT / "build"
DEFAULT_MODEL = "drive2mass"
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
    """The FMI 2.0 headers that the installed fmpy ships (``fmpy/c-code``)."""
    path = Path(fmpy.__file__).parent / "c-code"
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


def build_fmu(model: str = DEFAULT_MODEL, out_dir: Path | None = None, force: bool = False) -> Path:
    """Build ``<out_dir>/<model>.fmu`` unless an identical build already exists.

    Parameters
    ----------
    model
        Name of a folder under ``models/``.
    out_dir
        Where the .fmu goes; ``build/`` at the repository root by default.
    force
        Rebuild even when the fingerprint matches.

    Returns
    -------
    Path
        The .fmu file.
    """
    model_dir = _model_dir(model)
    out_dir = Path(out_dir) if out_dir is not None else DEFAULT_OUT_DIR
    fmu_path = out_dir / f"{model}.fmu"
    stamp = fmu_path.with_suffix(".fmu.sha256")
    current = fingerprint(model)
    if not force and fmu_path.is_file() and stamp.is_file() and stamp.read_text() == current:
        return fmu_path
    table = load_variable_table(model_dir / "variables.yaml", COMMON_DIR / "units.yaml")
    readme = model_dir / "README.md"
    with tempfile.TemporaryDirectory(prefix=f"{model}-fmu-") as tmp:
        staging = Path(tmp)
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
        out_dir.mkdir(parents=True, exist_ok=True)
        partial = fmu_path.with_suffix(".fmu.partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(staging.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(staging).as_posix())
        partial.replace(fmu_path)
    stamp.write_text(current)
    return fmu_path
