"""How trajopt reaches the physics: the gradient hooks of an environment.

:func:`as_hooks` accepts a Gymnasium environment whose ``unwrapped`` object offers the
:class:`soft_envs.envs.protocol.GradientEnv` hooks (``SoftTripod-v0``, ``SoftPuppy-v0``), a
:class:`soft_envs.sim.Robot`, a shipped robot name or a robot.toml path; for the last three it
builds :class:`SimulatorHooks`, the same hooks on a bare :class:`~soft_envs.sim.Simulator`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from soft_envs.sim import Robot, Simulator, Trajectory, incline_gravity, load_robot

__all__ = ["SimulatorHooks", "as_hooks", "make_hooks"]


class SimulatorHooks:
    """Gradient hooks on a bare simulator: rollouts start at rest (``rest_state`` with every
    motor at 0 clipped into its range, as the environments start)."""

    def __init__(self, robot: Robot, dt: float = 0.033, incline_deg: float = 0.0,
                 heading_deg: float = 0.0, control: str = "length"):
        a = np.radians(heading_deg)
        g = incline_gravity(incline_deg, uphill=(np.cos(a), np.sin(a)))
        self._sim = Simulator(robot, dt=dt, gravity=g, control=control)
        self.incline_deg = float(incline_deg)
        self._x0 = None

    @property
    def simulator(self) -> Simulator:
        return self._sim

    @property
    def robot(self) -> Robot:
        return self._sim.robot

    @property
    def dt(self) -> float:
        return self._sim.dt

    def reset_state(self) -> tuple[np.ndarray, np.ndarray]:
        if self._x0 is None:
            self._x0 = self._sim.rest_state(self.u_start)
        return self._x0.copy(), self._x0.copy()

    def rollout(self, u: np.ndarray, dudz: np.ndarray | None = None, *, store_dxdz: bool = False) -> Trajectory:
        x0, xm1 = self.reset_state()
        return self._sim.rollout(u, x0=x0, dudz=dudz, x_prev0=xm1, store_dxdz=store_dxdz)

    def get_state(self) -> dict[str, Any]:
        x0, xm1 = self.reset_state()
        return {"x": x0, "x_prev": xm1}

    def set_state(self, state: dict[str, Any]) -> None:
        self._x0 = np.array(state["x"])

    @property
    def u_start(self) -> np.ndarray:
        """(n_motors,) contractions of the rest state: ``robot.u_rest``."""
        return self.robot.u_rest

    def com(self) -> np.ndarray:
        return self.robot.com(self.reset_state()[0])

    def cable_deformation(self) -> np.ndarray:
        return self._sim.cable_deformation(self.reset_state()[0], self.u_start)


def as_hooks(env_or_robot: Any, *, incline_deg: float = 0.0, heading_deg: float = 0.0):
    """The gradient hooks of an environment, or :class:`SimulatorHooks` for a robot/name/path."""
    if isinstance(env_or_robot, (Robot, str, Path)):
        robot = env_or_robot if isinstance(env_or_robot, Robot) else load_robot(env_or_robot)
        return SimulatorHooks(robot, incline_deg=incline_deg, heading_deg=heading_deg)
    target = getattr(env_or_robot, "unwrapped", env_or_robot)
    for name in ("simulator", "robot", "dt", "rollout"):
        if not hasattr(target, name):
            raise TypeError(f"{type(target).__name__} does not offer the gradient hook {name!r} "
                            "(see soft_envs.envs.protocol.GradientEnv)")
    return target


def make_hooks(robot: str, *, incline_deg: float = 0.0, heading_deg: float = 0.0, use_env: bool = True):
    """Hooks for a shipped robot name or robot.toml path: the registered Gymnasium environment
    when there is one (``SoftTripod-v0`` / ``SoftPuppy-v0``), else a bare simulator."""
    ids = {"tripod": "SoftTripod-v0", "puppy": "SoftPuppy-v0"}
    if use_env and robot in ids:
        import gymnasium as gym

        import soft_envs  # noqa: F401  (registers the ids)
        env = gym.make(ids[robot], incline_deg=incline_deg, target_heading_deg=heading_deg,
                       reset_noise_scale=0.0)
        env.reset(seed=0)
        return as_hooks(env)
    return as_hooks(robot, incline_deg=incline_deg, heading_deg=heading_deg)
