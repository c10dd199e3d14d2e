r"""The kernels of the contact between the robot and a box (:mod:`.box_contact`): one pair (a robot
node ``p``, a face ``a, b, c, d`` of the box) as a function of its 15 coordinates ``y = (p, a,
b, c, d)``, with exact gradient and Hessian.

* :func:`face_geometry`: the face's normal ``n = w / |w|``, ``w = (c - a) x (d - b)``, its
  derivative ``dn/dy = J dw/dy`` with ``J = (I - n n^T) / |w|``, and its second derivative
  ``d^2 n_k = J_km d^2 w_m + dw^T H_k dw`` with ``H_k,ij = -(n_i P_kj + n_j P_ki + n_k P_ij) /
  |w|^2`` (``P = I - n n^T``; ``d^2 w`` is constant, ``w`` being bilinear in the corners).
* :func:`normal_pair`: the penalty ``Q_b(-delta)`` of the node's signed distance ``delta = n .
  (p - o)`` from the face's plane (``o`` its centroid): ``grad = -Q' d delta``, ``Hess = Q''
  d delta d delta^T - Q' d^2 delta``.
* :func:`friction_pair`: the Coulomb bristle ``a G(|t|)`` (``a = mu_b N_{k-1}``, ``G`` of
  :func:`.coulomb.bristle_potential`) of the tangential offset ``t = v - (n . v) n`` from the
  anchor ``q = sum_j phi_j(xi, eta) x_j`` (``v = p - q``): ``grad = a w t^T dt``, ``Hess = a [w
  (dt^T dt + t_k d^2 t_k) + c (dt^T t)(t^T dt)]``.
* :func:`friction_anchor_jacobian`: ``d g / d (xi, eta)`` of that gradient (the sensitivities,
  :mod:`.box_sensitivity`).
* :func:`box_assemble`: the term's energy over every contact node, its gradient and Hessian
  scattered into the system's (optionally each pair's Hessian clamped to its non-negative
  eigenvalues: the Newton solver's projected fallback).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .coulomb import bristle_potential
from .penalty import Q, d2Q, dQ

__all__ = ["face_index", "face_planes", "face_geometry", "depth", "normal_pair", "anchor_offset", "anchor_weights",
           "friction_pair", "friction_anchor_jacobian", "box_assemble", "bilinear", "pair_dofs"]

_LEVI = np.zeros((3, 3, 3))
_LEVI[0, 1, 2] = _LEVI[1, 2, 0] = _LEVI[2, 0, 1] = 1.0
_LEVI[0, 2, 1] = _LEVI[2, 1, 0] = _LEVI[1, 0, 2] = -1.0
_SEL = np.zeros((5, 3, 15))                     # the coordinates of point j of y = (p, a, b, c, d)
for _j in range(5):
    _SEL[_j, :, 3 * _j:3 * _j + 3] = np.eye(3)
_E1 = _SEL[3] - _SEL[1]                         # d(c - a)/dy
_E2 = _SEL[4] - _SEL[2]                         # d(d - b)/dy
_T = np.einsum("klm,li,mj->kij", _LEVI, _E1, _E2)
_D2W = _T + _T.transpose(0, 2, 1)               # d^2 w_k / dy^2
_DR = _SEL[0] - _SEL[1:].mean(axis=0)           # d(p - o)/dy


@njit(cache=True)
def face_index(h):
    """The face of a history entry ``h`` (a float; -1: none), rounded to the nearest integer."""
    return int(np.floor(h + 0.5))


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def face_planes(x, faces):
    """``(normals (f, 3), centroids (f, 3))`` of the faces ``faces`` (f, 4) at positions ``x``."""
    normals = np.empty((faces.shape[0], 3))
    centres = np.empty((faces.shape[0], 3))
    for f in range(faces.shape[0]):
        F = x[faces[f]]
        w = _cross(F[2] - F[0], F[3] - F[1])
        normals[f] = w / np.sqrt(w @ w)
        centres[f] = (F[0] + F[1] + F[2] + F[3]) / 4.0
    return normals, centres


@njit(cache=True)
def face_geometry(F, second):
    """``(n (3,), dn/dy (3, 15), d^2 n/dy^2 (3, 15, 15))`` of the face ``F`` (4, 3) (module
    docstring); the last is zeros unless ``second``."""
    e1, e2 = F[2] - F[0], F[3] - F[1]
    w = _cross(e1, e2)
    L = np.sqrt(w @ w)
    n = w / L
    Dw = np.zeros((3, 15))
    for k in range(3):
        for l in range(3):
            for m in range(3):
                e = _LEVI[k, l, m]
                if e != 0.0:
                    Dw[k] += e * (_E1[l] * e2[m] + e1[l] * _E2[m])
    P = np.eye(3) - np.outer(n, n)
    J = P / L
    Dn = J @ Dw
    D2n = np.zeros((3, 15, 15))
    if second:
        for k in range(3):
            Hk = -(np.outer(n, P[k]) + np.outer(P[k], n) + n[k] * P) / (L * L)
            D2n[k] = Dw.T @ Hk @ Dw
            for m in range(3):
                D2n[k] += J[k, m] * _D2W[m]
    return n, Dn, D2n


@njit(cache=True)
def depth(p, F, second):
    """``(s, d delta/dy (15,), d^2 delta/dy^2 (15, 15))``: node ``p``'s depth ``s = -delta``
    below face ``F``'s plane, ``delta = n . (p - o)`` (the last zeros unless ``second``)."""
    n, Dn, D2n = face_geometry(F, second)
    return depth_at(p, F, n, Dn, D2n, second)


@njit(cache=True)
def depth_at(p, F, n, Dn, D2n, second):
    """:func:`depth` given the face's :func:`face_geometry` ``n, Dn, D2n`` (shared by every node
    tested against the face)."""
    r = p - (F[0] + F[1] + F[2] + F[3]) / 4.0
    Dd = r @ Dn + n @ _DR
    D2d = np.zeros((15, 15))
    if second:
        M = Dn.T @ _DR
        D2d += M + M.T
        for c in range(3):
            D2d += r[c] * D2n[c]
    return -(n @ r), Dd, D2d


@njit(cache=True)
def normal_pair(p, F, k, eps, want_hess, g, H):
    """The penalty of node ``p`` below face ``F``: returns ``Q_b(-delta)``, writes its gradient
    ``g`` (15,) and, with ``want_hess``, its Hessian ``H`` (15, 15)."""
    n, Dn, D2n = face_geometry(F, want_hess)
    return normal_pair_at(p, F, n, Dn, D2n, k, eps, want_hess, g, H)


@njit(cache=True)
def normal_pair_at(p, F, n, Dn, D2n, k, eps, want_hess, g, H):
    """:func:`normal_pair` given the face's :func:`face_geometry` ``n, Dn, D2n``."""
    s, Dd, D2d = depth_at(p, F, n, Dn, D2n, want_hess)
    dq = dQ(s, k, eps)
    g[:] = -dq * Dd
    if want_hess:
        H[:, :] = d2Q(s, k, eps) * np.outer(Dd, Dd) - dq * D2d
    return Q(s, k, eps)


@njit(cache=True)
def bilinear(xi, eta):
    """The weights (4,) of corners a, b, c, d at ``(xi, eta)``: ``(1-xi)(1-eta), xi (1-eta),
    xi eta, (1-xi) eta``."""
    return np.array([(1 - xi) * (1 - eta), xi * (1 - eta), xi * eta, (1 - xi) * eta])


@njit(cache=True)
def anchor_offset(p, F, xi, eta, second):
    """The tangential offset of node ``p`` from its anchor ``(xi, eta)`` on face ``F``: ``(t,
    dt/dy (3, 15), n, dn/dy, d^2 n/dy^2, v = p - q, dv/dy, alpha = n . v, d alpha/dy)``."""
    n, Dn, D2n = face_geometry(F, second)
    return anchor_offset_at(p, F, n, Dn, D2n, xi, eta)


@njit(cache=True)
def anchor_offset_at(p, F, n, Dn, D2n, xi, eta):
    """:func:`anchor_offset` given the face's :func:`face_geometry` ``n, Dn, D2n``."""
    phi = bilinear(xi, eta)
    V = _SEL[0].copy()
    v = p.copy()
    for j in range(4):
        V -= phi[j] * _SEL[j + 1]
        v -= phi[j] * F[j]
    al = n @ v
    Dal = v @ Dn + n @ V
    t = v - al * n
    Dt = V - np.outer(n, Dal) - al * Dn
    return t, Dt, n, Dn, D2n, v, V, al, Dal


@njit(cache=True)
def anchor_weights(xi, eta):
    """(2, 4) ``d phi / d xi`` and ``d phi / d eta`` of :func:`bilinear`."""
    return np.array([[-(1 - eta), 1 - eta, eta, -eta], [-(1 - xi), -xi, xi, 1 - xi]])


@njit(cache=True)
def friction_pair(p, F, xi, eta, a, rs, want_hess, g, H):
    """The friction of node ``p`` anchored at ``(xi, eta)`` on face ``F`` with weight ``a = mu_b
    N_{k-1}``: returns ``a G(|t|)``, writes ``g`` and (``want_hess``) ``H``."""
    n, Dn, D2n = face_geometry(F, want_hess)
    return friction_pair_at(p, F, n, Dn, D2n, xi, eta, a, rs, want_hess, g, H)


@njit(cache=True)
def friction_pair_at(p, F, n, Dn, D2n, xi, eta, a, rs, want_hess, g, H):
    """:func:`friction_pair` given the face's :func:`face_geometry` ``n, Dn, D2n``."""
    t, Dt, n, Dn, D2n, v, V, al, Dal = anchor_offset_at(p, F, n, Dn, D2n, xi, eta)
    G, w, c = bristle_potential(np.sqrt(t @ t), rs)
    tDt = t @ Dt
    g[:] = a * w * tDt
    if want_hess:
        M = Dn.T @ V
        D2al = M + M.T
        for m in range(3):
            D2al += v[m] * D2n[m]
        S = Dt.T @ Dt
        for m in range(3):
            D2t = -n[m] * D2al - np.outer(Dal, Dn[m]) - np.outer(Dn[m], Dal) - al * D2n[m]
            S += t[m] * D2t
        H[:, :] = a * (w * S + c * np.outer(tDt, tDt))
    return a * G


@njit(cache=True)
def friction_anchor_jacobian(p, F, xi, eta, a, rs):
    """(15, 2) ``d g / d(xi, eta)`` of :func:`friction_pair`'s gradient ``g = a w t^T dt``: with
    ``v_xi = -sum_j phi_j,xi x_j``, ``t_xi = v_xi - (n . v_xi) n`` and ``dt_xi`` alike, ``g_xi =
    a (c (t . t_xi) t^T dt + w (t_xi^T dt + t^T dt_xi))``."""
    t, Dt, n, Dn, D2n, v, V, al, Dal = anchor_offset(p, F, xi, eta, False)
    G, w, c = bristle_potential(np.sqrt(t @ t), rs)
    tDt = t @ Dt
    dphi = anchor_weights(xi, eta)
    out = np.zeros((15, 2))
    for e in range(2):
        v_e = np.zeros(3)
        V_e = np.zeros((3, 15))
        for j in range(4):
            v_e -= dphi[e, j] * F[j]
            V_e -= dphi[e, j] * _SEL[j + 1]
        al_e = n @ v_e
        Dal_e = v_e @ Dn + n @ V_e
        t_e = v_e - al_e * n
        Dt_e = V_e - np.outer(n, Dal_e) - al_e * Dn
        out[:, e] = a * (c * (t @ t_e) * tDt + w * (t_e @ Dt + t @ Dt_e))
    return out


@njit(cache=True)
def pair_dofs(node, face, faces):
    """(15,) the dofs of the pair (``node``, ``face``): the node's, then the face's corners'."""
    out = np.empty(15, dtype=np.int64)
    for j in range(5):
        idx = node if j == 0 else faces[face, j - 1]
        for d in range(3):
            out[3 * j + d] = 3 * idx + d
    return out


@njit(cache=True)
def _scatter(node, face, faces, c, g, H, grad, hdata, slots, local, want_grad, want_hess, project):
    if want_grad:
        dofs = pair_dofs(node, face, faces)
        for i in range(15):
            grad[dofs[i]] += g[i]
    if want_hess:
        if project:
            lam, vec = np.linalg.eigh(H)
            H = (vec * np.maximum(lam, 0.0)) @ vec.T
        for i in range(15):
            for j in range(15):
                hdata[slots[c, local[face, i], local[face, j]]] += H[i, j]


@njit(cache=True)
def _face_geometry_once(f, F, second, level, N, DN, D2N):
    """Face ``f``'s :func:`face_geometry` into ``N, DN, D2N`` unless ``level[f]`` says it is
    there already (with its second derivative when ``second``)."""
    need = 2 if second else 1
    if level[f] < need:
        n, Dn, D2n = face_geometry(F, second)
        N[f], DN[f] = n, Dn
        if second:
            D2N[f] = D2n
        level[f] = need


@njit(cache=True)
def box_assemble(x, nodes, faces, opposite, weight, hist, k, eps, rs, grad, hdata, slots, local, want_grad,
                 want_hess, project):
    """The term's energy (:mod:`.box_contact`) over the contact ``nodes``: the penalty of each
    node inside the box against its nearest face (faces but ``opposite[c]``, the one opposite
    its nearest at the previous step; -1: none left out), and its friction when anchored
    (``hist[c] = (face, xi, eta)``, face >= 0) with ``weight[c] = mu_b N_{k-1} > 0``. Adds the
    gradient and the Hessian (``slots (c, 27, 27)``: each node's block of its 3 and the box's
    24 dofs; ``local (6, 15)``: a face's pair in that block) as asked. Each face's
    :func:`face_geometry` is computed once per call, when a pair first needs it, not once per
    pair (bit for bit the same; on SoftPuppyCarry-v0 about 21 pairs share one or two faces)."""
    normals, centres = face_planes(x, faces)
    level = np.zeros(faces.shape[0], dtype=np.int64)        # 0: not yet, 1: n and dn, 2: and d^2 n
    N = np.empty((faces.shape[0], 3))
    DN = np.empty((faces.shape[0], 3, 15))
    D2N = np.empty((faces.shape[0], 3, 15, 15))
    g = np.zeros(15)
    H = np.zeros((15, 15))
    total = 0.0
    for c in range(nodes.shape[0]):
        node = nodes[c]
        p = x[node]
        best, fb = -np.inf, np.int64(-1)              # (not the literal -1: one compile of the calls on fb)
        for f in range(6):
            if f != opposite[c]:
                d = normals[f] @ (p - centres[f])
                if d > best:
                    best, fb = d, f
        if best < 0.0:
            F = x[faces[fb]]
            _face_geometry_once(fb, F, want_hess, level, N, DN, D2N)
            total += normal_pair_at(p, F, N[fb], DN[fb], D2N[fb], k, eps, want_hess, g, H)
            _scatter(node, fb, faces, c, g, H, grad, hdata, slots, local, want_grad, want_hess, project)
        fa = face_index(hist[c, 0])
        if fa >= 0 and weight[c] > 0.0:
            F = x[faces[fa]]
            _face_geometry_once(fa, F, want_hess, level, N, DN, D2N)
            total += friction_pair_at(p, F, N[fa], DN[fa], D2N[fa], hist[c, 1], hist[c, 2], weight[c], rs, want_hess,
                                      g, H)
            _scatter(node, fa, faces, c, g, H, grad, hdata, slots, local, want_grad, want_hess, project)
    return total
