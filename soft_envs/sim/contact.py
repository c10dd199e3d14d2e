r"""Ground contact, lagged friction and gravity (paper II-C, IV-B).

The ground is the plane ``y = 0``. Per contact node ``i`` (the boundary nodes):

.. math::
    E_i^{contact} = Q_n(-y_i) + \mu_f N_{k-1,i}\,\big((x_i - x_{k-1,i})^2 + (z_i - z_{k-1,i})^2\big),
    \qquad N_{k-1,i} = Q_n'(-y_{k-1,i})

(paper eq. in II-C): a one-sided quadratic penalty of stiffness ``k_n`` [N/m] against
penetration, and a friction energy that resists tangential motion in proportion to the normal
force of the previous step. ``mu_f`` [1/m] is the paper's tunable roughness weight: the
tangential force is ``2 mu_f N dx_t``, so a node sliding ``1/(2 mu_f)`` metres in one step
feels a tangential force equal to its normal force.

Gravity: ``E = -sum_i m_i g . x_i`` for any vector ``g``; an incline rotates ``g``, not the
ground (paper IV-B), see :func:`incline_gravity`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cables import Q, d2Q, dQ

__all__ = ["contact_energy", "contact_assemble", "friction_cross", "friction_cross_T",
           "normal_forces", "incline_gravity"]


def incline_gravity(angle_deg: float, g: float = 9.81, uphill: tuple[float, float] = (1.0, 0.0)) -> np.ndarray:
    """Gravity vector equivalent to standing on a slope of ``angle_deg`` that rises along the
    horizontal direction ``uphill`` (x, z). A robot walking uphill along +x feels gravity tilted
    towards -x: ``g = 9.81 (-sin a, -cos a, 0)``."""
    a = math.radians(float(angle_deg))
    d = np.array([uphill[0], 0.0, uphill[1]], dtype=np.float64)
    n = np.linalg.norm(d)
    if n == 0:
        raise ValueError("uphill direction must be non-zero")
    d /= n
    return -g * (math.sin(a) * d + np.array([0.0, math.cos(a), 0.0]))


@njit(cache=True)
def normal_forces(x, nodes, k_n, eps_n):
    """Normal force ``N_i = Q_n'(-y_i)`` at every contact node."""
    out = np.empty(nodes.shape[0])
    for c in range(nodes.shape[0]):
        out[c] = dQ(-x[nodes[c], 1], k_n, eps_n)
    return out


@njit(cache=True)
def contact_energy(x, x_prev, nodes, k_n, eps_n, mu_f):
    total = 0.0
    for c in range(nodes.shape[0]):
        n = nodes[c]
        total += Q(-x[n, 1], k_n, eps_n)
        N = dQ(-x_prev[n, 1], k_n, eps_n)
        if N > 0.0:
            dx = x[n, 0] - x_prev[n, 0]
            dz = x[n, 2] - x_prev[n, 2]
            total += mu_f * N * (dx * dx + dz * dz)
    return total


@njit(cache=True)
def contact_assemble(x, x_prev, nodes, k_n, eps_n, mu_f, grad, hdata, diag_map, want_hess=True):
    """Add gradient and (diagonal) Hessian; ``diag_map (c, 3)`` gives the Hessian slots of the
    x, y, z diagonal entries of each contact node. Returns the energy."""
    total = 0.0
    for c in range(nodes.shape[0]):
        n = nodes[c]
        s = -x[n, 1]
        total += Q(s, k_n, eps_n)
        grad[3 * n + 1] -= dQ(s, k_n, eps_n)
        if want_hess:
            hdata[diag_map[c, 1]] += d2Q(s, k_n, eps_n)
        N = dQ(-x_prev[n, 1], k_n, eps_n)
        if N > 0.0:
            dx = x[n, 0] - x_prev[n, 0]
            dz = x[n, 2] - x_prev[n, 2]
            total += mu_f * N * (dx * dx + dz * dz)
            grad[3 * n] += 2.0 * mu_f * N * dx
            grad[3 * n + 2] += 2.0 * mu_f * N * dz
            if want_hess:
                hdata[diag_map[c, 0]] += 2.0 * mu_f * N
                hdata[diag_map[c, 2]] += 2.0 * mu_f * N
    return total


@njit(cache=True)
def friction_cross(x, x_prev, nodes, k_n, eps_n, mu_f, S_prev, out):
    """``out += (d^2 E / dx dx_prev) @ S_prev`` for the friction term (rows = dofs of x).

    d(grad_t)/d(t_prev) = -2 mu_f N and d(grad_t)/d(y_prev) = -2 mu_f dt Q_n''(-y_prev),
    for t in {x, z}: the previous state enters through the displacement and through N."""
    nz = S_prev.shape[1]
    for c in range(nodes.shape[0]):
        n = nodes[c]
        sp = -x_prev[n, 1]
        N = dQ(sp, k_n, eps_n)
        if N <= 0.0:
            continue
        dN = -d2Q(sp, k_n, eps_n)  # dN / dy_prev
        for t in (0, 2):
            d = x[n, t] - x_prev[n, t]
            a = -2.0 * mu_f * N
            b = 2.0 * mu_f * d * dN
            for j in range(nz):
                out[3 * n + t, j] += a * S_prev[3 * n + t, j] + b * S_prev[3 * n + 1, j]


@njit(cache=True)
def friction_cross_T(x, x_prev, nodes, k_n, eps_n, mu_f, lam, out):
    """``out += (d^2 E / dx dx_prev)^T @ lam`` (adjoint of :func:`friction_cross`)."""
    for c in range(nodes.shape[0]):
        n = nodes[c]
        sp = -x_prev[n, 1]
        N = dQ(sp, k_n, eps_n)
        if N <= 0.0:
            continue
        dN = -d2Q(sp, k_n, eps_n)
        for t in (0, 2):
            d = x[n, t] - x_prev[n, t]
            out[3 * n + t] += -2.0 * mu_f * N * lam[3 * n + t]
            out[3 * n + 1] += 2.0 * mu_f * d * dN * lam[3 * n + t]
