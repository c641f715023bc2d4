"""EMPS-format runs: a validation-like template that the .mat reader takes as published."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.emps_runs import main
from twin_cosim.measured import read_measured


def test_template_is_a_bang_bang_run_with_pulses(tmp_path):
    out = tmp_path / "template.mat"
    assert main(["--out", str(out), "--seed", "3", "--duration", "8"]) == 0
    run = read_measured(out)
    assert run.t[-1] >= 8.0 and run.period == pytest.approx(1e-3)
    acceleration = np.diff(run.x_ref, 2) / run.period**2
    accelerating = np.abs(acceleration[np.abs(acceleration) > 1e-6])
    at_limit = np.abs(accelerating - 0.8) < 1e-3  # bang-bang: +/- the limit, or coasting
    assert at_limit.mean() > 0.95  # the rest: samples that straddle a switch
    pulses = run.record["pulses_N"]
    assert set(np.unique(pulses)) == {-3.0, 0.0, 3.0}
    assert {"kp", "kv", "gtau"} <= set(run.scalars)


def test_an_existing_file_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "template.mat"
    out.write_text("a measured run")
    with pytest.raises(SystemExit):
        main(["--out", str(out)])
    assert "the file exists" in capsys.readouterr().err
    assert out.read_text() == "a measured run"
