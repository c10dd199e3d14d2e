r"""The Coulomb law (:mod:`.coulomb`) on a height field: :class:`CoulombFieldContact`.

The plane's law carried over to the surface ``y = h(x, z)`` (:mod:`.surface`): normal penalty
``Q_n(s)`` on the penetration ``s`` along the normal, ``N_{k-1} = Q_n'(s(x_{k-1}))``, and the
stick anchor of node ``i`` a surface point ``A_i = (a_x, h(a_x, a_z), a_z)`` kept as its
``(a_x, a_z)`` (the history, (c, 2) as on the plane). The bristle lies in the anchor's tangent
plane:

.. math::
    d_i = P_A (x_i - A_i), \quad P_A = I - n_A n_A^T, \qquad
    E_i = Q_n(s(x_i)) + \mu N_{k-1,i}\, G(|d_i|)

with ``G`` the bristle potential of :func:`.coulomb.bristle_potential` and ``n_A`` the surface
normal at the anchor. Gradient ``mu N w(r) d``, Hessian ``mu N (w P_A + c d d^T)`` (PSD).
Anchor update, with ``r = |d|``: not loaded (``N_{k-1} = 0``): re-anchored at the node's foot
``x + s n`` (:func:`.surface.surface_foot`); ``r <= r_s``: kept; sliding: ``A + (1 - r_s / r)
d``, the node's tangential position ``r_s`` behind it, both stored by their ``(x, z)``. For a
planar field every step is the plane's law rotated (anchors included).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .coulomb import CoulombContact, bristle_potential
from .surface import LaggedGeometry, field_normal_forces, field_normal_penalty, surface_foot

__all__ = ["CoulombFieldContact"]


@njit(cache=True, inline="always")
def _bristle(x, n, c, anchors, lag, rs, w, d):
    """Friction geometry of contact node ``n`` (anchor ``c``; ``lag`` from
    :class:`.surface.LaggedGeometry` at the anchors): fills ``w = x - A`` and the offset ``d``.
    Returns ``(N_{k-1}, Q_n''(s_prev), r, G, w(r), c(r))`` (N = 0: no friction)."""
    N, Npp, _, height, nrm, _ = lag
    w[0] = x[n, 0] - anchors[c, 0]
    w[1] = x[n, 1] - height[c]
    w[2] = x[n, 2] - anchors[c, 1]
    nw = nrm[c, 0] * w[0] + nrm[c, 1] * w[1] + nrm[c, 2] * w[2]
    r2 = 0.0
    for i in range(3):
        d[i] = w[i] - nw * nrm[c, i]
        r2 += d[i] * d[i]
    r = np.sqrt(r2)
    if N[c] <= 0.0:
        return 0.0, 0.0, r, 0.0, 0.0, 0.0
    G, wr, cr = bristle_potential(r, rs)
    return N[c], Npp[c], r, G, wr, cr


@njit(cache=True, inline="always")
def _offset_derivative(nA, dnA, w, D):
    """``D (3, 2)``: d(offset)/d(a_x, a_z) = ``-A_a - (dn_a . w) n - (n . w) dn_a`` with the
    tangent ``A_a = e_a + h_a e_y`` (``h_a = -n_a / n_y``)."""
    nw = nA[0] * w[0] + nA[1] * w[1] + nA[2] * w[2]
    for a in range(2):
        k = 2 * a
        dnw = dnA[a, 0] * w[0] + dnA[a, 1] * w[1] + dnA[a, 2] * w[2]
        for i in range(3):
            D[i, a] = -dnw * nA[i] - nw * dnA[a, i]
        D[k, a] -= 1.0
        D[1, a] += nA[k] / nA[1]


@njit(cache=True)
def _assemble(field, x, anchors, lag, nodes, k_n, eps_n, mu, rs, grad, hdata, slots, want_grad, want_hess,
              project):
    total = 0.0
    ds, d2s, w, d = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty(3)
    nrm = lag[4]
    for c in range(nodes.shape[0]):
        n = nodes[c]
        total += field_normal_penalty(x, n, field, k_n, eps_n, grad, hdata, slots[c], want_grad, want_hess,
                                      project, ds, d2s)
        N, _, r, G, wr, cr = _bristle(x, n, c, anchors, lag, rs, w, d)
        if N <= 0.0:
            continue
        a = mu * N
        total += a * G
        if want_grad:
            for i in range(3):
                grad[3 * n + i] += a * wr * d[i]
        if want_hess:
            for i in range(3):
                for j in range(i + 1):
                    hdata[slots[c, 3 * i + j]] += a * (wr * ((1.0 if i == j else 0.0) - nrm[c, i] * nrm[c, j])
                                                       + cr * d[i] * d[j])
    return total


@njit(cache=True)
def _prev_product(x, anchors, lag, nodes, mu, rs, S, out, transpose):
    """``out += d(grad)/dx_prev @ S`` (``transpose``: ``out (3n, 1) += (...)^T @ S``): through
    ``N_{k-1}`` only, ``mu w d (Q_n''(s_prev) grad s(x_prev))^T``."""
    w, d = np.empty(3), np.empty(3)
    dsp = lag[2]
    for c in range(nodes.shape[0]):
        n = nodes[c]
        N, Npp, r, G, wr, cr = _bristle(x, n, c, anchors, lag, rs, w, d)
        if N <= 0.0:
            continue
        f = mu * wr * Npp
        for j in range(S.shape[1]):
            if transpose:
                dl = d[0] * S[3 * n, j] + d[1] * S[3 * n + 1, j] + d[2] * S[3 * n + 2, j]
                for k in range(3):
                    out[3 * n + k, j] += f * dsp[c, k] * dl
            else:
                ss = dsp[c, 0] * S[3 * n, j] + dsp[c, 1] * S[3 * n + 1, j] + dsp[c, 2] * S[3 * n + 2, j]
                for i in range(3):
                    out[3 * n + i, j] += f * d[i] * ss


@njit(cache=True)
def _anchor_product(x, anchors, lag, nodes, mu, rs, P, out, transpose):
    """``out (3n, nz) += d(grad)/d anchors @ P (2c, nz)``; ``transpose``: ``out (2c, nz) +=
    (d(grad)/d anchors)^T @ P (3n, nz)``. ``d grad / d a = mu N (w I + c d d^T) D``."""
    w, d, D, K = np.empty(3), np.empty(3), np.empty((3, 2)), np.empty((3, 2))
    nrm, dnrm = lag[4], lag[5]
    for c in range(nodes.shape[0]):
        n = nodes[c]
        N, _, r, G, wr, cr = _bristle(x, n, c, anchors, lag, rs, w, d)
        if N <= 0.0:
            continue
        _offset_derivative(nrm[c], dnrm[c], w, D)
        for a in range(2):
            dD = d[0] * D[0, a] + d[1] * D[1, a] + d[2] * D[2, a]
            for i in range(3):
                K[i, a] = mu * N * (wr * D[i, a] + cr * d[i] * dD)
        for j in range(P.shape[1]):
            for a in range(2):
                for i in range(3):
                    if transpose:
                        out[2 * c + a, j] += K[i, a] * P[3 * n + i, j]
                    else:
                        out[3 * n + i, j] += K[i, a] * P[2 * c + a, j]


@njit(cache=True)
def _next_anchors(field, x, anchors, lag, nodes, rs, out, Jx, Ja):
    """The anchor update (module docstring) into ``out (c, 2)``, and its derivatives ``Jx (c, 2,
    3)`` with respect to the node and ``Ja (c, 2, 2)`` with respect to the anchor."""
    w, d, D, M = np.empty(3), np.empty(3), np.empty((3, 2)), np.empty((3, 3))
    ds, d2s, fn, fdn = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty((2, 3))
    nrm, dnrm = lag[4], lag[5]
    for c in range(nodes.shape[0]):
        n = nodes[c]
        N, _, r, G, wr, cr = _bristle(x, n, c, anchors, lag, rs, w, d)
        Jx[c] = 0.0
        Ja[c] = 0.0
        if N <= 0.0:                                    # re-anchored at the node's foot
            out[c, 0], out[c, 1] = surface_foot(field, x[n], Jx[c], ds, d2s, fn, fdn)
        elif r <= rs:                                   # sticks
            out[c, 0], out[c, 1] = anchors[c, 0], anchors[c, 1]
            Ja[c, 0, 0] = 1.0
            Ja[c, 1, 1] = 1.0
        else:                                           # slides: A + (1 - rs / r) d
            f = 1.0 - rs / r
            out[c, 0], out[c, 1] = anchors[c, 0] + f * d[0], anchors[c, 1] + f * d[2]
            for i in range(3):                          # M = f I + (rs / r^3) d d^T
                for j in range(3):
                    M[i, j] = (f if i == j else 0.0) + rs / (r * r * r) * d[i] * d[j]
            _offset_derivative(nrm[c], dnrm[c], w, D)
            for a in range(2):
                k = 2 * a
                mn = M[k, 0] * nrm[c, 0] + M[k, 1] * nrm[c, 1] + M[k, 2] * nrm[c, 2]
                for j in range(3):                      # M P_A, row k
                    Jx[c, a, j] = M[k, j] - mn * nrm[c, j]
                for b in range(2):
                    Ja[c, a, b] = (1.0 if a == b else 0.0) + M[k, 0] * D[0, b] + M[k, 1] * D[1, b] + M[k, 2] * D[2, b]


@njit(cache=True)
def _foot_anchors(field, x0, nodes, out):
    J, ds, d2s, n, dn = np.empty((2, 3)), np.empty(3), np.empty((3, 3)), np.empty(3), np.empty((2, 3))
    for c in range(nodes.shape[0]):
        out[c, 0], out[c, 1] = surface_foot(field, x0[nodes[c]], J, ds, d2s, n, dn)


class CoulombFieldContact(CoulombContact):
    """:class:`~.coulomb.CoulombContact` on ``robot.ground`` (module docstring); its history is
    the anchors' ``(x, z)`` (c, 2)."""

    def __init__(self, robot):
        super().__init__(robot)
        self.field = robot.ground.args
        self.lagged = LaggedGeometry(self.field, self.nodes, self.k_n, self.eps_n)

    def _args(self, x, x_prev, hist):
        return x, hist, self.lagged(x_prev, hist), self.nodes

    def normal_forces(self, x):
        return field_normal_forces(x, self.nodes, self.field, self.k_n, self.eps_n)

    def _assemble(self, x, x_prev, hist, mu, grad, hdata, want_grad, want_hess, project) -> float:
        return _assemble(self.field, x, hist, self.lagged(x_prev, hist), self.nodes, self.k_n, self.eps_n, mu,
                         self.rs, grad, hdata, self.slots, want_grad, want_hess, project)

    def energy(self, x, x_prev, u, hist=None) -> float:
        return self._assemble(x, x_prev, hist, self.mu, self._scratch, self._scratch, False, False, False)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return self._assemble(x, x_prev, hist, self.mu, grad, hdata, True, want_hess, False)

    def assemble_projected(self, x, x_prev, u, hist, grad, hdata) -> float:
        return self._assemble(x, x_prev, hist, self.mu, grad, hdata, True, True, True)

    def add_prev_product(self, x, x_prev, u, hist, S, out) -> None:
        _prev_product(*self._args(x, x_prev, hist), self.mu, self.rs, S, out, False)

    def add_prev_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        tmp = np.zeros((out.shape[0], 1))
        _prev_product(*self._args(x, x_prev, hist), self.mu, self.rs, lam.reshape(-1, 1), tmp, True)
        out += tmp[:, 0]

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        """The whole gradient is linear in k_n (``N`` and ``N_{k-1}``), its friction part
        linear in mu."""
        normal, friction = np.zeros(out.shape[0]), np.zeros(out.shape[0])
        self._assemble(x, x_prev, hist, 0.0, normal, self._scratch, True, False, False)
        self._assemble(x, x_prev, hist, 1.0, friction, self._scratch, True, False, False)
        friction -= normal                                                  # at mu = 1
        for j, n in enumerate(names):
            if n == "contact_stiffness":
                out[:, j] += (normal + self.mu * friction) / self.k_n
            elif n == "friction_coefficient":
                out[:, j] += friction

    def initial_history(self, x0) -> np.ndarray:
        """Every node anchored at its foot on the surface."""
        out = np.empty((len(self.nodes), 2))
        _foot_anchors(self.field, x0, self.nodes, out)
        return out

    def _update(self, x, x_prev, hist):
        c = len(self.nodes)
        out, Jx, Ja = np.empty((c, 2)), np.empty((c, 2, 3)), np.empty((c, 2, 2))
        _next_anchors(self.field, x, hist, self.lagged(x_prev, hist), self.nodes, self.rs, out, Jx, Ja)
        return out, Jx, Ja

    def next_history(self, x, x_prev, hist) -> np.ndarray:
        return self._update(x, x_prev, hist)[0]

    def add_history_product(self, x, x_prev, u, hist, P, out) -> None:
        _anchor_product(*self._args(x, x_prev, hist), self.mu, self.rs, P, out, False)

    def add_history_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        tmp = np.zeros((out.shape[0], 1))
        _anchor_product(*self._args(x, x_prev, hist), self.mu, self.rs, lam.reshape(-1, 1), tmp, True)
        out += tmp[:, 0]

    def history_tangent(self, x, x_prev, hist, S, P) -> np.ndarray:
        _, Jx, Ja = self._update(x, x_prev, hist)
        Sn = S.reshape(-1, 3, S.shape[1])[self.nodes]                       # (c, 3, nz)
        out = np.einsum("cij,cjz->ciz", Jx, Sn) + np.einsum("cab,cbz->caz", Ja, P.reshape(-1, 2, P.shape[1]))
        return out.reshape(P.shape)

    def history_tangent_T(self, x, x_prev, hist, m, out_x, out_h) -> None:
        _, Jx, Ja = self._update(x, x_prev, hist)
        m2 = m.reshape(-1, 2)
        np.add.at(out_x.reshape(-1, 3), self.nodes, np.einsum("cij,ci->cj", Jx, m2))
        out_h += np.einsum("cab,ca->cb", Ja, m2).ravel()
