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

from typing import Any

import gymnasium as gym
import numpy as np

from ...sim import HeightField, Robot, SimulationError
from .base import TaskEnv
from .docs import TASK_DOCS, task_docstring

__all__ = ["RoughTerrainEnv", "ClimbStepEnv", "CrossTrenchEnv", "LOOK_AHEAD_BL", "ROUGH_WAVELENGTH_BL",
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


class _TerrainEnv(TaskEnv):
    owned = ("task", "ground", "target_heading_deg", "incline_deg")

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
        L = self._L
        return HeightField.rough(amplitude=self.level["amplitude_bl"] * L, wavelength=ROUGH_WAVELENGTH_BL * L,
                                 seed=self._episode_seed, x_range=(-3.0 * L, 8.0 * L), z_range=(-4.0 * L, 4.0 * L))

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
        L, w = self._L, EDGE_WIDTH_BL * self._L
        self.step_position = self._front + GAP_BL * L + 0.5 * w          # the middle of the edge [m]
        self.step_height = self.level["height_bl"] * L
        self.finish_x = self.step_position + 0.5 * w + 0.5 * L          # the COM half a body length on top
        return HeightField.step(height=self.step_height, position=self.step_position, width=w)

    def _task_terms(self, com_before: np.ndarray) -> tuple[dict[str, float], bool]:
        return {}, bool(self._com[0] >= self.finish_x and self.is_healthy)


class CrossTrenchEnv(ClimbStepEnv):
    __doc__ = task_docstring(TASK_DOCS["cross_trench"])
    task_name = "cross_trench"
    #: the trench's depth [body lengths]
    DEPTH_BL = 0.05

    def _make_ground(self) -> HeightField:
        L, w = self._L, EDGE_WIDTH_BL * self._L
        self.trench_start = self._front + GAP_BL * L + 0.5 * w
        self.trench_length = self.level["length_bl"] * L
        self.finish_x = self.trench_start + self.trench_length + 0.5 * w + 0.5 * L
        return HeightField.trench(depth=self.DEPTH_BL * L, start=self.trench_start, length=self.trench_length, width=w)


