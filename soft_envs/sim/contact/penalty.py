r"""The smooth one-sided quadratic ``Q`` (paper II-B, II-C) and the ground's normal penalty.

``Q(s)`` is the energy of a unilateral spring stretched (cables: ``s = Gamma``, eq. 2) or
pressed into the ground (contact: ``s = -y``, the depth of a node below the plane ``y = 0``)
by ``s``: zero for ``s <= 0``, a C2 cubic blend of width ``eps`` and then a quadratic of
stiffness ``k``. The cables (:mod:`soft_envs.sim.cables`) and every contact law
(:mod:`soft_envs.sim.contact`) use it; the contact laws' normal penalty ``Q_n(-y_i)`` per contact
node is :func:`normal_penalty`, its force ``N_i = Q_n'(-y_i)`` :func:`normal_forces`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["Q", "dQ", "d2Q", "one_sided_quadratic", "normal_forces", "normal_penalty"]


@njit(cache=True)
def Q(s, k, eps):
    """Smooth one-sided quadratic (paper II-B): 0 for s <= 0, ``k s^3 / (6 eps)`` on (0, eps)
    (C2 cubic blend, Q'' rising linearly from 0 to k), ``k eps^2/6 + k s (s - eps)/2`` beyond.
    With ``eps = 0`` it is the half-quadratic ``k max(s, 0)^2 / 2`` (C1; Q'' jumps from 0 to k)."""
    if s <= 0.0:
        return 0.0
    if s < eps:
        return k * s * s * s / (6.0 * eps)
    return k * eps * eps / 6.0 + 0.5 * k * s * (s - eps)


@njit(cache=True)
def dQ(s, k, eps):
    """Q'(s): the spring force (cable tension, contact normal force)."""
    if s <= 0.0:
        return 0.0
    if s < eps:
        return 0.5 * k * s * s / eps
    return k * (s - 0.5 * eps)


@njit(cache=True)
def d2Q(s, k, eps):
    """Q''(s)."""
    if s <= 0.0:
        return 0.0
    if s < eps:
        return k * s / eps
    return k


def one_sided_quadratic(s, k: float, eps: float):
    """Vectorised ``(Q, Q', Q'')`` of :func:`Q` for numpy arrays (used by objectives and tests)."""
    s = np.asarray(s, dtype=np.float64)
    blend = (s > 0) & (s < eps)
    full = (s >= eps) & (s > 0)
    eps_safe = np.where(np.asarray(eps) > 0, eps, 1.0)        # eps = 0: no blend region
    q = np.where(blend, k * s**3 / (6 * eps_safe), np.where(full, k * eps**2 / 6 + 0.5 * k * s * (s - eps), 0.0))
    dq = np.where(blend, 0.5 * k * s**2 / eps_safe, np.where(full, k * (s - 0.5 * eps), 0.0))
    d2q = np.where(blend, k * s / eps_safe, np.where(full, k, 0.0))
    return q, dq, d2q


@njit(cache=True)
def normal_forces(x, nodes, k_n, eps_n):
    """Normal force ``N_i = Q_n'(-y_i)`` at every contact node."""
    out = np.empty(nodes.shape[0])
    for c in range(nodes.shape[0]):
        out[c] = dQ(-x[nodes[c], 1], k_n, eps_n)
    return out


@njit(cache=True, inline="always")
def normal_penalty(x, n, k_n, eps_n, grad, hdata, slot, want_grad, want_hess):
    """The normal penalty ``Q_n(-y)`` of node ``n`` (paper II-C; every contact law): adds its
    gradient (``want_grad``) and its Hessian entry ``hdata[slot]`` (``want_hess``). Returns
    the energy."""
    s = -x[n, 1]
    if want_grad:
        grad[3 * n + 1] -= dQ(s, k_n, eps_n)
    if want_hess:
        hdata[slot] += d2Q(s, k_n, eps_n)
    return Q(s, k_n, eps_n)
