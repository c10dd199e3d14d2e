r"""Positive semi-definite projection of the neo-Hookean Hessian (the Newton solver's fallback).

When the exact Hessian of the incremental potential is not positive definite, the Newton
solver (:mod:`soft_envs.sim.integrator`) factorises instead the Hessian whose elastic part is
projected, element by element, onto its positive semi-definite part in deformation-gradient
space: ``H_e = V B^T [d2Psi/dF2]_+ B`` with ``vec F = B x_e``. The projection uses the analytic
eigensystem of d2Psi/dF2 for the compressible neo-Hookean energy of :mod:`.materials`
(Smith, de Goes and Kim 2019, "Analytic eigensystems for isotropic distortion energies"), with
an allocation-free 3x3 Jacobi eigensolver; it equals the exact element Hessian wherever that is
already positive semi-definite.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .materials import _deformation_gradient, _det3, _fem_gradient, element_gradient_hessian

__all__ = ["element_hessian_projected", "fem_assemble_projected"]


@njit(cache=True)
def _project_psd(H):
    """Clamp the negative eigenvalues of a symmetric matrix to zero (reference for tests)."""
    w, V = np.linalg.eigh(H)
    for i in range(w.shape[0]):
        if w[i] < 0.0:
            w[i] = 0.0
    return (V * w) @ V.T


@njit(cache=True)
def _sym_eig3(A, w, Q):
    """Eigenvalues ``w`` and eigenvectors (columns of ``Q``) of a symmetric 3x3 matrix by cyclic
    Jacobi rotations (no allocation, unlike LAPACK through numba; A is overwritten)."""
    for i in range(3):
        for j in range(3):
            Q[i, j] = 1.0 if i == j else 0.0
    for sweep in range(30):
        off = A[0, 1] * A[0, 1] + A[0, 2] * A[0, 2] + A[1, 2] * A[1, 2]
        scale = A[0, 0] * A[0, 0] + A[1, 1] * A[1, 1] + A[2, 2] * A[2, 2]
        if off <= 1e-30 * scale or off == 0.0:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(3):          # A <- A R (columns p, q)
                    akp = A[k, p]
                    akq = A[k, q]
                    A[k, p] = c * akp - sn * akq
                    A[k, q] = sn * akp + c * akq
                for k in range(3):          # A <- R^T A (rows p, q)
                    apk = A[p, k]
                    aqk = A[q, k]
                    A[p, k] = c * apk - sn * aqk
                    A[q, k] = sn * apk + c * aqk
                for k in range(3):
                    qkp = Q[k, p]
                    qkq = Q[k, q]
                    Q[k, p] = c * qkp - sn * qkq
                    Q[k, q] = sn * qkp + c * qkq
    for i in range(3):
        w[i] = A[i, i]


@njit(cache=True)
def _add_mode(H, E, dNe, c, w):
    """``H += c w w^T`` (lower triangle) with ``w_(a,i) = (E N_a)_i``: one eigenmode ``E``
    (3x3) of d2Psi/dF2 pulled back to the 12 element dofs (F = sum_a x_a N_a^T)."""
    for a in range(4):
        for i in range(3):
            w[3 * a + i] = E[i, 0] * dNe[a, 0] + E[i, 1] * dNe[a, 1] + E[i, 2] * dNe[a, 2]
    for r in range(12):
        cr = c * w[r]
        for t in range(r + 1):
            H[r, t] += cr * w[t]


@njit(cache=True)
def element_hessian_projected(x, tet, dNe, vol, mu, lam, H):
    r"""Positive semi-definite projection of one element's Hessian, from the analytic
    eigensystem of :math:`\partial^2\Psi/\partial F^2` (Smith et al. 2019). With
    :math:`F = U \Sigma V^T` and :math:`D_{ij} = U e_i e_j^T V^T`,

    .. math::
        \frac{\partial^2\Psi}{\partial F^2} = \mu I + \lambda\, g g^T + (\mu - \lambda\ln J)\, T,
        \quad g = F^{-T} = \textstyle\sum_i D_{ii}/\sigma_i,
        \quad T D_{ij} = D_{ji} / (\sigma_i \sigma_j),

    so the six modes ``(D_ij +- D_ji)/sqrt 2`` (i < j) have eigenvalues
    ``mu +- (mu - lam ln J)/(sigma_i sigma_j)`` and the three scaling modes the eigenvalues of
    ``A = mu I + lam s s^T + (mu - lam ln J) diag(s^2)``, ``s_i = 1/sigma_i``. Negative ones are
    dropped: ``H = V B^T [d2Psi/dF2]_+ B``, equal to the exact Hessian where that is already
    positive semi-definite. Writes H (12x12); returns False for an inverted element."""
    work = np.empty((16, 3))
    w12 = np.empty(12)
    return _element_hessian_projected(x, tet, dNe, vol, mu, lam, H, work, w12)


@njit(cache=True)
def _element_hessian_projected(x, tet, dNe, vol, mu, lam, H, work, w12):
    F = work[0:3]
    C = work[3:6]
    V = work[6:9]
    _deformation_gradient(x, tet, dNe, F)
    J = _det3(F)
    if J <= 0.0:
        return False
    # SVD from the eigensystem of F^T F: F = U diag(sig) V^T, U = F V / sig (sig > 0 as J > 0)
    for i in range(3):
        for j in range(3):
            C[i, j] = F[0, i] * F[0, j] + F[1, i] * F[1, j] + F[2, i] * F[2, j]
    ev = w12[0:3]
    _sym_eig3(C, ev, V)
    # the two larger singular values from the eigenvalues; the smallest as J / (their product),
    # which stays accurate for a nearly flat element, and its U column by a cross product
    kmin = 0
    for k in range(1, 3):
        if ev[k] < ev[kmin]:
            kmin = k
    ka = (kmin + 1) % 3
    kb = (kmin + 2) % 3
    if ev[ka] <= 0.0 or ev[kb] <= 0.0:
        return False                       # degenerate beyond repair: the caller falls back
    sa = math.sqrt(ev[ka])
    sb = math.sqrt(ev[kb])
    smin = J / (sa * sb)
    U = C                                  # C is no longer needed
    for k in (ka, kb):
        sk = sa if k == ka else sb
        for i in range(3):
            U[i, k] = (F[i, 0] * V[0, k] + F[i, 1] * V[1, k] + F[i, 2] * V[2, k]) / sk
    detV = (V[0, 0] * (V[1, 1] * V[2, 2] - V[1, 2] * V[2, 1]) - V[0, 1] * (V[1, 0] * V[2, 2] - V[1, 2] * V[2, 0])
            + V[0, 2] * (V[1, 0] * V[2, 1] - V[1, 1] * V[2, 0]))
    sgn = 1.0 if detV > 0.0 else -1.0      # det U = det V since J > 0
    U[0, kmin] = sgn * (U[1, ka] * U[2, kb] - U[2, ka] * U[1, kb])
    U[1, kmin] = sgn * (U[2, ka] * U[0, kb] - U[0, ka] * U[2, kb])
    U[2, kmin] = sgn * (U[0, ka] * U[1, kb] - U[1, ka] * U[0, kb])
    sig = (smin if kmin == 0 else (sa if ka == 0 else sb),
           smin if kmin == 1 else (sa if ka == 1 else sb),
           smin if kmin == 2 else (sa if ka == 2 else sb))
    c2 = mu - lam * math.log(J)
    for r in range(12):
        for t in range(r + 1):
            H[r, t] = 0.0
    A = F                                  # F is no longer needed
    for i in range(3):
        for j in range(3):
            A[i, j] = lam / (sig[i] * sig[j])
        A[i, i] += mu + c2 / (sig[i] * sig[i])
    Q = work[9:12]
    E = work[12:15]
    wA = work[15]
    _sym_eig3(A, wA, Q)
    for k in range(3):
        if wA[k] <= 0.0:
            continue
        for i in range(3):
            for j in range(3):
                E[i, j] = (U[i, 0] * Q[0, k] * V[j, 0] + U[i, 1] * Q[1, k] * V[j, 1]
                           + U[i, 2] * Q[2, k] * V[j, 2])
        _add_mode(H, E, dNe, vol * wA[k], w12)
    r2 = 1.0 / math.sqrt(2.0)
    for p in range(3):
        for q in range(p + 1, 3):
            t = c2 / (sig[p] * sig[q])
            for sign in (1.0, -1.0):
                ev_ = mu + sign * t
                if ev_ <= 0.0:
                    continue
                for i in range(3):
                    for j in range(3):
                        E[i, j] = r2 * (U[i, p] * V[j, q] + sign * U[i, q] * V[j, p])
                _add_mode(H, E, dNe, vol * ev_, w12)
    for r in range(12):
        for t in range(r):
            H[t, r] = H[r, t]
    return True


@njit(cache=True)
def fem_assemble_projected(x, tets, dN, vol, mu, lam, grad, hdata, hmap):
    """Like :func:`.materials.fem_assemble` with ``want_hess=True``, but each element's Hessian
    is its positive semi-definite projection. Returns the energy (``inf`` if inverted)."""
    total = _fem_gradient(x, tets, dN, vol, mu, lam, grad)
    if total == np.inf:
        return np.inf
    H = np.empty((12, 12))
    work = np.empty((16, 3))
    w12 = np.empty(12)
    g = np.empty(12)
    for e in range(tets.shape[0]):
        if not _element_hessian_projected(x, tets[e], dN[e], vol[e], mu[e], lam[e], H, work, w12):
            element_gradient_hessian(x, tets[e], dN[e], vol[e], mu[e], lam[e], g, H)
            H[:, :] = _project_psd(H)      # (nearly) flat element: numerical projection
        hm = hmap[e]
        for r in range(12):
            for c in range(r + 1):      # H is symmetric: the lower triangle covers every stored slot
                hdata[hm[12 * r + c]] += H[r, c]
                if r != c:
                    hdata[hm[12 * c + r]] += H[r, c]
    return total
