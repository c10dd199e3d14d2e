"""The tasks with a second body: :class:`BoxTaskEnv`, the base of carry a payload
(:mod:`.carry`) and push a box (:mod:`.push`).

The box is a :class:`~soft_envs.sim.Box` (a stiff FEM hexahedron of 5 tets) added to the robot's
mesh by :func:`~soft_envs.sim.with_box`: it has mass, gravity, the robot's ground contact law on
its corners, and contact with friction against the robot's nodes
(:mod:`soft_envs.sim.contact.box_contact`), all in the same implicit-Euler Newton solve. The
robot's COM, frame and health leave it out. Each task builds its box from the robot's size and
the level (:meth:`BoxTaskEnv._make_box`) and appends the box's parts to the observation:
``box_offset`` (its centre minus the robot's COM), ``box_velocity`` (over the last physics step)
and ``box_axes`` (its x and y axes in the world frame).

The gradient hooks (``rollout`` with ``dudz``, ``rollout_parameters``) differentiate through the
box too (:mod:`soft_envs.sim.contact.box_sensitivity`).
"""
from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from ...sim import Box, Robot, load_robot, with_box
from .base import TaskEnv
from .difficulty import DEFAULT_DIFFICULTY, level

__all__ = ["BoxTaskEnv", "BOX_PARTS"]

#: the observation parts of the box: name -> size
BOX_PARTS = {"box_offset": 3, "box_velocity": 3, "box_axes": 6}
# the box's corners on its -x / +x and -y / +y faces (soft_envs.sim.box: corner i = bx + 2 by + 4 bz)
_LOW_X, _HIGH_X = [0, 2, 4, 6], [1, 3, 5, 7]
_LOW_Y, _HIGH_Y = [0, 1, 4, 5], [2, 3, 6, 7]


class BoxTaskEnv(TaskEnv):
    """A task with a box (module docstring); a subclass gives :meth:`_make_box`."""

    owned = ("task", "target_heading_deg")

    def __init__(self, robot: str | os.PathLike | Robot = "tripod", *, difficulty: str = DEFAULT_DIFFICULTY,
                 **kwargs: Any):
        lv = level(self.task_name, difficulty)              # a bad difficulty first, before any robot is built
        if isinstance(robot, (str, os.PathLike)):
            robot = load_robot(robot)
        if not isinstance(robot, Robot):
            raise ValueError(f"robot must be a shipped name, a robot.toml path or a Robot, got {type(robot).__name__}")
        if robot.box is not None:
            raise ValueError(f"robot {robot.name!r} has a box already; the task adds its own")
        self.box = self._make_box(robot, lv)
        super().__init__(with_box(robot, self.box), difficulty=difficulty, **kwargs)
        self._on_reset()

    def _make_box(self, robot: Robot, lv: dict[str, Any]) -> Box:
        """The task's box for ``robot`` (no box yet) at level ``lv``."""
        raise NotImplementedError

    # ------------------------------------------------------------------ the box's state
    def box_center(self, x: np.ndarray | None = None) -> np.ndarray:
        """The box's centre (3,) [m] (the mean of its corners, each of equal mass) at positions
        ``x`` (default now)."""
        x = self._x if x is None else x
        return x[self.robot.box_nodes].mean(axis=0)

    def box_axes(self, x: np.ndarray | None = None) -> np.ndarray:
        """(2, 3): the box's x and y axes (unit vectors from its -x to its +x face, -y to +y)."""
        c = (self._x if x is None else x)[self.robot.box_nodes]
        axes = np.stack([c[_HIGH_X].mean(axis=0) - c[_LOW_X].mean(axis=0),
                         c[_HIGH_Y].mean(axis=0) - c[_LOW_Y].mean(axis=0)])
        return axes / np.linalg.norm(axes, axis=1, keepdims=True)

    def box_tilt_deg(self) -> float:
        """Angle [deg] between the box's y axis and +y."""
        return math.degrees(math.acos(min(1.0, max(-1.0, float(self.box_axes()[1, 1])))))

    def box_height(self) -> float:
        """The box centre's height [m] above the ground under it."""
        c = self.box_center()
        return float(c[1] - self._ground_ref.height_under(c))

    def _on_reset(self) -> None:
        self._box_start = self.box_center()
        self._box_last = self._box_start.copy()
        self._box_rest_height = self.box_height()

    # ------------------------------------------------------------------ observation, info
    def _extra_structure(self) -> dict[str, int]:
        return dict(BOX_PARTS)

    def _extra_obs(self) -> np.ndarray:
        c = self.box_center()
        v = (c - self.box_center(self._x_prev)) / self._sim.physics_dt
        return np.concatenate([c - self._com, v, self.box_axes().ravel()])

    def _task_info(self) -> dict[str, Any]:
        return {"box_position": self.box_center(), "box_displacement": self.box_center() - self._box_start,
                "box_tilt_deg": self.box_tilt_deg()}
