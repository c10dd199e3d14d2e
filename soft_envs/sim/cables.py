r"""Cables: polylines through points bound to the mesh by barycentric coordinates (paper II-B,
eqs. 2-3), and the two cable energy terms: :class:`Cables` (length control) and
:class:`CableTensions` (tension control, paper appendix A).

A cable point ``p_s = sum_a w_{s,a} x_{n(s,a)}`` follows the tet it was bound to at rest. The
cable length is ``L(x) = sum_s |p_{s+1} - p_s|`` and its deformation (eq. 2, 3)

.. math::
    \Gamma(u, x) = L(x) - \alpha(u), \qquad \alpha(u) = \alpha^0 - u ,

with ``u`` the contracted length pulled in by the motor. The cable is a unilateral spring with
energy ``Q(Gamma)``, the one-sided quadratic :func:`~.contact.penalty.Q` (also the contact
laws'; ``Q``, ``dQ``, ``d2Q`` and ``one_sided_quadratic`` are re-exported here). In
tension-control mode (paper appendix A) the energy is ``tau * L(x)`` with ``tau >= 0`` the
prescribed tension.

Tendons are stored flat for the numba kernels: ``pt_nodes (P, 4)`` and ``pt_w (P, 4)`` for all
points of all tendons, ``ptr (T+1)`` the first point of each tendon. A tendon with ``P_t``
points couples ``4 P_t`` nodes, i.e. a dense ``12 P_t`` square block of the Hessian.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .contact.penalty import Q, d2Q, dQ, one_sided_quadratic
from .terms import EnergyTerm, readonly

__all__ = ["one_sided_quadratic", "Q", "dQ", "d2Q", "cable_lengths", "cable_length_gradients",
           "cable_energy", "cable_assemble", "LENGTH_CONTROL", "TENSION_CONTROL",
           "tendon_motor_matrix", "Cables", "CableTensions"]

LENGTH_CONTROL = 0
TENSION_CONTROL = 1


@njit(cache=True)
def _point(x, nodes, w, out):
    for i in range(3):
        out[i] = (w[0] * x[nodes[0], i] + w[1] * x[nodes[1], i]
                  + w[2] * x[nodes[2], i] + w[3] * x[nodes[3], i])


@njit(cache=True)
def _tendon_length_grad(x, pt_nodes, pt_w, p0, p1, dLp, want_grad):
    """Length of one tendon (points p0..p1-1); its gradient w.r.t. the points into dLp (P, 3)."""
    P = p1 - p0
    a = np.empty(3)
    b = np.empty(3)
    L = 0.0
    if want_grad:
        dLp[:P] = 0.0
    for s in range(P - 1):
        _point(x, pt_nodes[p0 + s], pt_w[p0 + s], a)
        _point(x, pt_nodes[p0 + s + 1], pt_w[p0 + s + 1], b)
        l = math.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2)
        L += l
        if want_grad and l > 1e-14:
            for i in range(3):
                e = (b[i] - a[i]) / l
                dLp[s + 1, i] += e
                dLp[s, i] -= e
    return L


@njit(cache=True)
def cable_lengths(x, pt_nodes, pt_w, ptr):
    """Current length L(x) of every tendon."""
    T = ptr.shape[0] - 1
    out = np.empty(T)
    dummy = np.empty((1, 3))
    for t in range(T):
        out[t] = _tendon_length_grad(x, pt_nodes, pt_w, ptr[t], ptr[t + 1], dummy, False)
    return out


@njit(cache=True)
def cable_length_gradients(x, pt_nodes, pt_w, ptr, n_dof):
    """Dense ``(T, 3n)`` matrix of dL_t/dx (tendons touch few nodes; T is small)."""
    T = ptr.shape[0] - 1
    out = np.zeros((T, n_dof))
    Pmax = 0
    for t in range(T):
        Pmax = max(Pmax, ptr[t + 1] - ptr[t])
    dLp = np.zeros((Pmax, 3))
    for t in range(T):
        _tendon_length_grad(x, pt_nodes, pt_w, ptr[t], ptr[t + 1], dLp, True)
        for s in range(ptr[t + 1] - ptr[t]):
            for a in range(4):
                n = pt_nodes[ptr[t] + s, a]
                w = pt_w[ptr[t] + s, a]
                for i in range(3):
                    out[t, 3 * n + i] += w * dLp[s, i]
    return out


@njit(cache=True)
def cable_energy(x, pt_nodes, pt_w, ptr, rest, k, eps, mode, tension):
    """Total cable energy: ``sum_t Q(L_t - rest_t)`` (length control) or ``sum_t tau_t L_t``."""
    L = cable_lengths(x, pt_nodes, pt_w, ptr)
    total = 0.0
    for t in range(L.shape[0]):
        if mode == LENGTH_CONTROL:
            total += Q(L[t] - rest[t], k[t], eps)
        else:
            total += tension[t] * L[t]
    return total


@njit(cache=True)
def cable_assemble(x, pt_nodes, pt_w, ptr, rest, k, eps, mode, tension, grad, hdata, hmap, hptr,
                   want_hess=True):
    """Add cable gradients into ``grad`` and Hessian blocks into ``hdata`` (via ``hmap``; tendon
    t's (12 P_t)^2 entries start at ``hptr[t]``, row-major). Returns the energy.

    Length control: grad = Q'(Gamma) dL, H = Q''(Gamma) dL dL^T + Q'(Gamma) d2L.
    Tension control: grad = tau dL, H = tau d2L."""
    T = ptr.shape[0] - 1
    total = 0.0
    for t in range(T):
        p0 = ptr[t]
        P = ptr[t + 1] - p0
        dLp = np.zeros((P, 3))
        L = _tendon_length_grad(x, pt_nodes, pt_w, p0, p0 + P, dLp, True)
        if mode == LENGTH_CONTROL:
            gam = L - rest[t]
            total += Q(gam, k[t], eps)
            c1 = dQ(gam, k[t], eps)
            c2 = d2Q(gam, k[t], eps)
        else:
            total += tension[t] * L
            c1 = tension[t]
            c2 = 0.0
        if c1 == 0.0 and c2 == 0.0:
            continue  # slack cable: no force, no stiffness
        n_loc = 12 * P
        dLx = np.empty(n_loc)
        for s in range(P):
            for a in range(4):
                w = pt_w[p0 + s, a]
                for i in range(3):
                    dLx[12 * s + 3 * a + i] = w * dLp[s, i]
                    grad[3 * pt_nodes[p0 + s, a] + i] += c1 * w * dLp[s, i]
        if not want_hess:
            continue
        # d2L with respect to the points: segment blocks (I - e e^T) / l
        Hp = np.zeros((3 * P, 3 * P))
        if c1 != 0.0:
            a_ = np.empty(3)
            b_ = np.empty(3)
            for s in range(P - 1):
                _point(x, pt_nodes[p0 + s], pt_w[p0 + s], a_)
                _point(x, pt_nodes[p0 + s + 1], pt_w[p0 + s + 1], b_)
                d = b_ - a_
                l = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                if l <= 1e-14:
                    continue
                for i in range(3):
                    for j in range(3):
                        h = ((1.0 if i == j else 0.0) - d[i] * d[j] / (l * l)) / l
                        Hp[3 * s + i, 3 * s + j] += h
                        Hp[3 * s + 3 + i, 3 * s + 3 + j] += h
                        Hp[3 * s + i, 3 * s + 3 + j] -= h
                        Hp[3 * s + 3 + i, 3 * s + j] -= h
        base = hptr[t]
        trash = hdata.shape[0] - 1          # upper-triangle and fixed-dof entries: not stored
        for s in range(P):
            for a in range(4):
                wa = pt_w[p0 + s, a]
                for i in range(3):
                    r = 12 * s + 3 * a + i
                    for s2 in range(P):
                        near = s2 >= s - 1 and s2 <= s + 1
                        for b in range(4):
                            wb = pt_w[p0 + s2, b]
                            for j in range(3):
                                c = 12 * s2 + 3 * b + j
                                slot = hmap[base + r * n_loc + c]
                                if slot == trash:
                                    continue
                                h = c2 * dLx[r] * dLx[c]
                                if near:
                                    h += c1 * wa * wb * Hp[3 * s + i, 3 * s2 + j]
                                hdata[slot] += h
    return total


# ---------------------------------------------------------------------- energy terms
def tendon_motor_matrix(tendon_motor: np.ndarray, n_motors: int) -> np.ndarray:
    """The motor-to-tendon map as a (T, n_motors) 0/1 matrix: a motor drives all its tendons
    (a tendon pair) with the same control; passive tendons (``tendon_motor == -1``) get none.
    Per-tendon values of per-motor ones are ``A @ u``."""
    tm = np.asarray(tendon_motor, dtype=np.int64)
    A = np.zeros((len(tm), n_motors))
    has = tm >= 0
    A[np.flatnonzero(has), tm[has]] = 1.0
    A.setflags(write=False)
    return A


class Cables(EnergyTerm):
    r"""Cables in length control (paper eqs. 2-3): ``E = sum_t Q(Gamma_t)`` with the deformation
    ``Gamma_t = L_t(x) - alpha_t(u)`` and the rest length ``alpha_t = alpha0_t - u_m(t)``, ``u``
    the contraction [m] of the motor driving tendon t. ``d(dE/dx)/du = Q''(Gamma) dL/dx`` per
    tendon, summed per motor. Q' is linear in the stiffness, and the parameter
    ``cable_stiffness`` (the mean k over the tendons, all scaled alike) gives
    ``d(dE/dx)/dk = sum_t Q'(Gamma_t) / k dL_t/dx``."""

    name = "cables"
    mode = LENGTH_CONTROL
    parameters = ("cable_stiffness",)

    def __init__(self, robot):
        cab = robot.cable_data
        self.pt_nodes, self.pt_w, self.ptr = cab.pt_nodes, cab.pt_w, cab.ptr
        self.alpha0, self.stiffness, self.blend = cab.rest_length, cab.stiffness, robot.cable_blend
        self.tendon_motor = cab.tendon_motor
        self.motor_matrix = tendon_motor_matrix(cab.tendon_motor, robot.n_motors)   # (T, M)
        self.n_dof = 3 * robot.mesh.n_nodes
        self._zeros = np.zeros(len(self.alpha0))

    @property
    def n_tendons(self) -> int:
        return len(self.alpha0)

    # ------------------------------------------------------------------ controls (eq. 3)
    def rest_lengths(self, u: np.ndarray) -> np.ndarray:
        """alpha(u) = alpha0 - u per tendon (eq. 3)."""
        return self.alpha0 - self.motor_matrix @ u

    def _tensions(self, u: np.ndarray) -> np.ndarray:
        return self._zeros

    def deformation(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Gamma = L(x) - alpha(u) per tendon (eq. 2): > 0 stretched, < 0 slack [m]."""
        return self.lengths(x) - self.rest_lengths(u)

    def deformation_jacobian(self, dL: np.ndarray, S: np.ndarray, U: np.ndarray) -> np.ndarray:
        """dGamma/dz = dL/dx S + dGamma/du U (T, nz), for ``S = dx/dz`` and ``U = du/dz``."""
        return dL @ S + self.motor_matrix @ U

    def tension(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Q'(Gamma) per tendon [N]."""
        return one_sided_quadratic(self.deformation(x, u), self.stiffness, self.blend)[1]

    # ------------------------------------------------------------------ geometry
    def lengths(self, x: np.ndarray) -> np.ndarray:
        return cable_lengths(readonly(x), self.pt_nodes, self.pt_w, self.ptr)

    def length_gradients(self, x: np.ndarray) -> np.ndarray:
        """Dense (T, 3n) dL/dx."""
        return cable_length_gradients(readonly(x), self.pt_nodes, self.pt_w, self.ptr, self.n_dof)

    # ------------------------------------------------------------------ energy term
    def hessian_blocks(self) -> list[np.ndarray]:
        blocks = []
        for t in range(self.n_tendons):
            nodes = self.pt_nodes[self.ptr[t]:self.ptr[t + 1]].ravel()
            blocks.append((3 * nodes[:, None] + np.arange(3)).reshape(1, -1))
        return blocks

    def bind(self, slots, diag_slots) -> None:
        super().bind(slots, diag_slots)
        sizes = [s.size for s in slots]
        self.hptr = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.hmap = (np.ascontiguousarray(np.concatenate([s.ravel() for s in slots]))
                     if slots else np.zeros(0, dtype=np.int64))

    def energy(self, x, x_prev, u, hist=None) -> float:
        return cable_energy(x, self.pt_nodes, self.pt_w, self.ptr, self.rest_lengths(u), self.stiffness,
                            self.blend, self.mode, self._tensions(u))

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return cable_assemble(x, self.pt_nodes, self.pt_w, self.ptr, self.rest_lengths(u), self.stiffness,
                              self.blend, self.mode, self._tensions(u), grad, hdata, self.hmap, self.hptr,
                              want_hess)

    def _control_stiffness(self, x, u) -> np.ndarray:
        """d(tension)/du per tendon: Q''(Gamma)."""
        return one_sided_quadratic(self.deformation(x, u), self.stiffness, self.blend)[2]

    def add_control_jacobian(self, x, x_prev, u, hist, G) -> None:
        c = self._control_stiffness(x, u)
        G += self.length_gradients(x).T @ (c[:, None] * self.motor_matrix)

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        for j, n in enumerate(names):
            if n in self.parameters and self.n_tendons:
                out[:, j] += self.length_gradients(x).T @ (self.tension(x, u) / self.stiffness.mean())


class CableTensions(Cables):
    r"""Cables in tension control (paper appendix A): ``E = sum_t tau_t L_t(x)`` with the
    tension ``tau_t = u_m(t) >= 0`` [N] of the motor driving tendon t; the rest lengths stay
    alpha0 (Gamma = L - alpha0 is still reported). ``d(dE/dx)/du = dL/dx`` per tendon."""

    mode = TENSION_CONTROL
    parameters = ()           # E = tau L: the stiffness plays no part

    def rest_lengths(self, u: np.ndarray) -> np.ndarray:
        return self.alpha0

    def _tensions(self, u: np.ndarray) -> np.ndarray:
        return self.motor_matrix @ u

    def deformation_jacobian(self, dL, S, U) -> np.ndarray:
        return dL @ S

    def tension(self, x, u) -> np.ndarray:
        return self._tensions(u)

    def _control_stiffness(self, x, u) -> np.ndarray:
        return np.ones(self.n_tendons)
