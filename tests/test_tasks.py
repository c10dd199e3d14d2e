"""Tasks as objects (trajopt.tasks, issue #27 item 4): each gives its target, heading term, gait
shape, weights and contact law, and a new task is one class and one registry line."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from trajopt.optim.gait import GaitSpec
from trajopt.optim.objectives import ObjectiveWeights
from trajopt.tasks.registry import TASKS, Task, command_line_tasks, get_task


#: the benchmark's tasks (soft_envs.envs.tasks) that trajopt adds to the paper's, in their order
BENCHMARK = ["slope_up", "slope_down", "rough_terrain", "climb_step", "cross_trench", "reach_goal", "carry", "push_box"]


def test_the_paper_tasks_and_what_they_give():
    assert list(TASKS) == ["walk", "turn", "incline", "custom"] + BENCHMARK
    assert command_line_tasks() == ["walk", "turn", "incline"] + BENCHMARK
    walk, turn, incline = TASKS["walk"], TASKS["turn"], TASKS["incline"]
    assert GaitSpec.for_task("walk") == GaitSpec() == GaitSpec.for_task("incline")
    assert GaitSpec.for_task("turn") == GaitSpec(n_keyframes=12, symmetry=False, interpolation="linear")
    assert GaitSpec.for_task("turn", interpolation="hermite").interpolation == "hermite"
    assert GaitSpec.for_task("walk").interpolation == GaitSpec.for_task("incline").interpolation == "hermite"
    assert GaitSpec.for_task("turn", symmetry=True).symmetry and not GaitSpec.for_task("walk", symmetry=False).symmetry
    assert ObjectiveWeights.for_task("turn").heading == 1.0 and ObjectiveWeights.for_task("walk") == ObjectiveWeights()
    assert (walk.contact, turn.contact, incline.contact) == (None, "coulomb", None)
    assert incline.on_slope and not walk.on_slope and turn.speed_along_path and not walk.speed_along_path
    line = walk.target_path(np.zeros(2), 10, 0.1, 0.5, 90.0)
    np.testing.assert_allclose(line[-1], [0.0, 0.5], atol=1e-12)          # heading 90: towards +z
    arc = turn.target_path(np.zeros(2), 10, 0.1, 0.5, 0.0, "left")
    assert arc[-1, 1] < 0 and walk.target_heading(10, 0.1, 0.5) is None
    np.testing.assert_allclose(turn.target_heading(10, 0.1, 0.5, "right")[[0, -1]], [0.0, np.pi / 2])
    with pytest.raises(ValueError, match=r"task must be one of \('walk', 'turn', 'incline', 'custom', 'slope_up', .*\), "
                                         r"got 'run'"):
        get_task("run")
    with pytest.raises(ValueError, match="needs a target array"):
        TASKS["custom"].target_path(np.zeros(2), 10, 0.1, 0.5, 0.0)


@dataclass(frozen=True)
class Sidestep(Task):
    """A new task: walk sideways (90 degrees right of the heading), symmetry off."""

    name: str = "sidestep"
    gait_defaults: dict = field(default_factory=lambda: {"symmetry": False})

    def target_path(self, start, n_steps, dt, speed, heading_deg, turn="right"):
        return super().target_path(start, n_steps, dt, speed, heading_deg + 90.0, turn)


def test_a_new_task_is_one_class_and_one_registry_line(monkeypatch, tmp_path):
    monkeypatch.setitem(TASKS, "sidestep", Sidestep())                       # the registry line
    assert GaitSpec.for_task("sidestep") == GaitSpec(symmetry=False)
    from trajopt.cli import build_parser
    args = build_parser().parse_args(["optimize", "tripod", "--task", "sidestep"])
    assert args.task == "sidestep"
    from trajopt.sweep.kinds import KINDS
    assert KINDS["optimize"].check("task", "sidestep") == "sidestep"
    from trajopt import optimize_gait
    from trajopt.optim.gauss_newton import GaussNewtonOptions
    res = optimize_gait("tripod", "sidestep", gait=GaitSpec(n_prep=2, n_cycle=6, n_keyframes=2, n_cycles=1,
                                                            symmetry=False),
                        options=GaussNewtonOptions(max_iter=0), n_seeds=1, eval_cycles=1)
    step = res.target[-1] - res.target[0]
    assert res.task == "sidestep" and abs(step[0]) < 1e-12 < step[1]         # straight towards +z
