"""Push a box: :class:`PushBoxEnv`.

A box (:class:`~soft_envs.sim.Box`) stands on the ground 0.1 body lengths ahead of the robot's
front at rest, centred on its width: 0.25 body lengths long, 0.25 high, 1.2 times the robot's
width across (its face meets the robot's front nodes). Its mass (a fraction of the robot's) is the
level's (:mod:`.difficulty`); it slides on the ground under the robot's contact law (its corners
are contact nodes) and the robot's nodes push its faces (with the friction of the robot's foam on
the box, 0.8). The forward reward is the box's speed along +x; the task succeeds when the box
has moved ``push_distance_bl`` body lengths along +x.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...sim import Box, Robot
from ..arguments import number_in
from .box_task import BoxTaskEnv
from .docs import TASK_DOCS, task_docstring

__all__ = ["PushBoxEnv", "box_to_push", "BOX_SIZE_BL", "BOX_GAP_BL"]

#: the box's length (x) and height (y) in body lengths; across (z) it is 1.2 times the robot's width
BOX_SIZE_BL = (0.25, 0.25)
#: the gap between the robot's front at rest and the box [body lengths]
BOX_GAP_BL = 0.1


def box_to_push(robot: Robot, lv: dict[str, Any]) -> Box:
    """The box ahead of ``robot`` at level ``lv`` (module docstring): the box this task adds, and
    :func:`~soft_envs.envs.tasks.task_keywords` gives an optimiser."""
    p, L = robot.mesh.points, float(robot.body_length)
    lx, ly = BOX_SIZE_BL[0] * L, BOX_SIZE_BL[1] * L
    lz = 1.2 * float(np.ptp(p[:, 2]))
    center = (float(p[:, 0].max()) + BOX_GAP_BL * L + 0.5 * lx, float(p[:, 1].min()) + 0.5 * ly,
              float(p[:, 2].min() + 0.5 * np.ptp(p[:, 2])))
    return Box(size=(lx, ly, lz), center=center, mass=lv["mass_fraction"] * robot.total_mass)


class PushBoxEnv(BoxTaskEnv):
    __doc__ = task_docstring(TASK_DOCS["push_box"])
    task_name = "push_box"

    def __init__(self, robot="tripod", *, push_distance_bl: float = 0.5, forward_reward_weight: float = 10.0,
                 **kwargs: Any):
        self.push_distance_bl = number_in("push_distance_bl", push_distance_bl, positive=True, what="[body lengths]")
        self._push_weight = number_in("forward_reward_weight", forward_reward_weight)
        super().__init__(robot, **kwargs)

    def _make_box(self, robot: Robot, lv: dict[str, Any]) -> Box:
        return box_to_push(robot, lv)

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        # the robot's forward term (its COM's speed) is off: this task's is the box's
        return {"task": "walk", "target_heading_deg": 0.0, "forward_reward_weight": 0.0}

    def box_pushed(self) -> float:
        """How far the box has moved along +x since the reset [m]."""
        return float(self.box_center()[0] - self._box_start[0])

    def _task_terms(self, com_before: np.ndarray) -> tuple[dict[str, float], bool]:
        now = self.box_center()
        speed = float(now[0] - self._box_last[0]) / self.dt / self._body_length      # BL/s along +x
        self._box_last = now
        success = bool(self.box_pushed() >= self.push_distance_bl * self._body_length and self.is_healthy)
        return {"reward_forward": self._push_weight * speed}, success

    def _task_info(self) -> dict[str, Any]:
        return {**super()._task_info(), "box_pushed": self.box_pushed()}
