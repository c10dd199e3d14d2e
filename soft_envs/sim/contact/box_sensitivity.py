r"""The sensitivities of the contact between the robot and a box (:mod:`.box_contact`): what the
forward recurrence and the adjoint (:mod:`soft_envs.sim.sensitivity`) need of a term with lagged
state, as numba kernels over the contact nodes.

* :func:`prev_product`: ``d grad / d x_prev`` enters only through the friction's lagged normal
  force ``N_{k-1} = Q_b'(s(x_prev))`` (the nearest face at ``x_prev`` and the face left out of
  the penalty's maximum are discrete): per anchored node ``d g / d y_prev = (g / N) Q_b''
  (-d delta / d y_prev)``, a rank-one product.
* :func:`history_product`: ``d grad / d (xi, eta)`` of the anchors
  (:func:`.box_geometry.friction_anchor_jacobian`; the face index has no derivative).
* :func:`anchor_tangent`: the anchors' update. A sticking node keeps ``(xi, eta)``; a node
  re-anchored at its projection ``z = p`` on a face, or sliding (``z = q + (1 - r_b / r) t``
  projected on its face), follows the projection's implicit derivative: the nearest point of
  the bilinear face satisfies ``R = [q_xi, q_eta]^T (q - z) = 0``, so ``d(xi, eta) = -A^{-1}
  (dR/dF dF + dR/dz dz)`` with ``A = dR / d(xi, eta)`` (:func:`projection_jacobian`).

Each has a ``transpose`` mode for the adjoint. Derivatives are those of the smooth pieces:
where a node switches between sticking and sliding, enters or leaves the box, or changes its
nearest face, the update is not differentiable (as for the ground's Coulomb law).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .box_geometry import (anchor_offset, anchor_weights, bilinear, depth, face_index, face_planes,
                           friction_anchor_jacobian, friction_pair, pair_dofs)
from .penalty import d2Q

__all__ = ["prev_product", "history_product", "anchor_tangent", "projection_jacobian"]

_SEL0 = np.zeros((3, 15))                       # d p / dy
_SEL0[:, :3] = np.eye(3)


@njit(cache=True)
def prev_product(x, x_prev, nodes, faces, hist, k, eps, mu, rs, S, out, transpose):
    """``out (3n, nz) += d grad / d x_prev @ S``; ``transpose``: ``out += (d grad / d x_prev)^T
    @ S`` (``S`` then the adjoint, (3n, nz))."""
    normals, centres = face_planes(x_prev, faces)
    g = np.zeros(15)
    H = np.zeros((15, 15))
    for c in range(nodes.shape[0]):
        fa = face_index(hist[c, 0])
        if fa < 0:
            continue
        node = nodes[c]
        pp = x_prev[node]
        best, fb = -np.inf, np.int64(-1)              # (not the literal -1: one compile of pair_dofs)
        for f in range(6):
            d = normals[f] @ (pp - centres[f])
            if d > best:
                best, fb = d, f
        s, Dd, _ = depth(pp, x_prev[faces[fb]], False)
        dN = -d2Q(s, k, eps) * Dd                       # d N_{k-1} / d y_prev
        if not np.any(dN != 0.0):
            continue
        friction_pair(x[node], x[faces[fa]], hist[c, 1], hist[c, 2], mu, rs, False, g, H)   # per unit N
        da, db = pair_dofs(node, fa, faces), pair_dofs(node, fb, faces)
        for j in range(S.shape[1]):
            if transpose:
                acc = 0.0
                for i in range(15):
                    acc += g[i] * S[da[i], j]
                for i in range(15):
                    out[db[i], j] += dN[i] * acc
            else:
                acc = 0.0
                for i in range(15):
                    acc += dN[i] * S[db[i], j]
                for i in range(15):
                    out[da[i], j] += g[i] * acc


@njit(cache=True)
def history_product(x, nodes, faces, hist, weight, rs, P, out, transpose):
    """``out (3n, nz) += d grad / d hist @ P`` (``P`` (3c, nz): the flattened history's
    derivative); ``transpose``: ``out (3c, nz) += (d grad / d hist)^T @ P`` (``P`` (3n, nz)).
    ``weight[c] = mu_b N_{k-1}``."""
    for c in range(nodes.shape[0]):
        fa = face_index(hist[c, 0])
        if fa < 0 or weight[c] <= 0.0:
            continue
        node = nodes[c]
        J = friction_anchor_jacobian(x[node], x[faces[fa]], hist[c, 1], hist[c, 2], weight[c], rs)
        da = pair_dofs(node, fa, faces)
        for j in range(P.shape[1]):
            if transpose:
                for e in range(2):
                    acc = 0.0
                    for i in range(15):
                        acc += J[i, e] * P[da[i], j]
                    out[3 * c + 1 + e, j] += acc
            else:
                for i in range(15):
                    out[da[i], j] += J[i, 0] * P[3 * c + 1, j] + J[i, 1] * P[3 * c + 2, j]


@njit(cache=True)
def projection_jacobian(F, xi, eta, z):
    """``(d(xi, eta)/dF (2, 12), d(xi, eta)/dz (2, 3))`` of the point ``(xi, eta)`` of face ``F``
    nearest ``z`` (module docstring)."""
    phi, dphi = bilinear(xi, eta), anchor_weights(xi, eta)
    q, qx, qe = np.zeros(3), np.zeros(3), np.zeros(3)
    for j in range(4):
        q += phi[j] * F[j]
        qx += dphi[0, j] * F[j]
        qe += dphi[1, j] * F[j]
    e = q - z
    cross = qx @ qe + e @ (F[0] - F[1] + F[2] - F[3])
    A = np.array([[qx @ qx, cross], [cross, qe @ qe]])
    B = np.zeros((2, 15))                              # dR / d(z, F)
    B[0, :3], B[1, :3] = -qx, -qe
    for j in range(4):
        B[0, 3 + 3 * j:6 + 3 * j] = dphi[0, j] * e + phi[j] * qx
        B[1, 3 + 3 * j:6 + 3 * j] = dphi[1, j] * e + phi[j] * qe
    J = -np.linalg.solve(A, B)
    return J[:, 3:].copy(), J[:, :3].copy()


@njit(cache=True)
def _update_jacobian(x, node, faces, old, new, active, rs):
    """``(My (2, 15), Ma (2, 2), face)``: ``d(xi', eta') = My dy + Ma d(xi, eta)`` of one node's
    anchor update, ``dy`` over the pair (node, face); face -1: no anchor after the update."""
    My, Ma = np.zeros((2, 15)), np.zeros((2, 2))
    if not active:
        f = face_index(new[0])
        if f >= 0:
            JF, Jz = projection_jacobian(x[faces[f]], new[1], new[2], x[node].copy())   # (writeable: one compile)
            My[:, :3], My[:, 3:] = Jz, JF
        return My, Ma, f
    f = face_index(old[0])
    F = x[faces[f]]
    t, Dt, n, Dn, D2n, v, V, al, Dal = anchor_offset(x[node], F, old[1], old[2], False)
    r = np.sqrt(t @ t)
    if r <= rs:                                        # sticks
        Ma[0, 0] = Ma[1, 1] = 1.0
        return My, Ma, f
    q = x[node] - v                                    # slides: z = q + (1 - r_b / r) t
    s = 1.0 - rs / r
    Zy = _SEL0 - V + s * Dt + (rs / r**3) * np.outer(t, t @ Dt)
    Za = np.zeros((3, 2))
    dphi = anchor_weights(old[1], old[2])
    for e in range(2):
        q_e = np.zeros(3)
        for j in range(4):
            q_e += dphi[e, j] * F[j]
        t_e = -q_e + (n @ q_e) * n
        Za[:, e] = q_e + s * t_e + (rs / r**3) * t * (t @ t_e)
    JF, Jz = projection_jacobian(F, new[1], new[2], q + s * t)
    My = Jz @ Zy
    My[:, 3:] += JF
    return My, Jz @ Za, f


@njit(cache=True)
def anchor_tangent(x, nodes, faces, hist, new, active, rs, S, P, out, transpose):
    """Forward: ``out (3c, nz) = d new / dz`` from ``S = dx/dz`` (3n, nz) and ``P = d hist / dz``
    (3c, nz). ``transpose``: ``S (3n, nz) += (d new / dx)^T P`` and ``out (3c, nz) += (d new /
    d hist)^T P`` for ``P`` the adjoint of ``new``. ``active[c]``: the node's friction was on
    during the step."""
    for c in range(nodes.shape[0]):
        My, Ma, f = _update_jacobian(x, nodes[c], faces, hist[c], new[c], active[c], rs)
        if f < 0:
            continue
        dofs = pair_dofs(nodes[c], f, faces)
        for j in range(P.shape[1]):
            for e in range(2):
                if transpose:
                    m = P[3 * c + 1 + e, j]
                    for i in range(15):
                        S[dofs[i], j] += My[e, i] * m
                    out[3 * c + 1, j] += Ma[e, 0] * m
                    out[3 * c + 2, j] += Ma[e, 1] * m
                else:
                    acc = Ma[e, 0] * P[3 * c + 1, j] + Ma[e, 1] * P[3 * c + 2, j]
                    for i in range(15):
                        acc += My[e, i] * S[dofs[i], j]
                    out[3 * c + 1 + e, j] = acc
