"""Campaign figures: convergence with penalised evaluations apart."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")

from twin_cosim.optimize import outputs  # noqa: E402


def _campaign(folder, fitness_status, keys=None):
    folder.mkdir()
    keys = keys or [str(i) for i in range(len(fitness_status))]
    lines = [
        json.dumps({"key": k, "x": [0.0], "generation": 0, "fitness": f, "status": s})
        for k, (f, s) in zip(keys, fitness_status, strict=True)
    ]
    (folder / "evaluations.jsonl").write_text("\n".join(lines) + "\n")
    return folder


def test_penalised_evaluations_are_shown_apart(tmp_path, saved_figure):
    runs = [(2e6, "failed"), (40.0, "ok"), (1e6 + 30.0, "violation"), (12.0, "ok")]
    runs += [(50.0, "stopped"), (2e6, "unstable"), (9.5, "ok")]
    saved = saved_figure
    outputs.plot_convergence({"CMA-ES": _campaign(tmp_path / "c", runs)}, tmp_path / "c.png")
    main, apart = saved["fig"].axes
    low, high = main.get_ylim()
    assert high < 1e3 and low > 1.0  # the valid E_pk, not stretched by the penalties
    best = main.lines[0].get_ydata()
    assert list(best) == [40.0, 12.0, 9.5]
    marked = sorted(x for line in apart.lines for x in line.get_xdata())
    assert marked == [1, 3, 5, 6]  # failed, violation, stopped, unstable (evaluation numbers)
    assert [t.get_text() for t in apart.get_yticklabels()] == ["CMA-ES (4 of 7)"]


def test_a_campaign_without_a_valid_run_is_drawn_and_says_so(tmp_path):
    runs = [(2e6, "failed"), (50.0, "stopped"), (2e6, "unstable")]
    path = outputs.plot_convergence({"CE": _campaign(tmp_path / "c", runs)}, tmp_path / "c.png")
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_a_candidate_of_a_second_pass_counts_once_with_its_final_result(tmp_path, saved_figure):
    """Early stopping logs a candidate stopped in the first pass again when its second pass
    completes it: the optimizer was told it once."""
    runs = [(30.0, "ok"), (1e6, "stopped"), (2e6, "failed"), (25.0, "ok"), (20.0, "ok")]
    keys = ["a", "b", "c", "b", "d"]  # b: stopped, then evaluated to the end
    outputs.plot_convergence({"CE": _campaign(tmp_path / "c", runs, keys)}, tmp_path / "c.png")
    main, apart = saved_figure["fig"].axes
    assert [t.get_text() for t in apart.get_yticklabels()] == ["CE (1 of 4)"]
    assert list(main.lines[0].get_xdata()) == [1, 2, 4]  # b at its first place, ok
    assert list(main.lines[0].get_ydata()) == [30.0, 25.0, 20.0]
