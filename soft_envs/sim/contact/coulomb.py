r"""Ground contact with Coulomb friction held by stick anchors: the :class:`CoulombContact` term,
the contact law ``model = "coulomb"``.

The ground is the plane ``y = 0``. Every contact node ``i`` (a boundary node that is not fixed)
has a *stick anchor* ``p_i``, a point of the ground (x, z) that the node is tied to by a stiff
tangential bristle while it sticks. With the tangential offset ``d_i = P_t x_i - p_i``, its
length ``r_i = |d_i|`` and the normal force of the previous step ``N_i = Q_n'(-y_{k-1,i})``:

.. math::
    E_i = Q_n(-y_i) + \mu N_i G(r_i), \qquad
    G(r) = \begin{cases} r_s (\rho^2 - \rho^3/3) & \rho = r/r_s < 1 \\
                         r - r_s / 3 & \text{otherwise.} \end{cases}

The tangential force ``mu N G'(r) d / r`` with ``G'(r) = 2 rho - rho^2`` grows from 0 and is
bounded by ``mu N`` (Coulomb's law), reached at the slip distance ``r_s`` (``slip_distance``
[m]). After each step the anchors are updated (:meth:`CoulombContact.next_history`): a node
whose friction was inactive during the step (``N_i = 0``) is re-anchored where it is; a node
with ``r_i <= r_s`` sticks (its anchor stays); a node beyond it slides and drags its anchor to
``r_s`` behind it. So a node under a tangential load below ``mu N`` deflects by at most ``r_s``
and then holds: sticking really sticks, with no creep, and nothing depends on the time step.
Sliding at any speed feels ``mu N`` against the slip direction. This is the "lagged stick
anchor" form of Coulomb friction (a bristle or Dahl model; IPC's lagged smoothed friction is
the same potential anchored at ``x_{k-1}`` instead, which creeps at ``eps_v tan(a) / (2 mu)``
on a slope unless ``eps_v`` is so small that Newton struggles, which was measured here).

``G`` is C2 (``G''`` is continuous at ``rho = 1``) and the friction Hessian ``mu N [w I +
(w'/r) d d^T]`` with ``w = G'(r) / r`` is positive semi-definite. The previous state enters
through ``N`` and the anchors (both in the sensitivities); the anchor update is differentiable
except where a node changes between sticking and sliding.

The normal law ``Q_n`` is the one-sided quadratic of :func:`.penalty.Q` with stiffness ``k_n``
and blend ``eps_n``; ``eps_n = 0`` is the half-quadratic ``k_n max(s, 0)^2 / 2``.

It reads the ``[contact]`` keys ``stiffness``, ``blend`` (0 allowed), ``friction_coefficient``
and ``slip_distance``; its friction parameter is ``friction_coefficient`` (mu).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

from .law import BLEND, STIFFNESS, ContactLaw, ContactParameter
from .penalty import d2Q, dQ, normal_penalty

__all__ = ["CoulombContact", "FRICTION_COEFFICIENT", "SLIP_DISTANCE", "bristle_potential", "coulomb_assemble"]

#: Coulomb's friction coefficient mu
FRICTION_COEFFICIENT = ContactParameter("friction_coefficient", 0.8, "", "Coulomb friction coefficient mu",
                                        inclusive=True)
#: the offset r_s from its stick anchor at which a node slides
SLIP_DISTANCE = ContactParameter("slip_distance", 3e-4, "m", "slip distance r_s of the stick anchors")
#: the Coulomb law allows ``blend = 0``: the half-quadratic normal law
HALF_QUADRATIC_BLEND = dataclasses.replace(BLEND, inclusive=True, note="0: the half-quadratic")


@njit(cache=True, inline="always")
def bristle_potential(r, rs):
    """``(G(r), w = G'(r) / r, c = w'(r) / r)`` (module docstring); at r = 0, c is 0 (its
    product with d d^T vanishes there)."""
    if r < rs:
        rho = r / rs
        c = -1.0 / (rs * rs * r) if r > 0.0 else 0.0
        return rs * rho * rho * (1.0 - rho / 3.0), (2.0 - rho) / rs, c
    return r - rs / 3.0, 1.0 / r, -1.0 / (r * r * r)


@njit(cache=True, inline="always")
def _friction(x, x_prev, anchors, n, c, k_n, eps_n, mu, rs):
    """``(a = mu N, dN/dy_prev, dx, dz, G, w, c)`` of contact node n (a = 0: no friction)."""
    sp = -x_prev[n, 1]
    N = dQ(sp, k_n, eps_n)
    dx = x[n, 0] - anchors[c, 0]
    dz = x[n, 2] - anchors[c, 1]
    if N <= 0.0:
        return 0.0, 0.0, dx, dz, 0.0, 0.0, 0.0
    G, w, cw = bristle_potential(np.sqrt(dx * dx + dz * dz), rs)
    return mu * N, -d2Q(sp, k_n, eps_n), dx, dz, G, w, cw


@njit(cache=True)
def coulomb_assemble(x, x_prev, anchors, nodes, k_n, eps_n, mu, rs, grad, hdata, slots, want_grad=True,
                     want_hess=True):
    """Energy of the term (module docstring); adds its gradient (``want_grad``) and Hessian
    (``want_hess``; ``slots (c, 9)`` are the Hessian slots of each contact node's 3x3 block,
    row-major). Returns the energy."""
    total = 0.0
    for c in range(nodes.shape[0]):
        n = nodes[c]
        total += normal_penalty(x, n, k_n, eps_n, grad, hdata, slots[c, 4], want_grad, want_hess)
        a, _, dx, dz, G, w, cw = _friction(x, x_prev, anchors, n, c, k_n, eps_n, mu, rs)
        if a == 0.0:
            continue
        total += a * G
        if want_grad:
            grad[3 * n] += a * w * dx
            grad[3 * n + 2] += a * w * dz
        if want_hess:
            hdata[slots[c, 0]] += a * (w + cw * dx * dx)
            hdata[slots[c, 8]] += a * (w + cw * dz * dz)
            hdata[slots[c, 6]] += a * cw * dx * dz       # (z, x); (x, z) is its unstored mirror
    return total


@njit(cache=True)
def _prev_product(x, x_prev, anchors, nodes, k_n, eps_n, mu, rs, S, out):
    """``out += d(grad)/dx_prev @ S``: through N only, ``mu w d dN/dy_prev`` (the anchors
    replace x_prev in the offset)."""
    for c in range(nodes.shape[0]):
        n = nodes[c]
        a, dN, dx, dz, G, w, cw = _friction(x, x_prev, anchors, n, c, k_n, eps_n, mu, rs)
        if a == 0.0:
            continue
        for j in range(S.shape[1]):
            out[3 * n, j] += mu * w * dx * dN * S[3 * n + 1, j]
            out[3 * n + 2, j] += mu * w * dz * dN * S[3 * n + 1, j]


@njit(cache=True)
def _prev_product_T(x, x_prev, anchors, nodes, k_n, eps_n, mu, rs, lam, out):
    for c in range(nodes.shape[0]):
        n = nodes[c]
        a, dN, dx, dz, G, w, cw = _friction(x, x_prev, anchors, n, c, k_n, eps_n, mu, rs)
        if a != 0.0:
            out[3 * n + 1] += mu * w * dN * (dx * lam[3 * n] + dz * lam[3 * n + 2])


@njit(cache=True)
def _anchor_product(x, x_prev, anchors, nodes, k_n, eps_n, mu, rs, P, out, transpose):
    """``out (3n, nz) += d(grad)/dp @ P`` with ``P (2c, nz)`` (``d grad_t / dp = -H_t``, the
    tangential friction Hessian); ``transpose``: ``out (2c, nz) += (d(grad)/dp)^T @ P`` with
    ``P (3n, nz)``."""
    for c in range(nodes.shape[0]):
        n = nodes[c]
        a, dN, dx, dz, G, w, cw = _friction(x, x_prev, anchors, n, c, k_n, eps_n, mu, rs)
        if a == 0.0:
            continue
        hxx, hzz, hxz = a * (w + cw * dx * dx), a * (w + cw * dz * dz), a * cw * dx * dz
        for j in range(P.shape[1]):
            if transpose:
                px, pz = P[3 * n, j], P[3 * n + 2, j]
                out[2 * c, j] -= hxx * px + hxz * pz
                out[2 * c + 1, j] -= hxz * px + hzz * pz
            else:
                px, pz = P[2 * c, j], P[2 * c + 1, j]
                out[3 * n, j] -= hxx * px + hxz * pz
                out[3 * n + 2, j] -= hxz * px + hzz * pz


@njit(cache=True)
def _friction_forces(x, x_prev, anchors, nodes, k_n, eps_n, mu, rs, out):
    """``out (c, 2)``: the tangential friction force ``mu N_{k-1} w d`` (x, z) of every contact
    node (its share of the gradient)."""
    for c in range(nodes.shape[0]):
        a, dN, dx, dz, G, w, cw = _friction(x, x_prev, anchors, nodes[c], c, k_n, eps_n, mu, rs)
        out[c, 0] = a * w * dx
        out[c, 1] = a * w * dz


@njit(cache=True)
def _next_anchors(x, x_prev, anchors, nodes, k_n, eps_n, rs, out):
    """The anchor update of the module docstring."""
    for c in range(nodes.shape[0]):
        n = nodes[c]
        tx, tz = x[n, 0], x[n, 2]
        if dQ(-x_prev[n, 1], k_n, eps_n) <= 0.0:
            out[c, 0], out[c, 1] = tx, tz
            continue
        dx, dz = tx - anchors[c, 0], tz - anchors[c, 1]
        r = np.sqrt(dx * dx + dz * dz)
        if r <= rs:
            out[c, 0], out[c, 1] = anchors[c, 0], anchors[c, 1]
        else:
            out[c, 0], out[c, 1] = tx - rs * dx / r, tz - rs * dz / r


@njit(cache=True)
def _anchor_tangent(x, x_prev, anchors, nodes, k_n, eps_n, rs, Sx, P, out, transpose):
    """Derivative of the anchor update: re-anchored ``dp' = dt``; sticking ``dp' = dp``;
    sliding ``dp' = (I - M) dt + M dp`` with ``M = (r_s / r)(I - n n^T)``, ``dt`` the node's
    tangential motion. Forward: ``out (2c, nz) = dp'/dz`` from ``Sx (3n, nz)`` and
    ``P (2c, nz)``. ``transpose``: ``Sx (3n, nz) += (dp'/dx)^T P`` and ``out (2c, nz) +=
    (dp'/dp)^T P`` for ``P`` the adjoint of p' (2c, nz)."""
    for c in range(nodes.shape[0]):
        n = nodes[c]
        active = dQ(-x_prev[n, 1], k_n, eps_n) > 0.0
        dx, dz = x[n, 0] - anchors[c, 0], x[n, 2] - anchors[c, 1]
        r = np.sqrt(dx * dx + dz * dz)
        if not active:                     # p' = t(x)
            mxx, mzz, mxz = 0.0, 0.0, 0.0
        elif r <= rs:                      # p' = p
            mxx, mzz, mxz = 1.0, 1.0, 0.0
        else:
            f = rs / r
            ex, ez = dx / r, dz / r
            mxx, mzz, mxz = f * (1.0 - ex * ex), f * (1.0 - ez * ez), -f * ex * ez
        for j in range(P.shape[1]):
            if transpose:
                qx, qz = P[2 * c, j], P[2 * c + 1, j]
                Sx[3 * n, j] += (1.0 - mxx) * qx - mxz * qz
                Sx[3 * n + 2, j] += -mxz * qx + (1.0 - mzz) * qz
                out[2 * c, j] += mxx * qx + mxz * qz
                out[2 * c + 1, j] += mxz * qx + mzz * qz
            else:
                sx, sz = Sx[3 * n, j], Sx[3 * n + 2, j]
                px, pz = P[2 * c, j], P[2 * c + 1, j]
                out[2 * c, j] = (1.0 - mxx) * sx - mxz * sz + mxx * px + mxz * pz
                out[2 * c + 1, j] = -mxz * sx + (1.0 - mzz) * sz + mxz * px + mzz * pz


class CoulombContact(ContactLaw):
    """Penalty contact with the ground plane and Coulomb friction held by stick anchors (module
    docstring) at every boundary node that is not fixed. Parameters from ``robot.contact``:
    ``stiffness`` k_n [N/m], ``blend`` eps_n [m] (0: half-quadratic),
    ``friction_coefficient`` mu, ``slip_distance`` r_s [m]. The history is the anchors,
    an array (c, 2) of ground points (x, z), one per contact node."""

    model = "coulomb"
    has_history = True
    contact_parameters = (STIFFNESS, HALF_QUADRATIC_BLEND, FRICTION_COEFFICIENT, SLIP_DISTANCE)
    friction_parameter = "friction_coefficient"
    #: 4 physics steps of 8.25 ms per 0.033 s control step: the fast gaits' speeds converge
    #: there (within 3 % of 4x finer steps; at 33 ms they were up to 25 % off: docs/fidelity.md)
    default_substeps = 4

    def __init__(self, robot):
        super().__init__(robot)
        c = robot.contact
        self.mu, self.rs = c.friction_coefficient, c.slip_distance

    def hessian_blocks(self) -> list[np.ndarray]:
        return [3 * self.nodes[:, None] + np.arange(3)]

    def bind(self, slots, diag_slots) -> None:
        super().bind(slots, diag_slots)
        self.slots = np.ascontiguousarray(slots[0])                 # (c, 9)

    def _args(self, x, x_prev, hist):
        return x, x_prev, hist, self.nodes, self.k_n, self.eps_n, self.mu, self.rs

    def energy(self, x, x_prev, u, hist=None) -> float:
        return coulomb_assemble(*self._args(x, x_prev, hist), self._scratch, self._scratch, self.slots,
                                False, False)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return coulomb_assemble(*self._args(x, x_prev, hist), grad, hdata, self.slots, True, want_hess)

    def add_prev_product(self, x, x_prev, u, hist, S, out) -> None:
        _prev_product(*self._args(x, x_prev, hist), S, out)

    def add_prev_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        _prev_product_T(*self._args(x, x_prev, hist), lam, out)

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        """The normal force ``-N(y)`` and the friction force ``mu N_{k-1} w d`` are linear in
        k_n (through N and the lagged N_{k-1}) and the friction force is linear in mu. The
        anchor update depends on the parameters only through the sign of N_{k-1}: no
        :meth:`history_parameter_jacobian`."""
        nodes = self.nodes
        f1 = np.empty((len(nodes), 2))                  # N_{k-1} w d: the friction force at mu = 1
        _friction_forces(x, x_prev, hist, nodes, self.k_n, self.eps_n, 1.0, self.rs, f1)
        for j, n in enumerate(names):
            if n == "contact_stiffness":
                out[3 * nodes + 1, j] -= self.normal_forces(x) / self.k_n
                out[3 * nodes, j] += self.mu * f1[:, 0] / self.k_n
                out[3 * nodes + 2, j] += self.mu * f1[:, 1] / self.k_n
            elif n == "friction_coefficient":
                out[3 * nodes, j] += f1[:, 0]
                out[3 * nodes + 2, j] += f1[:, 1]

    # ------------------------------------------------------------------ anchors
    def initial_history(self, x0) -> np.ndarray:
        """Every node anchored where it is."""
        return np.ascontiguousarray(x0[self.nodes][:, [0, 2]])

    def next_history(self, x, x_prev, hist) -> np.ndarray:
        out = np.empty_like(hist)
        _next_anchors(x, x_prev, hist, self.nodes, self.k_n, self.eps_n, self.rs, out)
        return out

    def add_history_product(self, x, x_prev, u, hist, P, out) -> None:
        _anchor_product(*self._args(x, x_prev, hist), P, out, False)

    def add_history_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        tmp = np.zeros((out.shape[0], 1))
        _anchor_product(*self._args(x, x_prev, hist), lam.reshape(-1, 1), tmp, True)
        out += tmp[:, 0]

    def history_tangent(self, x, x_prev, hist, S, P) -> np.ndarray:
        out = np.empty_like(P)
        _anchor_tangent(x, x_prev, hist, self.nodes, self.k_n, self.eps_n, self.rs, S, P, out, False)
        return out

    def history_tangent_T(self, x, x_prev, hist, m, out_x, out_h) -> None:
        sx = np.zeros((len(out_x), 1))
        oh = np.zeros((len(out_h), 1))
        _anchor_tangent(x, x_prev, hist, self.nodes, self.k_n, self.eps_n, self.rs, sx, m.reshape(-1, 1), oh,
                        True)
        out_x += sx[:, 0]
        out_h += oh[:, 0]
