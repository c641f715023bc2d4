"""The painter: a forked process draws the figure while its command works, and ends with it."""

from __future__ import annotations

import os
import subprocess
import sys
from functools import partial
from pathlib import Path

import pytest

from twin_cosim.painter import Painter, draw_side_by_side

ROOT = Path(__file__).resolve().parents[2]


def _write(path: Path, text: str) -> None:
    """A stand-in figure: ``text`` written to ``path``."""
    path.write_text(text)


def _fail(path: Path) -> None:
    raise ValueError(f"{path}: cannot draw this")


def test_the_figure_is_drawn_by_the_painter_and_it_is_gone_after(tmp_path):
    painter = Painter.start()
    pid = painter.pid
    assert painter.draw(f"{__name__}:_write", tmp_path / "f.txt", "drawn")
    assert (tmp_path / "f.txt").read_text() == "drawn"
    assert pid is not None and painter.pid is None
    assert not os.path.exists(f"/proc/{pid}")  # reaped, not a zombie


def _prepare(text: str) -> str:
    """A stand-in preparation: what the figure is drawn from, made before the figure."""
    return text.upper()


def _write_prepared(prepared: str, path: Path, suffix: str) -> None:
    path.write_text(prepared + suffix)


def _fail_to_prepare(text: str) -> str:
    raise ValueError(f"cannot prepare {text}")


@pytest.mark.parametrize("forked", [True, False])
def test_what_is_prepared_reaches_the_drawing_function_first(tmp_path, monkeypatch, forked):
    if not forked:  # a platform without os.fork: the painter is this process
        monkeypatch.delattr(os, "fork")
    painter = Painter.start()
    assert (painter.pid is not None) == forked
    painter.prepare(f"{__name__}:_prepare", "early data")
    assert painter.draw(f"{__name__}:_write_prepared", tmp_path / "f.txt", "!")
    assert (tmp_path / "f.txt").read_text() == "EARLY DATA!"


def test_a_failed_preparation_is_said_and_the_figure_reported_missing(tmp_path, capfd):
    painter = Painter.start()
    painter.prepare(f"{__name__}:_fail_to_prepare", "this")
    assert not painter.draw(f"{__name__}:_write_prepared", tmp_path / "f.txt", "!")
    assert "the figure was not drawn: cannot prepare this" in capfd.readouterr().err
    assert not (tmp_path / "f.txt").exists()


def test_a_painter_closed_after_a_preparation_ends_without_drawing(tmp_path):
    painter = Painter.start()
    pid = painter.pid
    painter.prepare(f"{__name__}:_prepare", "x")
    painter.close()
    assert not os.path.exists(f"/proc/{pid}")


def test_a_painter_closed_without_a_figure_ends_without_drawing():
    painter = Painter.start()
    pid = painter.pid
    painter.close()
    assert not os.path.exists(f"/proc/{pid}")


def test_a_failed_drawing_is_said_and_reported(tmp_path, capfd):
    painter = Painter.start()
    assert not painter.draw(f"{__name__}:_fail", tmp_path / "f.png")
    assert "the figure was not drawn" in capfd.readouterr().err


def test_figures_side_by_side_are_all_drawn(tmp_path):
    draw_side_by_side(
        partial(_write, tmp_path / "a.txt", "first"), partial(_write, tmp_path / "b.txt", "second")
    )
    assert (tmp_path / "a.txt").read_text() == "first"
    assert (tmp_path / "b.txt").read_text() == "second"


def test_a_figure_failing_beside_another_is_said_and_raised(tmp_path, capfd):
    with pytest.raises(RuntimeError, match="1 of 2 figures"):
        draw_side_by_side(partial(_fail, tmp_path / "a.png"), partial(_write, tmp_path / "b", "x"))
    assert "a.png: cannot draw this" in capfd.readouterr().err
    assert (tmp_path / "b").read_text() == "x"  # the other one is drawn all the same


def test_simulate_draws_run_png_without_matplotlib_in_its_process(tmp_path):
    code = (
        "import sys\n"
        "from twin_cosim.cli import main\n"
        f"code = main(['simulate', 'reference1', '--out', {str(tmp_path)!r}])\n"
        "print(code, sorted({'matplotlib', 'pandas'} & set(sys.modules)))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "0 []"
    assert (tmp_path / "run.png").read_bytes()[:4] == b"\x89PNG"
    assert "run.png" in done.stdout
