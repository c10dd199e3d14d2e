"""Gravity (paper II-D) and inclines (paper IV-B: an incline rotates gravity, not the ground)."""
from __future__ import annotations

import math

import numpy as np

from .terms import EnergyTerm

__all__ = ["Gravity", "incline_gravity"]


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


class Gravity(EnergyTerm):
    r"""Gravitational potential ``E = -sum_i m_i g . x_i`` for any vector ``g`` [m/s^2] (an
    incline rotates ``g``, paper IV-B; see :func:`incline_gravity`). ``mass_jacobian``
    (optional): ``{parameter: dm_i/dtheta (n,)}`` for the parameters that change the masses
    (:func:`~.parameters.node_mass_jacobian`); ``d(dE/dx)/dtheta = -dm/dtheta g``."""

    name = "gravity"

    def __init__(self, node_masses: np.ndarray, g: np.ndarray, mass_jacobian=None):
        self.g = np.asarray(g, dtype=np.float64)
        self.force = (np.asarray(node_masses)[:, None] * self.g[None, :]).ravel()   # (3n,)
        self.mass_jacobian = dict(mass_jacobian or {})
        self.parameters = tuple(self.mass_jacobian)

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        for j, n in enumerate(names):
            if n in self.mass_jacobian:
                out[:, j] -= (self.mass_jacobian[n][:, None] * self.g[None, :]).ravel()

    def energy(self, x, x_prev, u, hist=None) -> float:
        return -float(self.force @ x.ravel())

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        grad -= self.force
        return -float(self.force @ x.ravel())
