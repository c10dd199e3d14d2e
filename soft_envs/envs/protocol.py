"""The gradient protocol: the one way ``trajopt`` reaches the physics.

Any object satisfying :class:`GradientEnv` (usually ``env.unwrapped`` of a Gymnasium
environment) can be optimised by ``trajopt.optimize_gait``; the shipped ``SoftTripod-v2`` and
``SoftPuppy-v2`` do (and their older versions). :func:`~soft_envs.envs.factory.as_gradient_env` finds it in a (wrapped)
environment, or builds a bare one (:func:`~soft_envs.envs.factory.make_gradient_env`) for a
robot, a shipped robot name or a robot.toml path.
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..sim import Robot, Trajectory

__all__ = ["GradientEnv", "GRADIENT_ENV_MEMBERS", "PARAMETER_MEMBERS"]


@runtime_checkable
class GradientEnv(Protocol):
    """Analytic-gradient hooks of a soft-robot environment.

    ``rollout`` plays a whole control trajectory ``u`` (K, n_motors) [m of cable contraction:
    length control, paper eq. 2; the simulator's tension control (appendix A,
    ``Simulator(control="tension")``) is not an environment's] from the environment's reset
    state (the state the last ``reset`` produced; at rest unless reset noise is on), one
    control step of ``timestep`` seconds per row (``substeps`` physics steps each, the controls
    joined by straight lines), and returns a
    :class:`~soft_envs.sim.Trajectory`, with exact sensitivities when ``dudz`` (K, n_motors, nz)
    is given. It does not change the environment's own state. ``stop(k, com, gamma)``, when
    given, sees each state's centre of mass and cable deformations as they are reached and may end
    the rollout (:class:`~soft_envs.sim.RolloutStopped`; an objective that already knows a trial
    is rejected).
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
    def timestep(self) -> float: ...        # control step h [s] of rollouts (one row of u)

    @property
    def substeps(self) -> int: ...          # physics steps per control step (timestep / substeps each)

    @property
    def incline_deg(self) -> float: ...     # ground slope [deg]

    @property
    def contact_model(self) -> str: ...     # "paper" (II-C, viscous-like friction) or "coulomb"

    @property
    def gravity(self) -> np.ndarray: ...    # (3,) [m/s^2]

    def rollout(self, u: np.ndarray, dudz: np.ndarray | None = None, *,
                store_dxdz: bool = False, stop=None) -> Trajectory: ...

    def reset_state(self) -> tuple[np.ndarray, np.ndarray]: ...   # (x_0, x_{-1}) of rollouts

    def get_state(self) -> dict[str, Any]: ...

    def set_state(self, state: dict[str, Any]) -> None: ...

    def com(self) -> np.ndarray: ...       # current centre of mass (3,)

    def cable_deformation(self, x: np.ndarray | None = None, u: np.ndarray | None = None
                          ) -> np.ndarray: ...   # Gamma per tendon (current state by default)

    def cable_tension(self, x: np.ndarray | None = None, u: np.ndarray | None = None
                      ) -> np.ndarray: ...       # tension per tendon [N] (current state by default)


#: The members of :class:`GradientEnv`, checked by :func:`~soft_envs.envs.factory.as_gradient_env`.
GRADIENT_ENV_MEMBERS = ("robot", "timestep", "substeps", "incline_deg", "contact_model", "gravity", "rollout",
                        "reset_state", "get_state", "set_state", "com", "cable_deformation", "cable_tension")
#: Optional members of :class:`GradientEnv` (parameter sensitivities for calibration).
PARAMETER_MEMBERS = ("rollout_parameters",)
