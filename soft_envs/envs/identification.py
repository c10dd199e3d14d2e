"""System identification through the environments: physical parameters by name, tracked markers,
and rollouts with their sensitivities to the parameters (``trajopt calibrate``).

Re-exports for ``trajopt`` (which never imports :mod:`soft_envs.sim`): :data:`PHYSICAL_PARAMETERS`
(name -> unit and description), :func:`parameter_values`, :func:`with_parameters`,
:func:`scale_parameters`, :class:`MarkerSet` and :class:`Marker`. :func:`parameter_rollout` is what
``SoftRobotEnv.rollout_parameters`` (an optional member of the
:class:`~soft_envs.envs.protocol.GradientEnv` protocol) does.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..sim import Trajectory
from ..sim.markers import Marker, MarkerSet
from ..sim.parameters import PARAMETERS as PHYSICAL_PARAMETERS
from ..sim.parameters import check_parameters, parameter_values, scale_parameters, with_parameters
from .rest_rollout import rest_start_rollout

__all__ = ["PHYSICAL_PARAMETERS", "parameter_values", "with_parameters", "scale_parameters", "check_parameters",
           "Marker", "MarkerSet", "parameter_rollout"]


def parameter_rollout(env, u: np.ndarray, parameters: Sequence[str]) -> Trajectory:
    """Play ``u`` (K, n_motors) from the rest state of ``env`` (an unwrapped
    :class:`~soft_envs.envs.SoftRobotEnv` reset without noise, as :func:`make_gradient_env`
    makes it) and differentiate the whole rollout, rest state included, with respect to the
    physical ``parameters``: ``traj.dxdtheta`` (K+1, 3n, ntheta), ``traj.dcomdtheta``. The rest
    state and the friction law's stick anchors are those of
    :meth:`~soft_envs.sim.Simulator.rest_sensitivity`. ValueError for an unknown or inapplicable
    parameter, or an environment whose reset state is not its rest state
    (:func:`~soft_envs.envs.rest_rollout.rest_start_rollout`)."""
    return rest_start_rollout(env, u, parameters, caller="rollout_parameters")
