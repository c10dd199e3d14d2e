r"""Compressible neo-Hookean material on linear tetrahedra (paper eq. 1).

Energy density, with :math:`J = \det F` and :math:`I_1 = \operatorname{tr}(F^T F)`:

.. math::
    \Psi(F) = \frac{\mu}{2}(I_1 - 3) - \mu \ln J + \frac{\lambda}{2}(\ln J)^2

First Piola-Kirchhoff stress :math:`P = \partial\Psi/\partial F = \mu F + (\lambda \ln J - \mu) F^{-T}`.
Its derivative, written per element with shape-function gradients :math:`N_a` and
:math:`q_a = F^{-T} N_a`, gives the 3x3 blocks of the 12x12 element Hessian

.. math::
    H_{ab} = V\,[\mu (N_a\cdot N_b) I + (\mu - \lambda \ln J)\, q_b q_a^T + \lambda\, q_a q_b^T].

``mu = E / (2 (1 + nu))`` and ``lam = E nu / ((1 + nu)(1 - 2 nu))`` (first Lame parameter), so that
small strains reproduce linear elasticity with Young's modulus E and Poisson ratio nu.
``J <= 0`` lies outside the energy's domain: the energy is ``+inf`` there.

All kernels are numba ``@njit(cache=True)``; ``fem_assemble`` adds each element's gradient
into a dense vector and its Hessian into the values of a fixed sparse pattern through a
precomputed scatter map (see :mod:`soft_envs.sim.system`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["lame_parameters", "psi", "element_energy", "element_gradient_hessian", "element_hessian_projected",
           "fem_energy", "fem_assemble", "fem_energy_density"]


def lame_parameters(youngs_modulus: float, poisson_ratio: float) -> tuple[float, float]:
    """``(mu, lam)`` from Young's modulus [Pa] and Poisson ratio (``-1 < nu < 0.5``)."""
    E, nu = float(youngs_modulus), float(poisson_ratio)
    if not (E > 0 and np.isfinite(E)):
        raise ValueError(f"youngs_modulus must be positive and finite, got {youngs_modulus!r}")
    if not (-1.0 < nu < 0.5):
        raise ValueError(f"poisson_ratio must lie in (-1, 0.5), got {poisson_ratio!r}")
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


@njit(cache=True)
def _deformation_gradient(x, tet, dNe, F):
    for i in range(3):
        for k in range(3):
            s = 0.0
            for a in range(4):
                s += x[tet[a], i] * dNe[a, k]
            F[i, k] = s


@njit(cache=True)
def _det3(F):
    return (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))


@njit(cache=True)
def _inv_transpose(F, J, FinvT):
    """F^{-T} = cofactor(F) / J."""
    FinvT[0, 0] = (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) / J
    FinvT[0, 1] = (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]) / J
    FinvT[0, 2] = (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]) / J
    FinvT[1, 0] = (F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]) / J
    FinvT[1, 1] = (F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]) / J
    FinvT[1, 2] = (F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]) / J
    FinvT[2, 0] = (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]) / J
    FinvT[2, 1] = (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]) / J
    FinvT[2, 2] = (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]) / J


@njit(cache=True)
def _element_kinematics(x, tet, dNe, F, FinvT, q, FN):
    """Fill F, F^{-T}, q_a = F^{-T} N_a and F N_a of one element; return (J, ln J, tr F^T F).
    For J <= 0 only F is filled and (J, 0, 0) is returned."""
    _deformation_gradient(x, tet, dNe, F)
    J = _det3(F)
    if J <= 0.0:
        return J, 0.0, 0.0
    _inv_transpose(F, J, FinvT)
    I1 = 0.0
    for i in range(3):
        for k in range(3):
            I1 += F[i, k] * F[i, k]
    for a in range(4):
        for i in range(3):
            sq = 0.0
            sf = 0.0
            for k in range(3):
                sq += FinvT[i, k] * dNe[a, k]
                sf += F[i, k] * dNe[a, k]
            q[a, i] = sq
            FN[a, i] = sf
    return J, math.log(J), I1


@njit(cache=True)
def psi(F, mu, lam):
    """Energy density Psi(F) of eq. 1 (``+inf`` when det F <= 0)."""
    J = _det3(F)
    if J <= 0.0:
        return np.inf
    lnJ = math.log(J)
    I1 = 0.0
    for i in range(3):
        for k in range(3):
            I1 += F[i, k] * F[i, k]
    return 0.5 * mu * (I1 - 3.0) - mu * lnJ + 0.5 * lam * lnJ * lnJ


@njit(cache=True)
def element_energy(x, tet, dNe, vol, mu, lam):
    """Rest volume times Psi(F) of one element."""
    F = np.empty((3, 3))
    _deformation_gradient(x, tet, dNe, F)
    return vol * psi(F, mu, lam)


@njit(cache=True)
def element_gradient_hessian(x, tet, dNe, vol, mu, lam, g, H):
    """Energy of one element; writes its 12-gradient into ``g`` and 12x12 Hessian into ``H``
    (dof order: node a, component i -> 3 a + i). Returns ``inf`` (and leaves g, H unspecified)
    for an inverted element."""
    F = np.empty((3, 3))
    FinvT = np.empty((3, 3))
    q = np.empty((4, 3))
    FN = np.empty((4, 3))
    J, lnJ, I1 = _element_kinematics(x, tet, dNe, F, FinvT, q, FN)
    if J <= 0.0:
        return np.inf
    c1 = lam * lnJ - mu
    for a in range(4):
        for i in range(3):
            g[3 * a + i] = vol * (mu * FN[a, i] + c1 * q[a, i])
    c2 = mu - lam * lnJ
    for a in range(4):
        for b in range(4):
            nn = dNe[a, 0] * dNe[b, 0] + dNe[a, 1] * dNe[b, 1] + dNe[a, 2] * dNe[b, 2]
            for i in range(3):
                for j in range(3):
                    h = c2 * q[b, i] * q[a, j] + lam * q[a, i] * q[b, j]
                    if i == j:
                        h += mu * nn
                    H[3 * a + i, 3 * b + j] = vol * h
    return vol * (0.5 * mu * (I1 - 3.0) - mu * lnJ + 0.5 * lam * lnJ * lnJ)


@njit(cache=True)
def fem_energy(x, tets, dN, vol, mu, lam):
    """Total elastic energy; ``inf`` as soon as one element is inverted."""
    F = np.empty((3, 3))
    total = 0.0
    for e in range(tets.shape[0]):
        _deformation_gradient(x, tets[e], dN[e], F)
        p = psi(F, mu[e], lam[e])
        if p == np.inf:
            return np.inf
        total += vol[e] * p
    return total


@njit(cache=True)
def fem_energy_density(x, tets, dN, mu, lam):
    """Psi per element (for export and plots); inf for inverted elements."""
    F = np.empty((3, 3))
    out = np.empty(tets.shape[0])
    for e in range(tets.shape[0]):
        _deformation_gradient(x, tets[e], dN[e], F)
        out[e] = psi(F, mu[e], lam[e])
    return out


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
def fem_assemble(x, tets, dN, vol, mu, lam, grad, hdata, hmap, project, want_hess=True):
    """Add the elastic gradient into ``grad`` (3n) and the Hessian into ``hdata`` through
    ``hmap`` (m, 144) (row-major 12x12 slots; only the lower triangle of the global matrix is
    stored, the other slots point at a trash entry). With ``project`` each element Hessian is
    clamped to positive semi-definite (the safeguarded fallback of the Newton solver).
    ``want_hess=False`` skips the Hessian. Returns the energy (``inf`` if inverted)."""
    if project:
        return _fem_assemble_projected(x, tets, dN, vol, mu, lam, grad, hdata, hmap)
    if not want_hess:
        return _fem_gradient(x, tets, dN, vol, mu, lam, grad)
    return _fem_assemble_exact(x, tets, dN, vol, mu, lam, grad, hdata, hmap)


@njit(cache=True)
def _fem_gradient(x, tets, dN, vol, mu, lam, grad):
    """Energy and gradient only: ``grad_a += V P N_a`` with the stress
    ``P = mu F + (lam ln J - mu) F^{-T}`` formed once per element."""
    F = np.empty((3, 3))
    P = np.empty((3, 3))
    total = 0.0
    for e in range(tets.shape[0]):
        tet = tets[e]
        dNe = dN[e]
        _deformation_gradient(x, tet, dNe, F)
        J = _det3(F)
        if J <= 0.0:
            return np.inf
        lnJ = math.log(J)
        m = mu[e]
        lm = lam[e]
        v = vol[e]
        _inv_transpose(F, J, P)
        c1 = lm * lnJ - m
        I1 = 0.0
        for i in range(3):
            for k in range(3):
                I1 += F[i, k] * F[i, k]
                P[i, k] = v * (m * F[i, k] + c1 * P[i, k])
        total += v * (0.5 * m * (I1 - 3.0) - m * lnJ + 0.5 * lm * lnJ * lnJ)
        for a in range(4):
            n = tet[a]
            for i in range(3):
                grad[3 * n + i] += P[i, 0] * dNe[a, 0] + P[i, 1] * dNe[a, 1] + P[i, 2] * dNe[a, 2]
    return total


@njit(cache=True)
def _fem_assemble_exact(x, tets, dN, vol, mu, lam, grad, hdata, hmap):
    F = np.empty((3, 3))
    FinvT = np.empty((3, 3))
    q = np.empty((4, 3))
    FN = np.empty((4, 3))
    total = 0.0
    for e in range(tets.shape[0]):
        tet = tets[e]
        dNe = dN[e]
        J, lnJ, I1 = _element_kinematics(x, tet, dNe, F, FinvT, q, FN)
        if J <= 0.0:
            return np.inf
        v = vol[e]
        m = mu[e]
        lm = lam[e]
        c1 = lm * lnJ - m
        for a in range(4):
            n = tet[a]
            for i in range(3):
                grad[3 * n + i] += v * (m * FN[a, i] + c1 * q[a, i])
        total += v * (0.5 * m * (I1 - 3.0) - m * lnJ + 0.5 * lm * lnJ * lnJ)
        c2 = m - lm * lnJ
        hm = hmap[e]
        for a in range(4):
            for b in range(4):
                if tet[a] < tet[b]:
                    continue   # upper block: its mirror image is stored
                nn = m * (dNe[a, 0] * dNe[b, 0] + dNe[a, 1] * dNe[b, 1] + dNe[a, 2] * dNe[b, 2])
                for i in range(3):
                    r = 12 * (3 * a + i) + 3 * b
                    jmax = i + 1 if a == b else 3
                    for j in range(jmax):
                        h = c2 * q[b, i] * q[a, j] + lm * q[a, i] * q[b, j]
                        if i == j:
                            h += nn
                        hdata[hm[r + j]] += v * h
    return total


@njit(cache=True)
def _fem_assemble_projected(x, tets, dN, vol, mu, lam, grad, hdata, hmap):
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
