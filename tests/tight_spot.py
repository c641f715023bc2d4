"""A defect outside every FMU of the project, for blind tests (the tests' and
benchmarks/blind_gap.py's): a patched copy of a model built at run time.

:func:`build_tight_spot_fmu` copies the drive2mass sources, wraps its position factor of the
friction levels in a raised-friction bump (a tight spot of a guideway)

    factor(x) = (1 + a exp(-((x - x0) / w)^2)) x original factor,

x the carriage position (m), and builds that copy into an FMU with the same model identifier, so
that ``twin synth --plant`` makes a machine the twin has no block for. The diagnosis must not
name a library effect as its cause, and should locate it along the axis.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from fmu_build import build

SIGNATURE = "static double friction_position_factor(const ModelVariables *v, double load_angle) {"


def _patched_source(source: str, amplitude: float, centre: float, width: float) -> str:
    """drive2mass's model.c with the tight spot wrapped around its friction position factor."""
    start = source.find(SIGNATURE)
    if start < 0:
        raise ValueError("drive2mass model.c: friction_position_factor not found")
    end = source.index("\n}\n", start) + 3
    original = source[start:end].replace(
        "friction_position_factor(", "untouched_friction_position_factor(", 1
    )
    bump = (
        f"{SIGNATURE}\n"
        f"    const double spot = (load_angle * travel_per_rad(v) - "
        f"({centre!r})) / ({width!r});\n"
        f"    return (1.0 + ({amplitude!r}) * exp(-spot * spot)) *\n"
        f"           untouched_friction_position_factor(v, load_angle);\n"
        "}\n"
    )
    return source[:start] + original + "\n" + bump + source[end:]


def build_tight_spot_fmu(amplitude: float, centre: float, width: float, out_dir: Path) -> Path:
    """Build drive2mass with a tight spot into ``out_dir`` and return the .fmu.

    Parameters
    ----------
    amplitude : float
        Relative rise of the friction levels at the centre of the spot (0.5: 50 % more).
    centre : float
        Carriage position of the spot, m.
    width : float
        Half width of the bump (1/e of its height), m.
    out_dir : Path
        Folder of the FMU.
    """
    if amplitude <= -1.0 or width <= 0.0:
        raise ValueError("tight spot: amplitude must exceed -1 and width be positive")
    with tempfile.TemporaryDirectory(prefix="tight-spot-") as tmp:
        models = Path(tmp) / "models"
        shutil.copytree(build.MODELS_DIR, models)
        model_c = models / "drive2mass" / "model.c"
        model_c.write_text(_patched_source(model_c.read_text(), amplitude, centre, width))
        saved = build.MODELS_DIR, build.COMMON_DIR
        build.MODELS_DIR, build.COMMON_DIR = models, models / "common"
        try:
            return build.build_fmu("drive2mass", Path(out_dir), force=True)
        finally:
            build.MODELS_DIR, build.COMMON_DIR = saved
