r"""The paper's law (:mod:`.paper`) on a height field: :class:`PaperFieldContact`.

On the surface ``y = h(x, z)`` (:mod:`.surface`), per contact node ``i``:

.. math::
    E_i = Q_n(s(x_i)) + \mu_f N_{k-1,i}\, \delta_i^T P_{k-1,i}\, \delta_i, \qquad
    \delta_i = x_i - x_{k-1,i}, \quad P_{k-1,i} = I - n n^T,\ N_{k-1,i} = Q_n'(s(x_{k-1,i}))

with ``n`` the surface normal below the previous position (the tangential part of the step in
the local tangent plane; on ``y = 0``, ``P = diag(1, 0, 1)``: the paper's law). Gradient
``2 mu_f N P delta``, Hessian ``2 mu_f N P`` (a 3x3 block per node, PSD). The previous state
enters through ``delta``, ``N_{k-1}`` and ``P``:

.. math::
    \frac{\partial\, grad}{\partial x_{k-1}} = 2 \mu_f \big[ P\delta\, (Q_n''(s_{k-1})\, \nabla s_{k-1})^T
    - N P - N \sum_{a \in \{x, z\}} (n_a (n \cdot \delta) + n (n_a \cdot \delta)) e_a^T \big]

(``n_a = dn/da``). For a planar field it is the plane's law rotated.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .paper import GroundContact
from .surface import LaggedGeometry, field_normal_forces, field_normal_penalty

__all__ = ["PaperFieldContact"]


@njit(cache=True)
def _assemble(field, x, x_prev, lag, nodes, k_n, eps_n, mu_f, grad, hdata, slots, want_grad, want_hess, project):
    """The energy (module docstring; ``lag`` from :class:`.surface.LaggedGeometry` below
    ``x_prev``); adds its gradient and 3x3 Hessian blocks (``slots (c, 9)``)."""
    total = 0.0
    ds, d2s = np.empty(3), np.empty((3, 3))
    N, nrm = lag[0], lag[4]
    for c in range(nodes.shape[0]):
        n = nodes[c]
        total += field_normal_penalty(x, n, field, k_n, eps_n, grad, hdata, slots[c], want_grad, want_hess,
                                      project, ds, d2s)
        if N[c] <= 0.0:
            continue
        a = mu_f * N[c]
        nd = 0.0
        dd = 0.0
        for i in range(3):
            di = x[n, i] - x_prev[n, i]
            nd += nrm[c, i] * di
            dd += di * di
        total += a * (dd - nd * nd)
        if want_grad:
            for i in range(3):
                grad[3 * n + i] += 2.0 * a * (x[n, i] - x_prev[n, i] - nd * nrm[c, i])
        if want_hess:
            for i in range(3):
                for j in range(i + 1):
                    hdata[slots[c, 3 * i + j]] += 2.0 * a * ((1.0 if i == j else 0.0) - nrm[c, i] * nrm[c, j])
    return total


@njit(cache=True)
def _prev_product(x, x_prev, lag, nodes, mu_f, S, out, transpose):
    """``out += d(grad)/dx_prev @ S`` (module docstring); ``transpose``: ``out (3n, 1) +=
    (...)^T @ S (3n, 1)``."""
    J, Pd, delta = np.empty((3, 3)), np.empty(3), np.empty(3)
    N, Npp, dsp, _, nrm, dnrm = lag
    for c in range(nodes.shape[0]):
        n = nodes[c]
        if N[c] <= 0.0:
            continue
        nd = 0.0
        for i in range(3):
            delta[i] = x[n, i] - x_prev[n, i]
            nd += nrm[c, i] * delta[i]
        for i in range(3):
            Pd[i] = delta[i] - nd * nrm[c, i]
        for i in range(3):
            for j in range(3):
                J[i, j] = Pd[i] * Npp[c] * dsp[c, j] - N[c] * ((1.0 if i == j else 0.0) - nrm[c, i] * nrm[c, j])
        for a in range(2):
            nad = dnrm[c, a, 0] * delta[0] + dnrm[c, a, 1] * delta[1] + dnrm[c, a, 2] * delta[2]
            for i in range(3):
                J[i, 2 * a] -= N[c] * (dnrm[c, a, i] * nd + nrm[c, i] * nad)
        for i in range(3):
            for j in range(3):
                J[i, j] *= 2.0 * mu_f
        for z in range(S.shape[1]):
            for i in range(3):
                for j in range(3):
                    if transpose:
                        out[3 * n + j, z] += J[i, j] * S[3 * n + i, z]
                    else:
                        out[3 * n + i, z] += J[i, j] * S[3 * n + j, z]


class PaperFieldContact(GroundContact):
    """:class:`~.paper.GroundContact` on ``robot.ground`` (module docstring); its Hessian is a
    3x3 block per contact node."""

    def __init__(self, robot):
        super().__init__(robot)
        self.field = robot.ground.args
        self.lagged = LaggedGeometry(self.field, self.nodes, self.k_n, self.eps_n)

    def hessian_blocks(self) -> list[np.ndarray]:
        return [3 * self.nodes[:, None] + np.arange(3)]

    def bind(self, slots, diag_slots) -> None:
        self.diag_slots = diag_slots
        self.slots = np.ascontiguousarray(slots[0])                 # (c, 9)

    def normal_forces(self, x):
        return field_normal_forces(x, self.nodes, self.field, self.k_n, self.eps_n)

    def _assemble(self, x, x_prev, mu_f, grad, hdata, want_grad, want_hess, project) -> float:
        return _assemble(self.field, x, x_prev, self.lagged(x_prev), self.nodes, self.k_n, self.eps_n, mu_f, grad,
                         hdata, self.slots, want_grad, want_hess, project)

    def energy(self, x, x_prev, u, hist=None) -> float:
        return self._assemble(x, x_prev, self.mu_f, self._scratch, self._scratch, False, False, False)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return self._assemble(x, x_prev, self.mu_f, grad, hdata, True, want_hess, False)

    def assemble_projected(self, x, x_prev, u, hist, grad, hdata) -> float:
        return self._assemble(x, x_prev, self.mu_f, grad, hdata, True, True, True)

    def add_prev_product(self, x, x_prev, u, hist, S, out) -> None:
        _prev_product(x, x_prev, self.lagged(x_prev), self.nodes, self.mu_f, S, out, False)

    def add_prev_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        tmp = np.zeros((out.shape[0], 1))
        _prev_product(x, x_prev, self.lagged(x_prev), self.nodes, self.mu_f, lam.reshape(-1, 1), tmp, True)
        out += tmp[:, 0]

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        """The whole gradient is linear in k_n (``N`` and ``N_{k-1}``), its friction part
        linear in mu_f."""
        normal, friction = np.zeros(out.shape[0]), np.zeros(out.shape[0])
        self._assemble(x, x_prev, 0.0, normal, self._scratch, True, False, False)
        self._assemble(x, x_prev, 1.0, friction, self._scratch, True, False, False)
        friction -= normal                                                  # at mu_f = 1
        for j, n in enumerate(names):
            if n == "contact_stiffness":
                out[:, j] += (normal + self.mu_f * friction) / self.k_n
            elif n == "friction":
                out[:, j] += friction
