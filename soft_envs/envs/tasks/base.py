""":class:`TaskEnv`: what the benchmark's tasks add to :class:`~soft_envs.envs.base.SoftRobotEnv`.

A task is a :class:`~soft_envs.envs.base.SoftRobotEnv` (same robot, physics, actions and
observation) whose ``difficulty`` sets some of its keywords (:mod:`.difficulty`; those keywords
are then the task's, and passing one is a ValueError), plus, per task:

- observation parts appended after the robot's (:meth:`TaskEnv._extra_structure`,
  :meth:`TaskEnv._extra_obs`), listed in ``observation_structure``;
- reward terms added to the robot's (:meth:`TaskEnv._task_terms`, each in ``info``), and a
  success (``info["is_success"]``) that may end the episode.

Randomness comes from ``self.np_random`` only (reset noise, domain randomisation, the task's
draws).
"""
from __future__ import annotations

import os
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from ...sim import Robot, SimulationError, load_robot
from ..base import SoftRobotEnv
from ..ground_reference import GroundReference
from .difficulty import DEFAULT_DIFFICULTY, level

__all__ = ["TaskEnv"]


class TaskEnv(SoftRobotEnv):
    """A benchmark task on a robot (see :mod:`soft_envs.envs.tasks`)."""

    #: the task's key in :data:`~.difficulty.LEVELS`
    task_name: ClassVar[str] = "walk"
    #: keywords of SoftRobotEnv the task sets (a ValueError when given)
    owned: ClassVar[tuple[str, ...]] = ()

    def __init__(self, robot: str | os.PathLike | Robot = "tripod", *, difficulty: str = DEFAULT_DIFFICULTY,
                 success_reward: float = 10.0, terminate_on_success: bool = True, **kwargs: Any):
        self.difficulty = difficulty
        self.level = level(self.task_name, difficulty)          # ValueError for a bad difficulty
        given = sorted(set(kwargs) & set(self.owned))
        if given:
            raise ValueError(f"{given[0]} is set by the task (difficulty={difficulty!r}), got {given[0]}="
                             f"{kwargs[given[0]]!r}; the task's keywords are in its Arguments section")
        if not (isinstance(success_reward, (int, float, np.integer, np.floating))
                and not isinstance(success_reward, bool) and np.isfinite(success_reward)):
            raise ValueError(f"success_reward must be a finite number, got {success_reward!r}")
        if not isinstance(terminate_on_success, (bool, np.bool_)):
            raise ValueError(f"terminate_on_success must be True or False, got {terminate_on_success!r}")
        self.success_reward = float(success_reward)
        self.terminate_on_success = bool(terminate_on_success)
        if not isinstance(robot, Robot):
            robot = load_robot(robot) if isinstance(robot, (str, os.PathLike)) else robot
        super().__init__(robot, **self._task_kwargs(robot), **kwargs)
        self._succeeded = False
        extra = self._extra_structure()
        if extra:
            n = sum(extra.values())
            self.observation_structure = {**self.observation_structure, **extra}
            box = self.observation_space
            self.observation_space = spaces.Box(np.concatenate([box.low, np.full(n, -np.inf)]),
                                                np.concatenate([box.high, np.full(n, np.inf)]), dtype=np.float64)

    # ------------------------------------------------------------------ what a task defines
    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        """The SoftRobotEnv keywords the task and its level set (``owned``)."""
        return dict(self.level)

    def _extra_structure(self) -> dict[str, int]:
        """Observation parts appended after the robot's: name -> size."""
        return {}

    def _extra_obs(self) -> np.ndarray:
        """The values of :meth:`_extra_structure`'s parts now."""
        return np.empty(0)

    def _task_terms(self, com_before: np.ndarray) -> tuple[dict[str, float], bool]:
        """``({"reward_<term>": value}, success)`` of the step just taken (``com_before``: the COM
        before it). The values are added to the reward and reported in ``info``."""
        return {}, False

    def _task_info(self) -> dict[str, Any]:
        """Entries of ``info`` at reset and after every step."""
        return {}

    # ------------------------------------------------------------------ the Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = super().reset(seed=seed, options=options)
        self._succeeded = False
        self._on_reset()
        return self._get_obs(), {**info, **self._task_info(), "is_success": False}

    def _on_reset(self) -> None:
        """Draw the episode's task (after the robot's reset, from ``np_random``)."""

    def step(self, action: Any):
        com_before = self._com.copy()
        obs, reward, terminated, truncated, info = super().step(action)
        if "sim_failure" in info:
            return obs, reward, terminated, truncated, {**info, **self._task_info(), "is_success": False}
        terms, success = self._task_terms(com_before)
        first = success and not self._succeeded
        self._succeeded |= success
        terms["reward_success"] = self.success_reward if first else 0.0
        reward = float(reward) + sum(terms.values())
        terminated = bool(terminated or (success and self.terminate_on_success))
        info.update(terms, **self._task_info(), is_success=success)
        return obs, reward, terminated, truncated, info

    def _get_obs(self) -> np.ndarray:
        obs = super()._get_obs()
        extra = self._extra_obs()
        return np.concatenate([obs, extra]) if extra.size else obs

    # ------------------------------------------------------------------ helpers
    def _set_ground(self, ground) -> None:
        """Stand the robot on ``ground`` (a HeightField) from now on: the simulator and the rest
        state are rebuilt (with the episode's physical parameters). SimulationError, and nothing
        changed, when the robot cannot be placed at rest on it."""
        dt, before = self.timestep, (self._base_robot, self._ground_ref, self._sim)
        self._base_robot = self._base_robot.replace(ground=ground)
        self._ground_ref = GroundReference(ground)
        self._sim = None
        try:
            self._set_domain(dict(self._domain), dt=dt)
        except SimulationError:         # the robot cannot be placed at rest there: nothing changes
            self._base_robot, self._ground_ref, self._sim = before
            raise

    def ground_height(self, x: float, z: float) -> float:
        """The ground's height [m] at ``(x, z)`` (0 on the plane y = 0)."""
        return self._ground_ref.height_under(np.array([x, 0.0, z]))
