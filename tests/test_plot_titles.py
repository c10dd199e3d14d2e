"""``trajopt plot`` figures name what they show (issue #31 item 5): every title carries the robot,
the task and the result file; the speed plot draws the target speed the gait was optimised for
besides the paper's figure; the COM plot points forward. Read from SVGs written with text kept
as text."""
from __future__ import annotations

import matplotlib
import numpy as np

from trajopt.cli import main

from .test_robustness import tiny_result


def test_plot_titles_name_robot_task_and_file_and_the_speed_plot_shows_the_target(tmp_path):
    from trajopt.results.result import Result
    res = Result.load(tiny_result(tmp_path))
    res.settings["speed_bl_per_min"] = 7.5
    res.evaluation = {"speed_per_cycle_bl_per_min": [3.0, 3.5], "speed_bl_per_min": 3.25}
    res.history = [{"iteration": 1, "objective": 2.0, "objective_after": 1.0, "step": 1e-3}]
    path = res.save(tmp_path / "my_gait.npz")
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        assert main(["plot", str(path), "--out", str(tmp_path / "plots"), "--format", "svg"]) == 0
    svgs = {p.stem.rsplit("_", 1)[-1]: p.read_text() for p in (tmp_path / "plots").glob("*.svg")}
    assert set(svgs) == {"com", "controls", "convergence", "speed"}
    for name, svg in svgs.items():
        assert "tripod, task walk: my_gait.npz" in svg, f"{name}: the title does not name robot, task and file"
    assert "paper: 6.1 BL/min" in svgs["speed"]
    # the target is the tracked COM path's, not a goal the gait was held to (#41)
    assert "tracking target: 7.5 BL/min (the target COM path&#39;s speed; not enforced)" in svgs["speed"] \
        or "tracking target: 7.5 BL/min (the target COM path's speed; not enforced)" in svgs["speed"]
    assert "target COM path (tracked, not enforced)" in svgs["com"]
    assert "forward (+x)" in svgs["com"]
    assert np.isfinite(res.evaluation["speed_bl_per_min"])


def test_a_turns_plot_shows_its_heading_over_time_and_its_speed_along_the_path(tmp_path):
    """A turn is plotted as a turn (#41): its heading over time and its speed along the COM path
    per cycle (the figures its evaluation reports), not the +x speed against the paper's walk."""
    from trajopt.cli.output_commands import _turn_series
    from trajopt.evaluation import evaluate_result
    from trajopt.replay import env_for_result
    from trajopt.results.result import Result
    res = Result.load(tiny_result(tmp_path))
    res.task = "turn"
    res.settings["eval_cycles"] = 2
    ev = evaluate_result(res)
    res.evaluation = {k: v for k, v in ev.items() if k != "com"}
    path = res.save(tmp_path / "my_turn.npz")
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        assert main(["plot", str(path), "--out", str(tmp_path / "plots"), "--format", "svg"]) == 0
    svgs = {p.stem.rsplit("_", 1)[-1]: p.read_text() for p in (tmp_path / "plots").glob("*.svg")}
    assert "speed" not in svgs and "turn" in svgs
    assert "heading change [deg]" in svgs["turn"] and "speed along the path" in svgs["turn"]
    assert "paper: " not in svgs["turn"] and "tripod, task turn: my_turn.npz" in svgs["turn"]
    t, heading, speeds, prep_time = _turn_series(res, env_for_result(res))
    marks = [int(round(prep_time / res.dt)) + 12 * i for i in range(3)]
    assert np.allclose(np.diff(heading[marks]), ev["heading_per_cycle_deg"], atol=1e-9)
    assert np.mean(speeds) == np.float64(ev["cycle_path_speed_bl_per_min"]) or \
        abs(np.mean(speeds) - ev["cycle_path_speed_bl_per_min"]) < 1e-9
