"""Reach a goal point in the ground plane: :class:`ReachGoalEnv`.

At each reset a goal is drawn from ``np_random``: ``distance_bl`` body lengths from the COM, in a
direction uniform within ``half_angle_deg`` of the robot's forward direction (+x) (the level sets
both, :mod:`.difficulty`). The observation appends the goal relative to the COM (x, z) [m]; the
forward reward is the speed towards the goal (body lengths per second); reaching it (the COM
within ``goal_radius_bl`` body lengths, horizontally) is a success, which ends the episode.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...sim import Robot
from ..arguments import is_number
from .base import TaskEnv
from .docs import TASK_DOCS, task_docstring

__all__ = ["ReachGoalEnv"]


class ReachGoalEnv(TaskEnv):
    __doc__ = task_docstring(TASK_DOCS["reach_goal"])
    task_name = "reach_goal"
    owned = ("task", "target_heading_deg", "turn_direction", "turn_radius")

    def __init__(self, robot="tripod", *, goal_radius_bl: float = 0.25, forward_reward_weight: float = 10.0,
                 success_reward: float = 10.0, **kwargs: Any):
        if not (is_number(goal_radius_bl) and math.isfinite(goal_radius_bl) and goal_radius_bl > 0):
            raise ValueError(f"goal_radius_bl must be a positive number [body lengths], got {goal_radius_bl!r}")
        if not (is_number(forward_reward_weight) and math.isfinite(forward_reward_weight)):
            raise ValueError(f"forward_reward_weight must be a finite number, got {forward_reward_weight!r}")
        self.goal_radius_bl = float(goal_radius_bl)
        self._goal_weight = float(forward_reward_weight)
        self._goal = np.zeros(3)
        super().__init__(robot, success_reward=success_reward, **kwargs)

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        # the robot's forward term (speed along a heading) is off: this task's is towards the goal
        return {"task": "walk", "forward_reward_weight": 0.0}

    @property
    def goal(self) -> np.ndarray:
        """The episode's goal (3,) [m] (its height 0: only x and z count)."""
        return self._goal.copy()

    def _on_reset(self) -> None:
        lv = self.level
        angle = math.radians(self.np_random.uniform(-lv["half_angle_deg"], lv["half_angle_deg"]))
        d = lv["distance_bl"] * self._body_length
        self._goal = np.array([self._com[0] + d * math.cos(angle), 0.0, self._com[2] + d * math.sin(angle)])

    def _render_markers(self) -> list[np.ndarray]:
        return [self._goal.copy()]

    def _offset(self, com: np.ndarray) -> np.ndarray:
        return np.array([self._goal[0] - com[0], self._goal[2] - com[2]])

    def goal_distance(self) -> float:
        """Horizontal distance [m] from the COM to the goal."""
        return float(np.hypot(*self._offset(self._com)))

    def _extra_structure(self) -> dict[str, int]:
        return {"goal_offset": 2}

    def _extra_obs(self) -> np.ndarray:
        return self._offset(self._com)

    def _task_terms(self, com_before: np.ndarray) -> tuple[dict[str, float], bool]:
        before = float(np.hypot(*self._offset(com_before)))
        progress = (before - self.goal_distance()) / self.dt / self._body_length      # BL/s towards the goal
        success = bool(self.goal_distance() <= self.goal_radius_bl * self._body_length and self.is_healthy)
        return {"reward_forward": self._goal_weight * progress}, success

    def _task_info(self) -> dict[str, Any]:
        return {"goal": self._goal.copy(), "goal_distance": self.goal_distance()}
