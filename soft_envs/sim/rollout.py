"""Rollouts: control steps chained from a state, with the forward sensitivities alongside.

A control step (:func:`control_step`) is ``substeps`` implicit-Euler steps (paper eq. 4, each
the one loop body :func:`~.state.advance`) with the controls joined by straight lines
(:mod:`.substeps`); with one sub-step it is the paper's step. :func:`run_rollout` chains K of
them sharing one factorisation cache, records the states at the ends of the control steps and,
when asked, runs the recurrence of eqs. 10-11 over every sub-step
(:class:`~.sensitivity.ForwardSensitivities`, set up here: :func:`forward_sensitivities`).
"""
from __future__ import annotations

import numpy as np

from .linsolve import FactorCache
from .sensitivity import ForwardSensitivities
from .state import State, advance
from .substeps import substep_controls, substep_jacobian
from .trajectory import Trajectory

__all__ = ["control_step", "run_rollout", "forward_sensitivities", "start_controls", "RolloutStopped"]


class RolloutStopped(Exception):
    """A rollout's ``stop`` callback asked it to end after control step ``k`` (what an objective
    does when a lower bound of its value already exceeds what it could accept: the rest of the
    rollout cannot change the decision). Not a failure: nothing is wrong with the physics."""

    def __init__(self, k: int):
        super().__init__(f"the rollout was stopped after control step {k}")
        self.k = k


def start_controls(state: State, u_rest: np.ndarray) -> np.ndarray:
    """The controls a control step from ``state`` starts at: ``state.u``, else ``u_rest``."""
    return u_rest if state.u is None else state.u


def control_step(newton, state: State, u: np.ndarray, substeps: int, u_rest: np.ndarray, *,
                 cache: FactorCache | None = None) -> State:
    """The :class:`State` one control step after ``state`` under controls ``u`` (n_motors,):
    ``substeps`` solver steps along the straight line from :func:`start_controls` to ``u``;
    ``k`` counts the control step once. ``cache``: the factorisation the sub-steps share (and
    leave for the next step); None: start afresh."""
    if substeps == 1:
        return advance(newton, state, u, cache=cache)[0]
    cache = FactorCache() if cache is None else cache
    start = state
    for u_j in substep_controls(u[None, :], start_controls(state, u_rest), substeps):
        state = advance(newton, state, u_j, cache=cache)[0]
    return state.replace(k=start.k + 1)


def forward_sensitivities(newton, masses, dudz, K: int, n_motors: int, substeps: int, *, store_dxdz=False,
                          params=(), dx0dtheta=None, dhistory0dtheta=None, x0=None) -> ForwardSensitivities | None:
    """The recurrence of eqs. 10-11 for a rollout of K control steps, or None when neither
    ``dudz`` (K, n_motors, nz) nor ``params`` asks for derivatives (checks ``dudz``; carries it
    to the sub-steps)."""
    if dudz is not None:
        dudz = np.asarray(dudz, dtype=np.float64)
        if dudz.ndim != 3 or dudz.shape[:2] != (K, n_motors):
            raise ValueError(f"dudz must have shape ({K}, {n_motors}, nz), got {dudz.shape}")
        if not np.isfinite(dudz).all():
            raise ValueError(f"dudz contains NaN or inf at {np.argwhere(~np.isfinite(dudz))[:5].tolist()}")
    elif not params:
        return None
    dudz = np.zeros((K, n_motors, 0)) if dudz is None else dudz
    return ForwardSensitivities(newton, masses, substep_jacobian(dudz, substeps), store_dxdz, params=params,
                                dx0dtheta=dx0dtheta, dhistory0dtheta=dhistory0dtheta, x0=x0,
                                record_every=substeps)


def run_rollout(newton, robot, start: State, u: np.ndarray, substeps: int, sens: ForwardSensitivities | None = None,
                *, want_z: bool = False, keep_substeps: bool = False, stop=None) -> Trajectory:
    """K control steps of controls ``u`` (K, n_motors) from ``start`` (inputs checked by the
    caller), with ``sens`` stepped alongside (``want_z``: its control Jacobians go into the
    trajectory; its parameter block's always do). The :class:`Trajectory` holds the ends of
    the control steps; ``keep_substeps`` also keeps every sub-step's positions and controls in
    ``info["substep_x"]`` (K n + 1, n, 3) and ``info["substep_u"]`` (the adjoint needs them).
    ``stop(k, com, gamma)``, if given, sees the centre of mass (3,) and the cable deformations
    (T,) of every state k = 1..K as it is reached; when it returns True the rollout ends there
    with :class:`RolloutStopped`."""
    system = newton.system
    cables = system.cables
    K = len(u)
    n_nodes = robot.mesh.n_nodes
    u_fine = substep_controls(u, start_controls(start, robot.u_rest), substeps)
    xs = np.empty((K + 1, n_nodes, 3))
    xs[0] = start.x
    fine = np.empty((K * substeps + 1, n_nodes, 3)) if keep_substeps else None
    if fine is not None:
        fine[0] = start.x
    gam = np.empty((K + 1, cables.n_tendons))
    gam[0] = cables.deformation(start.x, robot.u_rest)      # before the first control
    iters = np.zeros(K, dtype=np.int64)
    cache = FactorCache()
    state = start
    for f in range(K * substeps):
        new, info = advance(newton, state, u_fine[f], cache=cache, need_exact=sens is not None)
        if sens is not None:
            sens.step(f, info.solver, new.x, state.x, u_fine[f], state.history, x_prev2=state.x_prev)
        if fine is not None:
            fine[f + 1] = new.x
        k, j = divmod(f, substeps)
        iters[k] += info.iterations
        state = new
        if j == substeps - 1:
            if substeps > 1:
                state = state.replace(k=start.k + k + 1)
            xs[k + 1] = state.x
            gam[k + 1] = cables.deformation(state.x, u[k])
            if stop is not None and stop(k + 1, robot.com(state.x), gam[k + 1]):
                raise RolloutStopped(k + 1)
    masses = robot.body_node_masses          # the robot's own COM (a box left out)
    com = np.einsum("kni,n->ki", xs, masses) / masses.sum()
    traj = Trajectory(x=xs, com=com, cable_deformation=gam, u=u, newton_iterations=iters,
                      info={"history": state.history, "state": state, "start": start, "substeps": substeps})
    if fine is not None:
        traj.info["substep_x"], traj.info["substep_u"] = fine, u_fine
    if want_z:
        traj.dcomdz, traj.dgammadz, traj.dxdz = sens.dcomdz, sens.dgammadz, sens.dxdz
    if sens is not None and sens.params:
        traj.dxdtheta, traj.dcomdtheta, traj.dgammadtheta = sens.dxdtheta, sens.dcomdtheta, sens.dgammadtheta
    return traj
