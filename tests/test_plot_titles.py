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
