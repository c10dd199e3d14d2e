"""The gradient protocol: the one way ``trajopt`` reaches the physics.

Any object satisfying :class:`GradientEnv` (usually ``env.unwrapped`` of a Gymnasium
environment) can be optimised by ``trajopt.optimize_gait``; the shipped ``SoftTripod-v0`` and
``SoftPuppy-v0`` do. :func:`as_gradient_env` finds it in a (wrapped) environment, or builds a bare
one (:func:`make_gradient_env`) for a robot, a shipped robot name or a robot.toml path.
"""
from __future__ import annotations

import os
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..sim import Robot, Trajectory
from .base import PAPER_TIMESTEP, SoftRobotEnv

__all__ = ["GradientEnv", "GRADIENT_ENV_MEMBERS", "PARAMETER_MEMBERS", "as_gradient_env", "make_gradient_env"]


@runtime_checkable
class GradientEnv(Protocol):
    """Analytic-gradient hooks of a soft-robot environment.

    ``rollout`` plays a whole control trajectory ``u`` (K, n_motors) [m of cable contraction:
    length control, paper eq. 2; the simulator's tension control (appendix A,
    ``Simulator(control="tension")``) is not an environment's] from the environment's reset
    state (the state the last ``reset`` produced; at rest unless reset noise is on), one
    simulation step of ``timestep`` seconds per row, and returns a
    :class:`~soft_envs.sim.Trajectory`, with exact sensitivities when ``dudz`` (K, n_motors, nz)
    is given. It does not change the environment's own state.
    ``u`` is applied as given (the environments' action clipping and motor speed limit are not
    applied; keep ``u`` within ``robot.u_bounds`` yourself). A failed step raises
    :class:`~soft_envs.sim.SimulationError` (re-exported by :mod:`soft_envs.envs`).

    Optional member (``trajopt calibrate`` needs it; :data:`PARAMETER_MEMBERS`):
    ``rollout_parameters(u, parameters)`` plays ``u`` from the rest state like ``rollout`` and
    returns the Trajectory with ``dxdtheta`` (K+1, 3n, ntheta) and ``dcomdtheta``, the
    sensitivities of the whole rollout (rest state included) to the physical ``parameters``
    (names of :data:`soft_envs.envs.PHYSICAL_PARAMETERS`: ``youngs_modulus``,
    ``poisson_ratio``, ``density``, ``payload_mass``, ``contact_stiffness``, ``friction`` or
    ``friction_coefficient`` (by the contact law), ``cable_stiffness``).

    In :class:`~soft_envs.envs.base.SoftRobotEnv`, stepping the environment and ``rollout`` agree
    up to the Newton tolerance (the controls actually applied per simulation step are
    ``info["u_substeps"]``), and ``get_state``/``set_state`` round-trip exactly.
    """

    @property
    def robot(self) -> Robot: ...           # mesh, masses, motors, tendons, body length

    @property
    def timestep(self) -> float: ...        # simulation time step h [s] of rollouts

    @property
    def incline_deg(self) -> float: ...     # ground slope [deg]

    @property
    def contact_model(self) -> str: ...     # "paper" (II-C, viscous-like friction) or "coulomb"

    @property
    def gravity(self) -> np.ndarray: ...    # (3,) [m/s^2]

    def rollout(self, u: np.ndarray, dudz: np.ndarray | None = None, *,
                store_dxdz: bool = False) -> Trajectory: ...

    def reset_state(self) -> tuple[np.ndarray, np.ndarray]: ...   # (x_0, x_{-1}) of rollouts

    def get_state(self) -> dict[str, Any]: ...

    def set_state(self, state: dict[str, Any]) -> None: ...

    def com(self) -> np.ndarray: ...       # current centre of mass (3,)

    def cable_deformation(self, x: np.ndarray | None = None, u: np.ndarray | None = None
                          ) -> np.ndarray: ...   # Gamma per tendon (current state by default)

    def cable_tension(self, x: np.ndarray | None = None, u: np.ndarray | None = None
                      ) -> np.ndarray: ...       # tension per tendon [N] (current state by default)


#: The members of :class:`GradientEnv`, checked by :func:`as_gradient_env`.
GRADIENT_ENV_MEMBERS = ("robot", "timestep", "incline_deg", "contact_model", "gravity", "rollout",
                        "reset_state", "get_state", "set_state", "com", "cable_deformation", "cable_tension")
#: Optional members of :class:`GradientEnv` (parameter sensitivities for calibration).
PARAMETER_MEMBERS = ("rollout_parameters",)


def make_gradient_env(robot: str | os.PathLike | Robot = "puppy", *, incline_deg: float = 0.0,
                      heading_deg: float = 0.0, timestep: float = PAPER_TIMESTEP,
                      contact: str | None = None) -> SoftRobotEnv:
    """A bare environment for trajectory optimisation, reset without noise: its rollouts start
    at the exact rest state with the motors at ``robot.u_rest``.

    ``robot``: a shipped robot name (``"tripod"``, ``"puppy"``: their registered classes), a
    robot.toml path or a :class:`~soft_envs.sim.Robot`; the ground slopes by ``incline_deg``,
    rising along ``heading_deg`` (degrees from +x towards +z); ``timestep`` is the simulation
    time step [s]; ``contact`` the contact law ("paper", "coulomb"; None: the robot file's)."""
    from .puppy import SoftPuppyEnv
    from .tripod import SoftTripodEnv
    shipped = {"tripod": SoftTripodEnv, "puppy": SoftPuppyEnv}
    cls = shipped.get(robot, SoftRobotEnv) if isinstance(robot, str) else SoftRobotEnv
    env = cls(robot, incline_deg=incline_deg, target_heading_deg=heading_deg, timestep=timestep,
              reset_noise_scale=0.0, contact=contact)
    env.reset(seed=0)
    return env


def as_gradient_env(env_or_robot: Any, *, incline_deg: float = 0.0, heading_deg: float = 0.0,
                    contact: str | None = None) -> GradientEnv:
    """The :class:`GradientEnv` of a (wrapped) environment, i.e. its ``unwrapped`` object, or
    :func:`make_gradient_env` of a :class:`~soft_envs.sim.Robot`, a robot name or a robot.toml
    path. TypeError when the environment lacks a member of the protocol."""
    if isinstance(env_or_robot, (Robot, str, os.PathLike)):
        return make_gradient_env(env_or_robot, incline_deg=incline_deg, heading_deg=heading_deg, contact=contact)
    target = getattr(env_or_robot, "unwrapped", env_or_robot)
    missing = [name for name in GRADIENT_ENV_MEMBERS if not hasattr(target, name)]
    if missing:
        raise TypeError(f"{type(target).__name__} does not offer the gradient hook(s) {missing} "
                        "(see soft_envs.envs.protocol.GradientEnv)")
    return target
