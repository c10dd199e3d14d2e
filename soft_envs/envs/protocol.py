"""The gradient hooks an environment offers to trajectory optimisers (``trajopt``).

Any environment whose ``unwrapped`` object satisfies :class:`GradientEnv` can be optimised by
``trajopt.optimize_gait``; the shipped ``SoftTripod-v0`` and ``SoftPuppy-v0`` do.
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..sim import Robot, Simulator, Trajectory

__all__ = ["GradientEnv"]


@runtime_checkable
class GradientEnv(Protocol):
    """Analytic-gradient hooks of a soft-robot environment.

    ``rollout`` plays a whole control trajectory ``u`` (K, n_motors) [m of cable contraction,
    or N of tension in tension control] from the environment's reset state (the state the last
    ``reset`` produced; at rest unless reset noise is on) and returns a
    :class:`~soft_envs.sim.Trajectory`, with exact sensitivities when ``dudz``
    (K, n_motors, nz) is given. It does not change the environment's own state. ``u`` is
    applied as given (the environments' action clipping and motor speed limit are not applied;
    keep ``u`` within ``robot.u_bounds`` yourself).

    In :class:`~soft_envs.envs.base.SoftRobotEnv`, stepping the environment and ``rollout`` agree
    up to the Newton tolerance (the controls actually applied per simulation step are
    ``info["u_substeps"]``), and ``get_state``/``set_state`` round-trip exactly.
    """

    @property
    def simulator(self) -> Simulator: ...

    @property
    def robot(self) -> Robot: ...

    @property
    def dt(self) -> float: ...            # simulation time step [s] (one env step = frame_skip of these)

    def rollout(self, u: np.ndarray, dudz: np.ndarray | None = None, *,
                store_dxdz: bool = False) -> Trajectory: ...

    def reset_state(self) -> tuple[np.ndarray, np.ndarray]: ...   # (x_0, x_{-1}) of rollouts

    def get_state(self) -> dict[str, Any]: ...

    def set_state(self, state: dict[str, Any]) -> None: ...

    def com(self) -> np.ndarray: ...       # current centre of mass (3,)

    def cable_deformation(self) -> np.ndarray: ...   # current Gamma per tendon
