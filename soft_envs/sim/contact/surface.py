r"""Contact geometry against a height field ``y = h(x, z)`` (:class:`~soft_envs.sim.ground.HeightField`)
and the normal penalty on it, shared by the contact laws' height-field variants.

The penetration of a point ``p = (x, y, z)`` is its gap below the surface measured along the
normal, to first order:

.. math::
    s(p) = \frac{h(x, z) - y}{L}, \qquad L = \sqrt{1 + h_x^2 + h_z^2}, \qquad
    n = \frac{(-h_x, 1, -h_z)}{L}

(``s > 0`` below the ground; ``n`` the upward unit normal at ``(x, z)``). For a planar field
``s`` is exactly the signed distance to the plane and ``grad s = -n``: the contact on a plane of
any slope is the contact on ``y = 0`` rotated. On a curved field ``grad s = -n + (h - y)
grad(1/L)``, along the normal on the surface and tilted by O(depth x curvature) below it. The
normal penalty is ``Q_n(s)`` (:func:`.penalty.Q`); its gradient ``Q_n'(s) grad s`` and Hessian
``Q_n''(s) grad s grad s^T + Q_n'(s) hess s``, where ``hess s`` involves the third
derivatives of ``h`` (the field is C4, so it is continuous). Its PSD substitute (Newton's
fallback) drops the curvature term ``Q_n' hess s``.

A field is passed to the kernels as the tuple ``HeightField.args``. Nodes above the relief's
highest coefficient (``HeightField.args``' ``top``) skip the field's evaluation in the
normal penalty: most of a robot's boundary nodes are in the air.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..ground import height_derivatives
from .penalty import Q, d2Q, dQ

__all__ = ["penetration", "surface_normal", "field_normal_penalty", "field_normal_forces", "surface_foot",
           "LaggedGeometry"]


@njit(cache=True)
def penetration(field, px, py, pz, ds, d2s, want_hess, n=None, dn=None):
    """``s(p)`` (module docstring); fills ``ds (3,)`` with ``grad s``, with ``want_hess``
    ``d2s (3, 3)`` with ``hess s``, and when given ``n (3,)`` and ``dn (2, 3)`` with the normal
    at ``(px, pz)`` and its derivatives (:func:`surface_normal`, from the same evaluation)."""
    coef, x0, z0, dx, dz, ax, az, _ = field
    h, hx, hz, hxx, hxz, hzz, hxxx, hxxz, hxzz, hzzz = height_derivatives(coef, x0, z0, dx, dz, ax, az, px, pz)
    q = 1.0 / np.sqrt(1.0 + hx * hx + hz * hz)
    u = h - py
    q3 = q * q * q
    mx = hx * hxx + hz * hxz                 # d(|grad h|^2 / 2)/dx
    mz = hx * hxz + hz * hzz
    qx, qz = -q3 * mx, -q3 * mz              # grad (1/L)
    ds[0] = q * hx + u * qx
    ds[1] = -q
    ds[2] = q * hz + u * qz
    if n is not None:
        _normal(q, hx, hz, hxx, hxz, hzz, n, dn)
    if want_hess:
        du = (hx, -1.0, hz)
        qv = (qx, 0.0, qz)
        mxx = hxx * hxx + hxz * hxz + hx * hxxx + hz * hxxz
        mxz = hxz * hxx + hzz * hxz + hx * hxxz + hz * hxzz
        mzz = hxz * hxz + hzz * hzz + hx * hxzz + hz * hzzz
        q5 = q3 * q * q
        for i in range(3):
            for j in range(3):
                d2s[i, j] = du[i] * qv[j] + qv[i] * du[j]
        d2s[0, 0] += q * hxx + u * (3.0 * q5 * mx * mx - q3 * mxx)
        d2s[0, 2] += q * hxz + u * (3.0 * q5 * mx * mz - q3 * mxz)
        d2s[2, 0] += q * hxz + u * (3.0 * q5 * mx * mz - q3 * mxz)
        d2s[2, 2] += q * hzz + u * (3.0 * q5 * mz * mz - q3 * mzz)
    return u * q


@njit(cache=True)
def surface_normal(field, px, pz, n, dn):
    """The surface point's height ``h(px, pz)``; fills ``n (3,)`` with the unit normal there and
    ``dn (2, 3)`` with its derivatives along x and z."""
    coef, x0, z0, dx, dz, ax, az, _ = field
    h, hx, hz, hxx, hxz, hzz, _, _, _, _ = height_derivatives(coef, x0, z0, dx, dz, ax, az, px, pz)
    _normal(1.0 / np.sqrt(1.0 + hx * hx + hz * hz), hx, hz, hxx, hxz, hzz, n, dn)
    return h


@njit(cache=True, inline="always")
def _normal(q, hx, hz, hxx, hxz, hzz, n, dn):
    """``n = q (-h_x, 1, -h_z)`` and ``dn (2, 3)`` (``q = 1 / sqrt(1 + h_x^2 + h_z^2)``)."""
    q3 = q * q * q
    n[0], n[1], n[2] = -q * hx, q, -q * hz
    for a in range(2):
        ha_x = hxx if a == 0 else hxz            # d h_x / d a
        ha_z = hxz if a == 0 else hzz
        qa = -q3 * (hx * ha_x + hz * ha_z)
        dn[a, 0] = -qa * hx - q * ha_x
        dn[a, 1] = qa
        dn[a, 2] = -qa * hz - q * ha_z


@njit(cache=True, inline="always")
def field_normal_penalty(x, node, field, k_n, eps_n, grad, hdata, slots, want_grad, want_hess, project, ds, d2s):
    """The normal penalty ``Q_n(s)`` of node ``node`` (module docstring): adds its gradient
    (``want_grad``) and its 3x3 Hessian block into the row-major ``slots (9,)`` (``want_hess``;
    ``project``: without the curvature term). ``ds``, ``d2s``: work arrays (3,), (3, 3)."""
    _, _, _, _, _, ax, az, top = field
    if x[node, 1] - ax * x[node, 0] - az * x[node, 2] >= top:       # above the highest relief: s < 0
        return 0.0
    s = penetration(field, x[node, 0], x[node, 1], x[node, 2], ds, d2s, want_hess and not project)
    if s <= 0.0:
        return 0.0
    if want_grad:
        f = dQ(s, k_n, eps_n)
        for i in range(3):
            grad[3 * node + i] += f * ds[i]
    if want_hess:
        f = dQ(s, k_n, eps_n)
        f2 = d2Q(s, k_n, eps_n)
        for i in range(3):
            for j in range(i + 1):
                v = f2 * ds[i] * ds[j]
                if not project:
                    v += f * d2s[i, j]
                hdata[slots[3 * i + j]] += v
    return Q(s, k_n, eps_n)


@njit(cache=True)
def field_normal_forces(x, nodes, field, k_n, eps_n):
    """Normal force ``N_i = Q_n'(s(x_i))`` [N] at every contact node."""
    out = np.empty(nodes.shape[0])
    ds = np.empty(3)
    d2s = np.empty((3, 3))
    _, _, _, _, _, ax, az, top = field
    for c in range(nodes.shape[0]):
        n = nodes[c]
        above = x[n, 1] - ax * x[n, 0] - az * x[n, 2] >= top
        out[c] = 0.0 if above else dQ(penetration(field, x[n, 0], x[n, 1], x[n, 2], ds, d2s, False), k_n, eps_n)
    return out


@njit(cache=True)
def surface_foot(field, p, J, ds, d2s, n, dn):
    """The foot ``(x, z)`` of point ``p (3,)`` on the surface, ``p + s(p) n`` with the normal at
    ``(p_x, p_z)`` (for a planar field the orthogonal projection), and its derivative
    ``J (2, 3)`` (rows x, z) with respect to ``p``. ``ds, d2s, n, dn``: work arrays (3,),
    (3, 3), (3,), (2, 3)."""
    s = penetration(field, p[0], p[1], p[2], ds, d2s, False, n, dn)
    for r in range(2):
        k = 2 * r                            # x or z component
        for j in range(3):
            J[r, j] = (1.0 if j == k else 0.0) + n[k] * ds[j]
        J[r, 0] += s * dn[0, k]
        J[r, 2] += s * dn[1, k]
    return p[0] + s * n[0], p[2] + s * n[2]


@njit(cache=True)
def _lagged(field, x_prev, nodes, k_n, eps_n, points, at_nodes, N, Npp, dsp, height, normal, dnormal):
    """:class:`LaggedGeometry`'s arrays; a node not pressed into the ground at ``x_prev`` (no
    friction) gets ``N = 0`` and a horizontal frame, without evaluating the field above it."""
    _, _, _, _, _, ax, az, top = field
    d2s = np.empty((3, 3))
    for c in range(nodes.shape[0]):
        n = nodes[c]
        if x_prev[n, 1] - ax * x_prev[n, 0] - az * x_prev[n, 2] >= top:
            sp = -1.0
        elif at_nodes:
            sp = penetration(field, x_prev[n, 0], x_prev[n, 1], x_prev[n, 2], dsp[c], d2s, False, normal[c],
                             dnormal[c])
            height[c] = x_prev[n, 1] + sp / normal[c, 1]          # s = (h - y) n_y
        else:
            sp = penetration(field, x_prev[n, 0], x_prev[n, 1], x_prev[n, 2], dsp[c], d2s, False)
            if sp > 0.0:
                height[c] = surface_normal(field, points[c, 0], points[c, 1], normal[c], dnormal[c])
        N[c] = dQ(sp, k_n, eps_n)
        Npp[c] = d2Q(sp, k_n, eps_n)
        if N[c] <= 0.0:
            dsp[c] = 0.0
            height[c] = 0.0
            normal[c] = 0.0
            normal[c, 1] = 1.0
            dnormal[c] = 0.0


class LaggedGeometry:
    """What a field law's friction takes from the previous step, once per step instead of once
    per Newton iteration: at every contact node ``N_{k-1} = Q_n'(s(x_prev))``, ``Q_n''(s(x_prev))``
    and ``grad s(x_prev)`` (c, 3), and the surface's height, normal (c, 3) and the normal's
    derivatives (c, 2, 3) at ``points`` (c, 2) (the stick anchors), or below ``x_prev`` when
    ``points`` is None. Recomputed when ``x_prev`` or ``points`` differ from the last call's."""

    def __init__(self, field, nodes, k_n, eps_n):
        self.field, self.nodes, self.k_n, self.eps_n = field, nodes, k_n, eps_n
        self._key: tuple | None = None
        self._value: tuple | None = None

    def __call__(self, x_prev, points=None) -> tuple:
        """``(N, Q_n'', grad s, height, normal, d normal)`` (module docstring of the class)."""
        key = self._key
        if key is not None and np.array_equal(key[0], x_prev) and (
                (points is None and key[1] is None) or (points is not None and key[1] is not None
                                                         and np.array_equal(key[1], points))):
            return self._value
        c = len(self.nodes)
        value = (np.empty(c), np.empty(c), np.empty((c, 3)), np.empty(c), np.empty((c, 3)), np.empty((c, 2, 3)))
        _lagged(self.field, x_prev, self.nodes, self.k_n, self.eps_n,
                np.zeros((c, 2)) if points is None else points, points is None, *value)
        self._key = (np.array(x_prev), None if points is None else np.array(points))
        self._value = value
        return value
