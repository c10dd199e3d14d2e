"""The tasks on flat ground: walk, turn, walk up a slope, walk down a slope.

Their observation, reward and termination are the robot environment's (``SoftTripod-v2``,
``SoftPuppy-v2``); ``difficulty`` sets the physical parameters drawn at each reset (walk, turn)
or the slope (:mod:`.difficulty`). A slope is the gravity-rotated incline of ``incline_deg``
(the ground stays the plane y = 0 of the robot's frame, which a sloped height field reproduces to
6e-15 m: docs/contact.md), rising along ``target_heading_deg``.
"""
from __future__ import annotations

from typing import Any

from ...sim import Robot
from .base import TaskEnv
from .docs import TASK_DOCS, task_docstring

__all__ = ["WalkEnv", "TurnEnv", "SlopeUpEnv", "SlopeDownEnv"]


class WalkEnv(TaskEnv):
    __doc__ = task_docstring(TASK_DOCS["walk"])
    task_name = "walk"
    owned = ("task", "domain_randomization")

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        return {"task": "walk", **self.level}


class TurnEnv(TaskEnv):
    __doc__ = task_docstring(TASK_DOCS["turn"])
    task_name = "turn"
    owned = ("task", "domain_randomization")

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        return {"task": "turn", **self.level}


class SlopeUpEnv(TaskEnv):
    __doc__ = task_docstring(TASK_DOCS["slope_up"])
    task_name = "slope_up"
    owned = ("task", "incline_deg", "ground")

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        return {"task": "walk", **self.level}

    def _task_info(self) -> dict[str, Any]:
        return {"incline_deg": self.incline_deg}


class SlopeDownEnv(SlopeUpEnv):
    __doc__ = task_docstring(TASK_DOCS["slope_down"])
    task_name = "slope_down"
