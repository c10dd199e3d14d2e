r"""Sensitivity analysis of whole rollouts (paper III-A, eqs. 8-11).

Every step satisfies ``R_k = dPhi_k/dx_k (x_k, x_{k-1}, x_{k-2}, u_k) = 0`` (eq. 4 as the
gradient of the incremental potential). Differentiating all of them with respect to the
parameters z (eqs. 8-9) gives a block lower-triangular system whose block rows are the
recurrence of eq. 10 for ``S_k = dx_k/dz``:

.. math::
    H_k S_k = -\big(A_k S_{k-1} + C S_{k-2} + G_k U_k\big),

with ``H_k = d^2 Phi_k / dx_k^2`` at the converged state, ``A_k = dR_k/dx_{k-1} = -2M/h^2 +
d^2E/(dx_k dx_{k-1})`` (lagged terms: the friction law depends on ``x_{k-1}`` through the
displacement and through the normal force ``N_{k-1}``), ``C = M/h^2``, ``G_k = dR_k/du_k`` (the
energy terms' control Jacobians) and ``U_k = du_k/dz``. Terms with a history ``p`` (the
Coulomb law's stick anchors, updated after each step by ``p_k = Pi(x_k, p_{k-1})``) add
``D_k P_{k-1}`` with ``D_k = dR_k/dp_{k-1}`` to the bracket, and their history's derivative
follows ``P_k = dPi/dx S_k + dPi/dp P_{k-1}``. Eq. 11 is the first block (``S_{k-1} =
S_{k-2} = 0`` for a rollout that starts at rest). One multi-right-hand-side solve per step
reuses the Newton factorisation of ``H_k``.

The adjoint (reverse) form gives ``dO/du`` of a scalar ``O = sum_k o_k(x_k)`` at the cost of one
backward pass, whatever the number of parameters:

.. math::
    H_j \lambda_j = -(\partial o/\partial x_j + A_{j+1}^T \lambda_{j+1} + C \lambda_{j+2}
                      - (\partial \Pi_j/\partial x_j)^T \mu_j),
    \qquad \mu_{j-1} = -D_j^T \lambda_j + (\partial \Pi_j/\partial p_{j-1})^T \mu_j,
    \qquad dO/du_k = \lambda_k^T G_k ,

with ``mu`` the adjoints of the histories (``mu_K = 0``; absent without history).
"""
from __future__ import annotations

import numpy as np

from .parameter_block import parameter_block
from .state import State, next_state

__all__ = ["ForwardSensitivities", "adjoint_pass"]


class ForwardSensitivities:
    """The forward recurrence (eqs. 10-11) alongside a rollout of K steps from rest.

    ``newton`` is the rollout's :class:`~soft_envs.sim.integrator.NewtonSolver`, ``dudz``
    (K, n_motors, nz) the control Jacobian. After :meth:`step` has been called for every
    step, ``dcomdz`` (K+1, 3, nz), ``dgammadz`` (K+1, T, nz) and, with ``store_dxdz``,
    ``dxdz`` (K+1, 3n, nz) hold the Jacobians of the centre of mass, the cable deformations
    and the states (entry 0, the given initial state, is zero).

    Parameter block: with ``params`` (names of :data:`~soft_envs.sim.parameters.PARAMETERS`) the
    same recurrence runs for ``S_k = dx_k/dtheta`` with the right-hand side ``-dR_k/dtheta =
    -(d(dE/dx)/dtheta + dM/dtheta a_k)`` (the energy terms' parameter Jacobians and the mass
    matrix's derivative times the acceleration ``a_k = (x_k - 2x_{k-1} + x_{k-2}) / h^2``); the
    histories' derivatives follow ``P_k = dPi/dx S_k + dPi/dp P_{k-1} + dPi/dtheta``. The
    initial state's derivative ``dx0dtheta`` (3n, ntheta) (a rest state depends on the
    parameters; the rollout starts at rest, so ``x_{-1}`` has the same) and the initial
    histories' ``dhistory0dtheta`` (a tuple aligned with the terms) start it; ``x0`` gives the
    COM's entry 0. Then ``dxdtheta`` (K+1, 3n, ntheta), ``dcomdtheta`` (K+1, 3, ntheta)
    (which includes the masses' own dependence) and, with ``deformations`` (the default),
    ``dgammadtheta`` (K+1, T, ntheta) ``= dL/dx dx/dtheta + dGamma/dtheta`` (the block's part at
    fixed x, :meth:`~.parameter_block.ParameterBlock.deformation_jacobian`; entry 0 needs
    ``x0``) hold the results. Both blocks share each step's
    one multi-right-hand-side solve. ``params`` may also be a
    :class:`~.parameter_block.ParameterBlock` (design parameters, :mod:`soft_envs.sim.design`):
    the block gives the three partial derivatives.

    Physics sub-steps (:mod:`.substeps`): the recurrence runs over every step of the solver
    (``dudz`` holds the sub-steps' rows, :func:`~.substeps.substep_jacobian`) and records the
    Jacobians of every ``record_every``-th state only, the ends of the control steps: the
    arrays above then have ``K / record_every + 1`` entries."""

    def __init__(self, newton, masses: np.ndarray, dudz: np.ndarray, store_dxdz: bool = False,
                 params=(), dx0dtheta: np.ndarray | None = None, dhistory0dtheta: tuple | None = None,
                 x0: np.ndarray | None = None, record_every: int = 1, deformations: bool = True):
        self.newton = newton
        system = newton.system
        K, _, nz = dudz.shape
        self.record_every = int(record_every)
        if K % self.record_every:
            raise ValueError(f"{K} steps are not a whole number of control steps of {record_every} sub-steps")
        K //= self.record_every
        self.dudz = dudz
        self.masses = np.asarray(masses)
        self.total_mass = self.masses.sum()
        self.block = parameter_block(params)
        self.params = self.block.names
        self.nz, nt = nz, len(self.params)
        self.S1 = np.zeros((system.n_dof, nz + nt))       # S_{k-1}, [dx/dz | dx/dtheta]
        if nt and dx0dtheta is not None:
            self.S1[:, nz:] = dx0dtheta
        self.S2 = self.S1.copy()                          # S_{k-2} (at rest: x_{-1} = x_0)
        self.dcomdz = np.zeros((K + 1, 3, nz))
        self.dgammadz = np.zeros((K + 1, system.cables.n_tendons, nz))
        self.dxdz = np.zeros((K + 1, system.n_dof, nz)) if store_dxdz else None
        self.P = None                               # dhistory_{k-1}/dz per term (x_0 is given: 0)
        self._dh0 = dhistory0dtheta
        self.dxdtheta = self.dcomdtheta = self.dgammadtheta = None
        if nt:
            self.mass_jacobian = self.block.mass_jacobian(system)           # (3n, nt)
            self.dxdtheta = np.zeros((K + 1, system.n_dof, nt))
            self.dxdtheta[0] = self.S1[:, nz:]
            self.dcomdtheta = np.zeros((K + 1, 3, nt))
            if x0 is not None:
                self.dcomdtheta[0] = self._dcom(x0, self.S1[:, nz:])
            if deformations:
                self.dgammadtheta = np.zeros((K + 1, system.cables.n_tendons, nt))
                if x0 is not None:
                    self.dgammadtheta[0] = self._dgamma(x0, self.S1[:, nz:])

    def _dcom(self, x: np.ndarray, St: np.ndarray) -> np.ndarray:
        """d COM/dtheta (3, nt) at x: positions move (St) and masses change."""
        nt = St.shape[1]
        com = self.masses @ x / self.total_mass
        dm = self.mass_jacobian[::3]                                         # (n, nt)
        dcom = (self.masses @ St.reshape(-1, 3 * nt)).reshape(3, nt) + (x - com).T @ dm
        return dcom / self.total_mass

    def _dgamma(self, x: np.ndarray, St: np.ndarray, dL: np.ndarray | None = None) -> np.ndarray:
        """d Gamma/dtheta (T, nt) at x: positions move (St, through ``dL`` = dL/dx at x) and the
        block moves the cables' points and lengths."""
        system = self.newton.system
        cables = system.cables
        if not cables.n_tendons:
            return np.zeros((0, St.shape[1]))
        dL = cables.length_gradients(x) if dL is None else dL
        return dL @ St + self.block.deformation_jacobian(system, x)

    def hold(self) -> None:
        """The next step starts at rest, ``x_{k-2} = x_{k-1}`` (the relaxation steps of
        :meth:`~soft_envs.sim.Simulator.rest_state`)."""
        self.S2 = self.S1.copy()

    def _initial_histories(self, history: tuple) -> tuple:
        ncol = self.S1.shape[1]
        P = []
        for i, h in enumerate(history):
            p = None if h is None else np.zeros((h.size, ncol))
            if p is not None and self._dh0 is not None and self._dh0[i] is not None:
                p[:, self.nz:] = self._dh0[i]
            P.append(p)
        return tuple(P)

    def step(self, k: int, solver, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray,
             history: tuple, x_prev2: np.ndarray | None = None) -> None:
        """Advance the recurrence by the step that took ``x_prev`` to ``x`` = state k+1 under
        controls ``u = u_k`` and the energy terms' ``history``; ``solver`` holds the
        factorisation of the exact ``H`` at ``x``. ``x_prev2`` (the state before ``x_prev``) is
        needed by the parameter block when a parameter changes the masses."""
        system = self.newton.system
        U = self.dudz[k]
        nz = self.nz
        if self.P is None:
            self.P = self._initial_histories(history)
        rhs = self.newton.inertia[:, None] * (2.0 * self.S1 - self.S2)
        rhs -= system.prev_product(x, x_prev, u, self.S1, history)
        if nz:
            rhs[:, :nz] -= system.control_jacobian(x, x_prev, u, history) @ U
        if system.has_history:
            d = np.zeros_like(rhs)
            system.history_product(x, x_prev, u, history, self.P, d)
            rhs -= d
        if self.params:
            rhs[:, nz:] -= self.block.force_jacobian(system, x, x_prev, u, history)
            if self.mass_jacobian.any():
                if x_prev2 is None:
                    raise ValueError("the parameter block needs x_prev2 for parameters that change the masses")
                acc = (x - 2.0 * x_prev + x_prev2).reshape(-1) / self.newton.dt ** 2
                rhs[:, nz:] -= self.mass_jacobian * acc[:, None]
        S = np.zeros_like(self.S1)
        S[system.free] = solver.solve(np.ascontiguousarray(rhs[system.free]))
        if system.has_history:
            self.P = system.history_tangent(x, x_prev, history, S, self.P)
            if self.params:
                for p, e in zip(self.P, self.block.history_jacobian(system, x, x_prev, history)):
                    if p is not None and e is not None:
                        p[:, nz:] += e
        self.S2, self.S1 = self.S1, S
        if (k + 1) % self.record_every == 0:
            self._record((k + 1) // self.record_every - 1, x, S, U)

    def _record(self, k: int, x: np.ndarray, S: np.ndarray, U: np.ndarray) -> None:
        """Store the Jacobians of state ``k + 1`` (``S = dx/d[z | theta]`` there; ``U`` the
        controls' ``du/dz`` of the step that reached it)."""
        system = self.newton.system
        nz = self.nz
        cables = system.cables
        dL = None
        if nz:
            Sz = S[:, :nz]
            self.dcomdz[k + 1] = (self.masses @ Sz.reshape(-1, 3 * nz)).reshape(3, nz) / self.total_mass
            dL = cables.length_gradients(x)
            self.dgammadz[k + 1] = cables.deformation_jacobian(dL, Sz, U)
            if self.dxdz is not None:
                self.dxdz[k + 1] = Sz
        if self.params and k + 1 < len(self.dxdtheta):
            self.dxdtheta[k + 1] = S[:, nz:]
            self.dcomdtheta[k + 1] = self._dcom(x, S[:, nz:])
            if self.dgammadtheta is not None:
                self.dgammadtheta[k + 1] = self._dgamma(x, S[:, nz:], dL)


def adjoint_pass(newton, xs: np.ndarray, us: np.ndarray, dobj_dx: np.ndarray, history0=None, *,
                 start: State | None = None) -> np.ndarray:
    """``dO/du`` (K, n_motors) for states ``xs`` (K+1, n, 3) of a rollout with controls ``us``
    (K, n_motors) and ``dobj_dx`` (K+1, n, 3) (the entry for x_0 is ignored: x_0 is given).
    ``start`` is the :class:`~.state.State` the rollout started from (``traj.info["start"]``);
    without it, the rollout must have started at rest (``x_{-1} = x_0``) with the terms' history
    ``history0`` (default: at rest at x_0). The states each step started from are re-walked
    from ``start`` with the rollout's own bookkeeping (:func:`~.state.next_state`)."""
    system = newton.system
    K = len(us)
    n_dof = system.n_dof
    free = system.free
    inertia = newton.inertia
    if start is None:
        start = State.at_rest(xs[0], system.resolve_history(history0, xs[0]))
    positions = xs.view()
    positions.flags.writeable = False               # rows become the states' x without copies
    states = [start]                                # the state each step starts from
    for j in range(1, K):
        states.append(next_state(system, states[-1], positions[j]))
    lam_next = np.zeros(n_dof)      # lambda_{j+1}
    lam_next2 = np.zeros(n_dof)     # lambda_{j+2}
    mu = tuple(None if h is None else np.zeros(h.size) for h in start.history)     # mu_K = 0
    out = np.zeros_like(us, dtype=np.float64)
    for j in range(K, 0, -1):
        xj = xs[j]
        xjm1 = xs[j - 1]
        xjm2 = states[j - 1].x_prev
        h = states[j - 1].history
        rhs = dobj_dx[j].reshape(-1).copy()
        if j < K:
            # A_{j+1}^T lambda_{j+1} with A = -2M/h^2 + the lagged terms' cross derivative
            rhs += -2.0 * inertia * lam_next
            system.prev_product_T(xs[j + 1], xj, us[j], lam_next, rhs, states[j].history)
        if j + 1 < K:
            rhs += inertia * lam_next2
        if system.has_history:
            tx, th = system.history_tangent_T(xj, xjm1, h, mu)
            rhs -= tx
        solver = newton.factorize_exact_at(xj, xjm1, xjm2, us[j - 1], history=h)
        lam = np.zeros(n_dof)
        lam[free] = -solver.solve(np.ascontiguousarray(rhs[free]))
        out[j - 1] = lam @ system.control_jacobian(xj, xjm1, us[j - 1], h)
        if system.has_history:
            dT = system.history_product_T(xj, xjm1, us[j - 1], h, lam)
            mu = tuple(None if a is None else b - a for a, b in zip(dT, th))
        lam_next2, lam_next = lam_next, lam
    return out
