"""Carry a payload: :class:`CarryEnv`.

A box (:class:`~soft_envs.sim.Box`) rests on the robot's top, centred over its top nodes: 0.6
body lengths long, 0.1 deep, 1.1 times the robot's width across, pressed 0.1 mm into the top at
rest so that friction holds it from the first step of the rest state's relaxation on. Its mass
(a fraction of the robot's) and the friction coefficient between it and the robot are the
level's (:mod:`.difficulty`). Walk along +x without dropping it: the payload *falls* when its
centre's height above the ground drops below ``fall_height_fraction`` of its height at rest or its
y axis tilts more than ``fall_tilt_deg`` from +y; that ends the episode (``terminated``) with
``-drop_penalty`` (``info["reward_drop"]``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...sim import Box, Robot
from ..arguments import number_in
from .box_task import BoxTaskEnv
from .docs import TASK_DOCS, task_docstring

__all__ = ["CarryEnv", "payload_box", "PAYLOAD_SIZE_BL", "PRESS_IN"]

#: the payload's length (x) and depth (y) in body lengths; across (z) it is 1.1 times the robot's width
PAYLOAD_SIZE_BL = (0.6, 0.1)
#: how far the payload's bottom lies below the robot's top at rest [m]
PRESS_IN = 1e-4


def payload_box(robot: Robot, lv: dict[str, Any]) -> Box:
    """The payload on ``robot``'s top at level ``lv`` (module docstring): the box this task adds,
    and :func:`~soft_envs.envs.tasks.task_keywords` gives an optimiser."""
    p, L = robot.mesh.points, float(robot.body_length)
    top = float(p[:, 1].max())
    on_top = p[p[:, 1] >= top - 1e-9]
    lx, ly = PAYLOAD_SIZE_BL[0] * L, PAYLOAD_SIZE_BL[1] * L
    lz = 1.1 * float(np.ptp(on_top[:, 2]))
    center = (float(on_top[:, 0].mean()), top + 0.5 * ly - PRESS_IN, float(on_top[:, 2].mean()))
    return Box(size=(lx, ly, lz), center=center, mass=lv["mass_fraction"] * robot.total_mass,
               friction_coefficient=lv["friction_coefficient"])


class CarryEnv(BoxTaskEnv):
    __doc__ = task_docstring(TASK_DOCS["carry"])
    task_name = "carry"

    def __init__(self, robot="tripod", *, drop_penalty: float = 10.0, fall_height_fraction: float = 0.5,
                 fall_tilt_deg: float = 60.0, **kwargs: Any):
        self.drop_penalty = number_in("drop_penalty", drop_penalty, 0.0)
        self.fall_height_fraction = number_in("fall_height_fraction", fall_height_fraction, 0.0, 1.0)
        self.fall_tilt_deg = number_in("fall_tilt_deg", fall_tilt_deg, 0.0, 180.0)
        super().__init__(robot, **kwargs)

    def _make_box(self, robot: Robot, lv: dict[str, Any]) -> Box:
        return payload_box(robot, lv)

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        return {"task": "walk", "target_heading_deg": 0.0}

    def payload_fell(self) -> bool:
        """Whether the payload has fallen (module docstring)."""
        return bool(self.box_height() < self.fall_height_fraction * self._box_rest_height
                    or self.box_tilt_deg() > self.fall_tilt_deg)

    def _task_terms(self, com_before: np.ndarray) -> tuple[dict[str, float], bool]:
        return {"reward_drop": -self.drop_penalty if self.payload_fell() else 0.0}, False

    def _task_info(self) -> dict[str, Any]:
        return {**super()._task_info(), "payload_fell": self.payload_fell(), "payload_height": self.box_height()}

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = super().step(action)
        return obs, reward, bool(terminated or info["payload_fell"]), truncated, info

    def _has_terminated(self) -> bool:
        return super()._has_terminated() or (self._n_sub > 0 and self.payload_fell())
