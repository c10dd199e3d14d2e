"""The elastic energy term: compressible neo-Hookean linear tetrahedra (paper eq. 1).

``E_FEM(x) = sum_e V_e Psi(F_e)``; the kernels (energy density, stress, 12x12 element Hessian
and the scatter into the global pattern) are in :mod:`.materials`, the positive semi-definite
projection used by the Newton solver's fallback in :mod:`.psd_projection`.
"""
from __future__ import annotations

import numpy as np

from .materials import fem_assemble, fem_energy
from .psd_projection import fem_assemble_projected
from .terms import EnergyTerm

__all__ = ["Elastic"]


class Elastic(EnergyTerm):
    """Neo-Hookean elasticity of every tet of ``robot.mesh`` with the robot's Lame parameters
    (eq. 1). ``inf`` when an element is inverted (J <= 0)."""

    name = "elastic"

    def __init__(self, robot):
        mesh = robot.mesh
        self.tets, self.dN, self.vol = mesh.tets, mesh.dN, mesh.volumes
        self.mu, self.lam = robot.element_lame()

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
