"""The tasks on ground that is not flat (a :class:`~soft_envs.sim.ground.HeightField`): cross rough
terrain, climb a step, cross a trench.

Each appends a ``terrain`` part to the observation: the COM's height above the ground under it,
and the ground's height half a body length and one body length ahead (along the body's forward
vector in the ground plane) relative to the ground under the COM. The health check measures
heights above the ground under the COM (:mod:`soft_envs.envs.ground_reference`), so a hollow or
a step does not end an episode. The field is along +x (the step and the trench are across the x
axis): these tasks walk along +x.
"""
from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np

from ...sim import HeightField, Robot, SimulationError, load_robot
from .base import TaskEnv
from .difficulty import DEFAULT_DIFFICULTY, LEVELS, level
from .docs import TASK_DOCS, TERRAIN_OWNED, task_docstring

__all__ = ["RoughTerrainEnv", "ClimbStepEnv", "CrossTrenchEnv", "task_ground", "task_keywords", "LOOK_AHEAD_BL", "ROUGH_WAVELENGTH_BL",
           "MAX_TERRAIN_DRAWS"]

#: where the terrain part of the observation looks, in body lengths ahead of the COM
LOOK_AHEAD_BL = (0.5, 1.0)
#: the rough terrain's wavelength, in body lengths (5.6 and 5.2 cm for the Tripod and the Puppy)
ROUGH_WAVELENGTH_BL = 0.4
#: terrains drawn at most at a reset before giving up (a draw fails when the rest state's relaxation
#: does not converge on it: about 1 in 150 draws, measured over the three levels and both robots)
MAX_TERRAIN_DRAWS = 10
#: the smoothing width of a step's or a trench's edges [body lengths]
EDGE_WIDTH_BL = 0.07
#: the gap between the robot's front at rest and the foot of a step or a trench's near edge [body lengths]
GAP_BL = 0.15


def task_ground(task: str, level: dict[str, Any], body_length: float, front: float, seed: int = 0
                ) -> tuple[HeightField, dict[str, float]]:
    """The ground of a terrain task (``"rough_terrain"``, ``"climb_step"``, ``"cross_trench"``) at
    ``level`` (:data:`~.difficulty.LEVELS`) for a robot of ``body_length`` whose front at rest is
    at x = ``front`` [m]; ``seed``: the rough terrain's. Returns the field and the places it
    defines [m] (``finish_x``, and ``step_position``, ``step_height`` or ``trench_start``,
    ``trench_length``). The environments and ``trajopt optimize --task climb_step`` build their
    ground here."""
    L, w = float(body_length), EDGE_WIDTH_BL * float(body_length)
    if task == "rough_terrain":
        return HeightField.rough(amplitude=level["amplitude_bl"] * L, wavelength=ROUGH_WAVELENGTH_BL * L,
                                 seed=int(seed), x_range=(-3.0 * L, 8.0 * L), z_range=(-4.0 * L, 4.0 * L)), {}
    if task == "climb_step":
        position, height = front + GAP_BL * L + 0.5 * w, level["height_bl"] * L       # the middle of the edge
        return (HeightField.step(height=height, position=position, width=w),
                {"step_position": position, "step_height": height, "finish_x": position + 0.5 * w + 0.5 * L})
    if task == "cross_trench":
        start, length = front + GAP_BL * L + 0.5 * w, level["length_bl"] * L
        return (HeightField.trench(depth=CrossTrenchEnv.DEPTH_BL * L, start=start, length=length, width=w),
                {"trench_start": start, "trench_length": length, "finish_x": start + length + 0.5 * w + 0.5 * L})
    raise ValueError(f"task must be one of 'rough_terrain', 'climb_step', 'cross_trench' (a terrain task), "
                     f"got {task!r}")


def task_keywords(task: str, robot: str | os.PathLike | Robot, difficulty: str = DEFAULT_DIFFICULTY, *,
                  seed: int = 0) -> dict[str, Any]:
    """The keywords of :class:`~soft_envs.envs.base.SoftRobotEnv` (and of
    :func:`~soft_envs.envs.make_gradient_env`) that put ``robot`` where ``task`` at
    ``difficulty`` stands: ``{"incline_deg": ...}`` on a slope, ``{"ground": HeightField}`` on the
    terrain tasks (``seed``: the rough terrain's), ``{"box": Box}`` for carry a payload and push a
    box (the task's box for ``robot``: :func:`~.carry.payload_box`, :func:`~.push.box_to_push`),
    ``{}`` for the tasks on the plane (walk, turn, reach a goal; their levels draw physical
    parameters or goals at each reset, which a fixed environment does not). A ValueError names a
    bad task or difficulty."""
    if task not in LEVELS:
        raise ValueError(f"task must be one of {tuple(LEVELS)}, got {task!r}")
    lv = level(task, difficulty)
    if "incline_deg" in lv:
        return {"incline_deg": float(lv["incline_deg"])}
    if task not in ("rough_terrain", "climb_step", "cross_trench", "carry", "push_box"):
        return {}
    if not isinstance(robot, Robot):
        robot = load_robot(robot)
    if task in ("carry", "push_box"):
        if robot.box is not None:
            raise ValueError(f"task {task!r} adds its own box; robot {robot.name!r} has one already")
        from .carry import payload_box          # they import this module's siblings: not at import time
        from .push import box_to_push
        return {"box": (payload_box if task == "carry" else box_to_push)(robot, lv)}
    return {"ground": task_ground(task, lv, robot.body_length, float(robot.mesh.points[:, 0].max()), seed)[0]}


class _TerrainEnv(TaskEnv):
    owned = TERRAIN_OWNED

    def _task_kwargs(self, robot: Robot) -> dict[str, Any]:
        self._L = float(robot.body_length)
        self._front = float(robot.mesh.points[:, 0].max())
        return {"task": "walk", "ground": self._make_ground(), "target_heading_deg": 0.0}

    def _make_ground(self) -> HeightField:
        raise NotImplementedError

    def _extra_structure(self) -> dict[str, int]:
        return {"terrain": 1 + len(LOOK_AHEAD_BL)}

    def _extra_obs(self) -> np.ndarray:
        com = self._com
        h0 = self._ground_ref.height_under(com)
        f = np.array([self._rot[0, 0], self._rot[2, 0]])
        norm = float(np.hypot(*f))
        f = f / norm if norm > 1e-9 else np.array([1.0, 0.0])
        ahead = [self.ground_height(com[0] + d * self._L * f[0], com[2] + d * self._L * f[1]) - h0
                 for d in LOOK_AHEAD_BL]
        return np.array([com[1] - h0, *ahead])

    def _task_info(self) -> dict[str, Any]:
        return {"height_above_ground": float(self._com[1] - self._ground_ref.height_under(self._com))}


class RoughTerrainEnv(_TerrainEnv):
    __doc__ = task_docstring(TASK_DOCS["rough_terrain"])
    task_name = "rough_terrain"

    def __init__(self, robot="tripod", *, terrain_seed: int | None = None, **kwargs: Any):
        if not (terrain_seed is None or (isinstance(terrain_seed, (int, np.integer))
                                         and not isinstance(terrain_seed, bool) and terrain_seed >= 0)):
            raise ValueError(f"terrain_seed must be an integer >= 0 or None (a new terrain at each reset), "
                             f"got {terrain_seed!r}")
        self.terrain_seed = terrain_seed
        self._episode_seed = 0 if terrain_seed is None else int(terrain_seed)
        self._terrain_draws = 1
        super().__init__(robot, **kwargs)

    def _make_ground(self) -> HeightField:
        return task_ground(self.task_name, self.level, self._L, self._front, self._episode_seed)[0]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """A new terrain (its seed drawn from ``np_random``; redrawn when the robot cannot be placed
        at rest on it, at most :data:`MAX_TERRAIN_DRAWS` draws) unless ``terrain_seed`` fixes it;
        then the robot's reset on it."""
        self._check_reset_options(options)
        if seed is not None:
            gym.Env.reset(self, seed=seed)
        if self.terrain_seed is None:
            kept = self._episode_seed
            for draw in range(1, MAX_TERRAIN_DRAWS + 1):
                self._episode_seed = int(self.np_random.integers(2**31 - 1))     # _make_ground reads it
                try:
                    self._set_ground(self._make_ground())
                    break
                except SimulationError:
                    if draw == MAX_TERRAIN_DRAWS:
                        self._episode_seed = kept            # the terrain in use is still the old one
                        raise
            self._terrain_draws = draw
        return super().reset(seed=None, options=options)

    def _task_info(self) -> dict[str, Any]:
        return {**super()._task_info(), "terrain_seed": self._episode_seed, "terrain_draws": self._terrain_draws}


class ClimbStepEnv(_TerrainEnv):
    __doc__ = task_docstring(TASK_DOCS["climb_step"])
    task_name = "climb_step"

    def _make_ground(self) -> HeightField:
        ground, places = task_ground(self.task_name, self.level, self._L, self._front)
        # step_position (the middle of the edge), step_height, finish_x (the COM half a body length
        # on top); the trench: trench_start, trench_length, finish_x
        for name, value in places.items():
            setattr(self, name, value)
        return ground

    def _task_terms(self, com_before: np.ndarray) -> tuple[dict[str, float], bool]:
        return {}, bool(self._com[0] >= self.finish_x and self.is_healthy)


class CrossTrenchEnv(ClimbStepEnv):
    __doc__ = task_docstring(TASK_DOCS["cross_trench"])
    task_name = "cross_trench"
    #: the trench's depth [body lengths]
    DEPTH_BL = 0.05



