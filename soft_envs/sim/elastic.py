"""The elastic energy term: compressible neo-Hookean linear tetrahedra (paper eq. 1).

``E_FEM(x) = sum_e V_e Psi(F_e)``; the kernels (energy density, stress, 12x12 element Hessian
and the scatter into the global pattern) are in :mod:`.materials`, the positive semi-definite
projection used by the Newton solver's fallback in :mod:`.psd_projection`.

The gradient is linear in the Lame parameters, ``dE/dx = mu G_mu(x) + lam G_lam(x)`` with
``G_mu = sum_e V_e (F - F^{-T}) N_a`` and ``G_lam = sum_e V_e ln J F^{-T} N_a`` (the gradient
kernel at (mu, lam) = (1, 0) and (0, 1)), so its derivative with respect to Young's modulus and
the Poisson ratio is ``dmu/dtheta G_mu + dlam/dtheta G_lam``
(:func:`~.parameters.lame_jacobian`).
"""
from __future__ import annotations

import numpy as np

from .materials import fem_assemble, fem_energy
from .parameters import lame_jacobian
from .psd_projection import fem_assemble_projected
from .terms import EnergyTerm

__all__ = ["Elastic"]


class Elastic(EnergyTerm):
    """Neo-Hookean elasticity of every tet of ``robot.mesh`` with the robot's Lame parameters
    (eq. 1). ``inf`` when an element is inverted (J <= 0)."""

    name = "elastic"
    parameters = ("youngs_modulus", "poisson_ratio")

    def __init__(self, robot):
        mesh = robot.mesh
        self.tets, self.dN, self.vol = mesh.tets, mesh.dN, mesh.volumes
        self.mu, self.lam = robot.element_lame()
        self.modulus_scale = robot.element_modulus_scale
        self._lame_jacobian = lame_jacobian(robot.youngs_modulus, robot.poisson_ratio)

    def hessian_blocks(self) -> list[np.ndarray]:
        return [(3 * self.tets[:, :, None] + np.arange(3)).reshape(len(self.tets), 12)]

    def bind(self, slots, diag_slots) -> None:
        super().bind(slots, diag_slots)
        self.hmap = np.ascontiguousarray(slots[0])            # (m, 144)

    def energy(self, x, x_prev, u, hist=None) -> float:
        return fem_energy(x, self.tets, self.dN, self.vol, self.mu, self.lam)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return fem_assemble(x, self.tets, self.dN, self.vol, self.mu, self.lam, grad, hdata,
                            self.hmap, want_hess)

    def assemble_projected(self, x, x_prev, u, hist, grad, hdata) -> float:
        return fem_assemble_projected(x, self.tets, self.dN, self.vol, self.mu, self.lam, grad,
                                      hdata, self.hmap)

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        cols = [(j, self._lame_jacobian[n]) for j, n in enumerate(names) if n in self.parameters]
        if not cols:
            return
        scale, zeros = self.modulus_scale, np.zeros_like(self.mu)
        g_mu, g_lam = self.lame_gradient(x, scale, zeros), self.lame_gradient(x, zeros, scale)
        for j, (dmu, dlam) in cols:
            out[:, j] += dmu * g_mu + dlam * g_lam

    def lame_gradient(self, x, mu: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """The elastic gradient (3n,) at ``x`` with per-element Lame parameters ``(mu, lam)``
        in place of the robot's: the gradient is linear in them, so per-element derivatives
        (``dmu_e/dtheta``, ``dlam_e/dtheta``) give ``d(dE/dx)/dtheta`` (a parameter that acts
        on some elements only passes zeros elsewhere)."""
        g = np.zeros(3 * len(x))
        if fem_assemble(x, self.tets, self.dN, self.vol, mu, lam, g, g, self.hmap, False) == np.inf:
            raise ValueError("an element is inverted: the elastic gradient has no parameter derivative")
        return g
