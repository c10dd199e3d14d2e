"""Co-design through the environments: the design parameters a robot declares, the
rollouts' sensitivities to them, and writing a designed robot.

Re-exports for ``trajopt`` (which never imports :mod:`soft_envs.sim`):
:func:`~soft_envs.sim.design.load_design` (the ``[design]`` table of a robot.toml as a
:class:`~soft_envs.sim.design.DesignParameters` block), :data:`KINDS`, :data:`MIN_CLEARANCE`,
:data:`MAX_MASS_LOSS` and :func:`~soft_envs.sim.design.write_designed_robot`.
:func:`design_rollout` is a rollout from the rest state with the Jacobians of the whole rollout
with respect to the controls' parameters and the design, through one forward recurrence.
"""
from __future__ import annotations

import numpy as np

from ..sim import Trajectory
from ..sim.design import KINDS, MAX_MASS_LOSS, MIN_CLEARANCE, DesignParameters, load_design, write_designed_robot
from .rest_rollout import rest_start_rollout

__all__ = ["KINDS", "MAX_MASS_LOSS", "MIN_CLEARANCE", "DesignParameters", "load_design", "write_designed_robot",
           "design_rollout"]


def design_rollout(env, u: np.ndarray, design: DesignParameters, dudz: np.ndarray | None = None) -> Trajectory:
    """Play ``u`` (K, n_motors) from the rest state of ``env`` (an unwrapped environment reset
    without noise, as :func:`~soft_envs.envs.make_gradient_env` makes it, of ``design.robot``)
    and differentiate the whole rollout, rest state included: ``traj.dcomdtheta`` (K+1, 3,
    len(design)) with respect to the design, and with ``dudz`` (K, n_motors, nz) ``traj.dcomdz``
    too (the controls' parameters; the rest state does not depend on them). ValueError when the
    environment is not at rest or simulates another robot
    (:func:`~soft_envs.envs.rest_rollout.rest_start_rollout`)."""
    return rest_start_rollout(env, u, design, dudz=dudz, caller="design_rollout")
