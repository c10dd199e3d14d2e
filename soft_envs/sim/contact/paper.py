r"""Ground contact with lagged friction (paper II-C): the :class:`GroundContact` energy term,
the contact law ``model = "paper"``.

The ground is the plane ``y = 0``. Per contact node ``i`` (the boundary nodes that are not
fixed), the paper's law:

.. math::
    E_i^{contact} = Q_n(-y_i) + \mu_f N_{k-1,i}\,\big((x_i - x_{k-1,i})^2 + (z_i - z_{k-1,i})^2\big),
    \qquad N_{k-1,i} = Q_n'(-y_{k-1,i})

(the contact energy of paper II-C): a one-sided quadratic penalty of stiffness ``k_n`` [N/m]
against penetration, and a friction energy that resists tangential motion in proportion to the
normal force of the previous step. ``mu_f`` [1/m] is the paper's tunable roughness weight: the
tangential force is ``2 mu_f N dx_t``, so a node sliding ``1/(2 mu_f)`` metres in one step
feels a tangential force equal to its normal force. The previous state enters twice: through
the displacement and through ``N_{k-1}`` (both in the sensitivities).

It reads the ``[contact]`` keys ``stiffness``, ``blend`` and ``friction``; its friction
parameter is ``friction`` (mu_f).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .law import BLEND, STIFFNESS, ContactLaw, ContactParameter
from .penalty import d2Q, dQ, normal_forces, normal_penalty

__all__ = ["GroundContact", "FRICTION_WEIGHT", "contact_assemble", "friction_cross", "friction_cross_T",
           "normal_forces"]

#: the paper's friction weight mu_f
FRICTION_WEIGHT = ContactParameter("friction", 500.0, "1/m", "friction weight mu_f of the paper's law",
                                   inclusive=True)


@njit(cache=True)
def contact_assemble(x, x_prev, nodes, k_n, eps_n, mu_f, grad, hdata, diag_map, want_grad=True,
                     want_hess=True):
    """The contact energy of paper II-C; adds its gradient (``want_grad``) and its (diagonal)
    Hessian (``want_hess``; ``diag_map (c, 3)`` gives the Hessian slots of the x, y, z diagonal
    entries of each contact node). Returns the energy."""
    total = 0.0
    for c in range(nodes.shape[0]):
        n = nodes[c]
        total += normal_penalty(x, n, k_n, eps_n, grad, hdata, diag_map[c, 1], want_grad, want_hess)
        N = dQ(-x_prev[n, 1], k_n, eps_n)
        if N > 0.0:
            dx = x[n, 0] - x_prev[n, 0]
            dz = x[n, 2] - x_prev[n, 2]
            total += mu_f * N * (dx * dx + dz * dz)
            if want_grad:
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


class GroundContact(ContactLaw):
    """Penalty contact with the ground plane and the paper's lagged friction (module docstring)
    at every boundary node that is not fixed. Parameters from ``robot.contact``:
    ``stiffness`` k_n [N/m], ``blend`` eps_n [m], ``friction`` mu_f [1/m]."""

    model = "paper"
    contact_parameters = (STIFFNESS, BLEND, FRICTION_WEIGHT)
    friction_parameter = "friction"
    #: the paper's physics: one implicit-Euler step of 0.033 s per control step. Its friction
    #: force is proportional to the step (``2 mu_f N v h``), so the law is defined at its step
    #: and Table I is made with it (``-v0``)
    default_substeps = 1

    def __init__(self, robot):
        super().__init__(robot)
        self.mu_f = robot.contact.friction

    def bind(self, slots, diag_slots) -> None:
        super().bind(slots, diag_slots)
        self.diag_map = np.ascontiguousarray(diag_slots.reshape(-1, 3)[self.nodes])

    def energy(self, x, x_prev, u, hist=None) -> float:
        return contact_assemble(x, x_prev, self.nodes, self.k_n, self.eps_n, self.mu_f, self._scratch,
                                self._scratch, self.diag_map, False, False)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return contact_assemble(x, x_prev, self.nodes, self.k_n, self.eps_n, self.mu_f, grad, hdata,
                                self.diag_map, True, want_hess)

    def add_prev_product(self, x, x_prev, u, hist, S, out) -> None:
        friction_cross(x, x_prev, self.nodes, self.k_n, self.eps_n, self.mu_f, S, out)

    def add_prev_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        friction_cross_T(x, x_prev, self.nodes, self.k_n, self.eps_n, self.mu_f, lam, out)

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        """Q_n' is linear in k_n, so ``N = k_n Q_1'``: the normal force ``-N(y)`` gives
        ``-N / k_n`` and the friction force ``2 mu_f N_{k-1} dx_t`` gives ``2 mu_f N_{k-1} dx_t
        / k_n`` (the lagged N_{k-1} scales with k_n too); ``d/d mu_f = 2 N_{k-1} dx_t``."""
        nodes = self.nodes
        N = self.normal_forces(x)
        N_prev = self.normal_forces(x_prev)
        dt = x[nodes][:, [0, 2]] - x_prev[nodes][:, [0, 2]]
        friction = 2.0 * N_prev[:, None] * dt                  # d grad_t / d mu_f
        for j, n in enumerate(names):
            if n == "contact_stiffness":
                out[3 * nodes + 1, j] -= N / self.k_n
                out[3 * nodes, j] += self.mu_f * friction[:, 0] / self.k_n
                out[3 * nodes + 2, j] += self.mu_f * friction[:, 1] / self.k_n
            elif n == "friction":
                out[3 * nodes, j] += friction[:, 0]
                out[3 * nodes + 2, j] += friction[:, 1]
