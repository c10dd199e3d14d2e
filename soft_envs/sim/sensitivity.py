r"""Sensitivity analysis of whole rollouts (paper III-A, eqs. 8-11).

Every step satisfies ``R_k = dPhi_k/dx_k (x_k, x_{k-1}, x_{k-2}, u_k) = 0``. Differentiating
(eq. 10) gives the block lower-triangular recurrence for ``S_k = dx_k/dz``:

.. math::
    H_k S_k = -\big(A_k S_{k-1} + C S_{k-2} + G_k U_k\big),

with ``H_k = d^2 Phi_k / dx_k^2`` at the converged state, ``A_k = dR_k/dx_{k-1} = -2M/h^2 +
d^2E/(dx_k dx_{k-1})`` (the friction term depends on ``x_{k-1}`` through the displacement and
through the normal force ``N_{k-1}``), ``C = M/h^2`` and ``G_k = dR_k/du_k``: per tendon
``Q''(Gamma) dL/dx`` in length control, ``dL/dx`` in tension control, summed per motor.
``U_k = du_k/dz``. One multi-right-hand-side solve per step reuses the Newton factorisation.

The adjoint (reverse) form gives ``dO/du`` of a scalar ``O = sum_k o_k(x_k)`` at the cost of one
backward pass, whatever the number of parameters:

.. math::
    H_j \lambda_j = -(\partial o/\partial x_j + A_{j+1}^T \lambda_{j+1} + C \lambda_{j+2}),
    \qquad dO/du_k = \lambda_k^T G_k .
"""
from __future__ import annotations

import numpy as np

from .cables import cable_length_gradients, d2Q
from .contact import friction_cross, friction_cross_T

__all__ = ["control_jacobian", "sensitivity_step", "adjoint_pass"]


def control_jacobian(system, x: np.ndarray, u: np.ndarray):
    """``(G, dL)``: ``G (3n, n_motors)`` = dR/du and ``dL (T, 3n)`` the cable length gradients."""
    dL = cable_length_gradients(x, system.pt_nodes, system.pt_w, system.ptr, system.n_dof)
    if system.mode == 0:
        gamma = system.cable_deformation(x, u)
        c = np.array([d2Q(g, k, system.eps_cable) for g, k in zip(gamma, system.k_cable)])
    else:
        c = np.ones(len(dL))
    G = np.zeros((system.n_dof, len(u)))
    for t, m in enumerate(system.tendon_motor):
        if m >= 0 and c[t] != 0.0:
            G[:, m] += c[t] * dL[t]
    return G, dL


def sensitivity_step(solver, newton, x, x_prev, u, S1, S2, U):
    """``S_k`` (3n, nz) from ``S_{k-1}``, ``S_{k-2}`` and ``U_k`` (n_motors, nz); ``solver``
    holds the factorisation of ``H_k`` of ``newton`` (a :class:`NewtonSolver`). Also returns
    the cable length gradients at x_k."""
    system = newton.system
    rhs = newton.inertia[:, None] * (2.0 * S1 - S2)
    cross = np.zeros_like(S1)
    friction_cross(x, x_prev, system.contact_nodes, system.k_n, system.eps_n, system.mu_f, S1, cross)
    rhs -= cross
    G, dL = control_jacobian(system, x, u)
    rhs -= G @ U
    S = np.zeros_like(S1)
    S[system.free] = solver.solve(np.ascontiguousarray(rhs[system.free]))
    return S, dL


def adjoint_pass(newton, xs: np.ndarray, us: np.ndarray, dobj_dx: np.ndarray) -> np.ndarray:
    """``dO/du`` (K, n_motors) for states ``xs`` (K+1, n, 3) of a rollout with controls ``us``
    (K, n_motors) and ``dobj_dx`` (K+1, n, 3) (the entry for x_0 is ignored: x_0 is given).
    The rollout must have started at rest (``x_{-1} = x_0``)."""
    system = newton.system
    K = len(us)
    n_dof = system.n_dof
    free = system.free
    inertia = newton.inertia
    lam_next = np.zeros(n_dof)      # lambda_{j+1}
    lam_next2 = np.zeros(n_dof)     # lambda_{j+2}
    out = np.zeros_like(us, dtype=np.float64)
    for j in range(K, 0, -1):
        xj = xs[j]
        xjm1 = xs[j - 1]
        xjm2 = xs[j - 2] if j >= 2 else xs[0]
        rhs = dobj_dx[j].reshape(-1).copy()
        if j < K:
            # A_{j+1}^T lambda_{j+1} with A = -2M/h^2 + friction cross term of step j+1
            rhs += -2.0 * inertia * lam_next
            friction_cross_T(xs[j + 1], xj, system.contact_nodes, system.k_n, system.eps_n,
                             system.mu_f, lam_next, rhs)
        if j + 1 < K:
            rhs += inertia * lam_next2
        solver = newton.factorize_exact_at(xj, xjm1, xjm2, us[j - 1])
        lam = np.zeros(n_dof)
        lam[free] = -solver.solve(np.ascontiguousarray(rhs[free]))
        G, _ = control_jacobian(system, xj, us[j - 1])
        out[j - 1] = lam @ G
        lam_next2, lam_next = lam_next, lam
    return out
