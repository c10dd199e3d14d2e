"""A rollout from an environment's rest state, differentiated with respect to a parameter block,
the rest state included: what calibration (physical parameters,
:func:`~soft_envs.envs.identification.parameter_rollout`) and co-design (design parameters,
:func:`~soft_envs.envs.design.design_rollout`) both play.
"""
from __future__ import annotations

import numpy as np

from ..sim import Trajectory

__all__ = ["rest_start_rollout"]


def rest_start_rollout(env, u: np.ndarray, params, *, dudz: np.ndarray | None = None,
                       caller: str = "rest_start_rollout") -> Trajectory:
    """Play ``u`` (K, n_motors) from the rest state of ``env`` (an unwrapped environment reset
    without noise, as :func:`~soft_envs.envs.make_gradient_env` makes it) with the sensitivities
    to ``params`` (names of physical parameters, or a parameter block such as
    :class:`~soft_envs.sim.design.DesignParameters`) of the whole rollout, the rest state and
    its stick anchors included (:meth:`~soft_envs.sim.Simulator.rest_sensitivity`): the rest
    state depends on the parameters, so the rollout starts from the rest state recomputed with
    its derivative, which must be the environment's reset state. With ``dudz`` (K, n_motors, nz)
    also the sensitivities to the controls' parameters. ValueError, naming ``caller``, when the
    environment's reset state is not its rest state."""
    sim = env.simulator
    x0, h0, dx0, dh0 = sim.rest_sensitivity(params, u=env.robot.u_rest)
    x_reset, xm1_reset = env.reset_state()
    if not (np.array_equal(x_reset, x0) and np.array_equal(xm1_reset, x0)):
        raise ValueError(f"{caller} needs an environment reset at rest without noise "
                         "(reset_noise_scale=0, as make_gradient_env makes it)")
    return sim.rollout(u, x0=x0, history0=h0, dudz=dudz, params=params, dx0dtheta=dx0, dhistory0dtheta=dh0)
