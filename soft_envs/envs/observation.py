"""The observation of :class:`~soft_envs.envs.base.SoftRobotEnv`: its parts, its space, and the
vector built from a state.

The parts, in order (``observation_structure``): the COM relative to the COM at reset (its
height absolute), the COM velocity over the last physics step, the body's forward and up
vectors (the first two columns of the best-fit rotation), each tendon's cable deformation
divided by its motor's range, each motor's applied contraction scaled like the actions, the gait
phase (sin, cos) and, with ``observe_nodes``, the node positions relative to the COM.

Bounds (:data:`BOUNDED_PARTS`): the unit vectors, the applied contraction and the gait phase lie
in [-1, 1] by construction, and the observation space says so. The other parts have no bound the
environment can promise and stay at -inf and inf; the Observation Space section of the
environments' docstrings (:mod:`.env_docs`) says why for each.
"""
from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from ..sim import Robot

__all__ = ["Observation", "BOUNDED_PARTS"]

#: the parts of the observation with a finite range ``(low, high)`` that each of their entries
#: lies in: the columns of a rotation matrix, the applied contraction scaled like the actions
#: (the motors keep it in [u_min, u_max]) and a sine and cosine
BOUNDED_PARTS = {"forward_vector": (-1.0, 1.0), "up_vector": (-1.0, 1.0), "contraction": (-1.0, 1.0),
                 "gait_phase": (-1.0, 1.0)}


class Observation:
    """The observation of one environment: ``structure`` (part -> size, in order), ``size``, the
    observation ``space`` (a Box: the ranges of :data:`BOUNDED_PARTS`, -inf and inf elsewhere)
    and :meth:`build`. ``motor_range`` (M,) [m] is each motor's ``u_max - u_min``: a tendon's
    cable deformation is divided by its motor's range (a passive tendon's by the mean range)."""

    def __init__(self, robot: Robot, motor_range: np.ndarray, observe_nodes: bool, gait_period: float):
        self.structure = {
            "com_position": 3, "com_velocity": 3, "forward_vector": 3, "up_vector": 3,
            "cable_deformation": len(robot.tendons), "contraction": robot.n_motors, "gait_phase": 2,
            "nodes": 3 * robot.mesh.n_nodes if observe_nodes else 0}
        self.size = sum(self.structure.values())
        self.observe_nodes = bool(observe_nodes)
        self.gait_period = float(gait_period)
        tm = robot.tendon_motor
        self.gamma_scale = 1.0 / np.where(tm >= 0, motor_range[np.maximum(tm, 0)], motor_range.mean())
        low, high = np.full(self.size, -np.inf), np.full(self.size, np.inf)
        for name, part in self.slices().items():
            if name in BOUNDED_PARTS:
                low[part], high[part] = BOUNDED_PARTS[name]
        self.space = spaces.Box(low, high, shape=(self.size,), dtype=np.float64)

    def slices(self) -> dict[str, slice]:
        """Where each part lies in the observation vector."""
        out, i = {}, 0
        for name, n in self.structure.items():
            out[name] = slice(i, i + n)
            i += n
        return out

    def build(self, *, com: np.ndarray, com_start: np.ndarray, com_prev: np.ndarray, physics_dt: float,
              rotation: np.ndarray, gamma: np.ndarray, contraction: np.ndarray, n_sub: int, timestep: float,
              x: np.ndarray) -> np.ndarray:
        """The observation of a state: COM now ``com`` (3,), at reset ``com_start`` and one
        physics step (``physics_dt`` seconds) ago ``com_prev`` [m]; the best-fit ``rotation``
        (3, 3); the cable deformations ``gamma`` (T,) [m]; the applied ``contraction`` as an
        action (M,); ``n_sub`` control steps of ``timestep`` seconds since reset; node positions
        ``x`` (n, 3) [m]. The unit vectors and the contraction are clipped into [-1, 1], where
        they lie up to rounding (at rest an entry of the rotation may be 1 + 2e-16); a
        contraction outside the motor's range (only ``set_state`` can set one) reads as the
        nearer end."""
        s = self.structure
        obs = np.empty(self.size)
        obs[0:3] = com - com_start
        obs[1] = com[1]
        obs[3:6] = (com - com_prev) / physics_dt
        obs[6:9] = np.clip(rotation[:, 0], -1.0, 1.0)
        obs[9:12] = np.clip(rotation[:, 1], -1.0, 1.0)
        i = 12 + s["cable_deformation"]
        obs[12:i] = gamma * self.gamma_scale
        j = i + s["contraction"]
        obs[i:j] = np.clip(contraction, -1.0, 1.0)
        phase = 2.0 * math.pi * n_sub * timestep / self.gait_period
        obs[j] = math.sin(phase)
        obs[j + 1] = math.cos(phase)
        if self.observe_nodes:
            obs[j + 2:] = (x - com).ravel()
        return obs
