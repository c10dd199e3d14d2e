r"""Tendon routing as design parameters: the rest positions of the tendons' via points.

Embedding. A cable point with rest position ``q`` lies in tet ``e`` with barycentric
coordinates ``w_a(q)``, affine in ``q`` inside the tet with ``dw_a/dq = N_a`` (the tet's
shape-function gradients, :func:`~soft_envs.sim.mesh.shape_gradients`). Its position in a
deformed state x is ``p = sum_a w_a x_a`` (paper eq. 2), so

.. math::
    \frac{\partial p}{\partial q} = \sum_a x_a \otimes N_a = F_e(x),

the tet's deformation gradient (:func:`embedding_jacobian`; the identity at rest). Across a
face the tet changes and the derivative jumps (the embedding is piecewise affine): a point on a
face has one-sided derivatives only.

Cable force. In length control the cable term's gradient is ``g = Q'(Gamma) dL/dx`` with
``Gamma = L(x) - alpha0 + u`` and ``dL/dx`` at node ``n_{s,a}`` equal to ``sum_s w_{s,a}
dL/dp_s``. Moving point r's rest position q_r changes (i) the weights of point r, (ii) the
point's position ``p_r`` (through ``F_r``), hence ``dL/dp`` of it and its neighbours (the
segment Hessians ``d2L/dp_s dp_r``), (iii) ``Gamma`` through ``L`` and through the assembly
length ``alpha0`` = the rest polyline's length (``d alpha0/dq_r = t_{r-1} - t_r`` with the unit
rest segment directions; an explicit ``rest_length`` keeps its offset from the rest polyline,
so its derivative is the same):

.. math::
    \frac{\partial g}{\partial q_r} = Q''(\Gamma)\, \frac{dL}{dx}
        \Big(F_r^T \frac{\partial L}{\partial p_r} - \frac{\partial \alpha_0}{\partial q_r}\Big)^T
      + Q'(\Gamma) \Big[\sum_a e_{n_{r,a}} \frac{\partial L}{\partial p_r} N_{r,a}^T
      + \sum_{s=r-1}^{r+1} \sum_a w_{s,a} e_{n_{s,a}} \frac{\partial^2 L}{\partial p_s \partial p_r} F_r\Big].

In tension control ``Q'`` is the tension ``u`` and the first term vanishes.

Cable deformation. At fixed x the same two paths move ``Gamma_t`` itself: ``dGamma_t/dq_r =
F_r^T dL/dp_r - d alpha0/dq_r`` (:func:`deformation_point_gradients`), the design's part of the
tensions' sensitivities (``dGamma/dtheta``, the motors' torque-speed rows of co-design).

Relations kept (not free): a routed tendon follows an earlier one (its points are an affine
image ``q' = R q + c`` of the leader's, so its columns add ``dg/dq' R``) when its rest points are

* the mirror image of the earlier tendon's in the body's mid-plane (normal to the lateral axis,
  forward x up): bilateral symmetry, e.g. the Puppy's left and right motors;
* a translate of the earlier tendon's and both hang on the same motor: a tendon pair keeps its
  spacing (the Puppy's ``_a`` and ``_b``; on the Tripod the pair is also a mirror pair).

Maps compose: the mirror of a pair's second tendon follows the first tendon's leader. The point
where a tendon leaves the body to its motor (the last point) is fixed by default: the motors do
not move.
"""
from __future__ import annotations

import copy
import dataclasses
from collections.abc import Sequence

import numpy as np

from ..cables import LENGTH_CONTROL, one_sided_quadratic
from .clearance import signed_distance

__all__ = ["embedding_jacobian", "tendon_points_jacobian", "cable_gradient_point_jacobian",
           "cable_rest_length_jacobian", "rest_length_gradient", "deformation_point_gradients", "TendonRouting"]

AXES = "xyz"


def embedding_jacobian(mesh, tet: int, x: np.ndarray) -> np.ndarray:
    """``dp/dq`` (3, 3) of a cable point bound in tet ``tet``: the tet's deformation gradient at x."""
    return x[mesh.tets[tet]].T @ mesh.dN[tet]


def rest_length_gradient(points: np.ndarray, r: int) -> np.ndarray:
    """``d/dq_r`` of the rest polyline's length ``sum_s |q_{s+1} - q_s|`` (3,)."""
    out = np.zeros(3)
    if r > 0:
        d = points[r] - points[r - 1]
        out += d / np.linalg.norm(d)
    if r + 1 < len(points):
        d = points[r + 1] - points[r]
        out -= d / np.linalg.norm(d)
    return out


def _polyline(p: np.ndarray):
    """Unit directions, lengths, dL/dp (P, 3) and the segment Hessians of a polyline."""
    d = np.diff(p, axis=0)
    lengths = np.linalg.norm(d, axis=1)
    e = d / lengths[:, None]
    dLp = np.zeros_like(p)
    dLp[1:] += e
    dLp[:-1] -= e
    h = (np.eye(3)[None] - e[:, :, None] * e[:, None, :]) / lengths[:, None, None]
    return lengths, dLp, h


def _d2L(h: np.ndarray, s: int, r: int) -> np.ndarray:
    """``d2L/dp_s dp_r`` (3, 3) from the segment Hessians ``h`` (P-1, 3, 3)."""
    out = np.zeros((3, 3))
    nseg = len(h)
    if s == r:
        if r > 0:
            out += h[r - 1]
        if r < nseg:
            out += h[r]
    elif s == r - 1:
        out -= h[s]
    elif s == r + 1:
        out -= h[r]
    return out


def _tendon_state(system, x, u, t):
    """Points, polyline data and ``(Q'(Gamma), Q''(Gamma))`` of tendon t at x (tension control:
    ``(tau, 0)``)."""
    cables = system.cables
    p0, p1 = cables.ptr[t], cables.ptr[t + 1]
    nodes, w = cables.pt_nodes[p0:p1], cables.pt_w[p0:p1]
    p = np.einsum("sa,sai->si", w, x[nodes])
    lengths, dLp, h = _polyline(p)
    if cables.mode == LENGTH_CONTROL:
        gam = lengths.sum() - cables.rest_lengths(u)[t]
        _, c1, c2 = one_sided_quadratic(gam, cables.stiffness[t], cables.blend)
        return nodes, w, p, dLp, h, float(c1), float(c2)
    return nodes, w, p, dLp, h, float(cables.tension(x, u)[t]), 0.0


def deformation_point_gradients(system, x: np.ndarray, t: int, rest_length: bool = True) -> np.ndarray:
    """``dGamma_t/dq_s`` (P, 3) at fixed x: tendon t's deformation against the rest position of
    each of its P points, ``F_s^T dL/dp_s - d alpha0/dq_s`` (module docstring; in tension control
    Gamma = L - alpha0 too). ``rest_length=False`` leaves out the assembly length's part."""
    cables = system.cables
    p0, p1 = cables.ptr[t], cables.ptr[t + 1]
    _, dLp, _ = _polyline(np.einsum("sa,sai->si", cables.pt_w[p0:p1], x[cables.pt_nodes[p0:p1]]))
    return _deformation_gradients(system, x, t, dLp, rest_length)


def _point_jacobians(system, x: np.ndarray, t: int) -> np.ndarray:
    """``dp_s/dq_s`` (P, 3, 3) of tendon t's points: their tets' deformation gradients at x."""
    mesh = system.robot.mesh
    tets = system.robot._binding[t][0]
    return np.einsum("sai,sak->sik", x[mesh.tets[tets]], mesh.dN[tets])


def _deformation_gradients(system, x: np.ndarray, t: int, dLp: np.ndarray, rest_length: bool,
                           F: np.ndarray | None = None) -> np.ndarray:
    """:func:`deformation_point_gradients` from the polyline's ``dL/dp`` (P, 3) (and the points'
    ``F``, :func:`_point_jacobians`, when at hand)."""
    F = _point_jacobians(system, x, t) if F is None else F
    out = np.einsum("rik,ri->rk", F, dLp)                                       # F_r^T dL/dp_r
    if rest_length:
        pts = np.asarray(system.robot.tendons[t].points)
        out -= np.array([rest_length_gradient(pts, r) for r in range(len(pts))])
    return out


def cable_rest_length_jacobian(system, x: np.ndarray, u: np.ndarray, t: int) -> np.ndarray:
    """``-d(dE_cables/dx)/d alpha0_t`` (3n,) = ``Q''(Gamma) dL_t/dx`` (zero in tension control)."""
    nodes, w, _, dLp, _, _, c2 = _tendon_state(system, x, u, t)
    out = np.zeros((system.n_nodes, 3))
    if c2:
        np.add.at(out, nodes.ravel(), c2 * (w[:, :, None] * dLp[:, None, :]).reshape(-1, 3))
    return out.ravel()


def tendon_points_jacobian(system, x: np.ndarray, u: np.ndarray, t: int,
                           rest_length: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(dofs (12 P,), J (12 P, 3 P))``: ``d(dE_cables/dx)/dq`` of tendon t's gradient at its
    nodes' dofs (repeated where points share a node: add them up) with respect to the rest
    positions of all its P points (module docstring), at fixed binding tets.
    ``rest_length=False`` leaves out the assembly length's part (the rest-shape derivatives,
    :mod:`.rest_shape`, add it for the whole polyline)."""
    mesh = system.robot.mesh
    nodes, w, p, dLp, h, c1, c2 = _tendon_state(system, x, u, t)
    tets = system.robot._binding[t][0]
    P = len(p)
    F = _point_jacobians(system, x, t)                                         # dp_s/dq_s per point
    J = np.zeros((P, 4, 3, P, 3))                                              # (s, a, i) x (r, k)
    if c2:
        dgam = _deformation_gradients(system, x, t, dLp, rest_length, F)       # dGamma/dq_r
        J += c2 * (w[:, :, None] * dLp[:, None, :])[:, :, :, None, None] * dgam[None, None, None]
    if c1:
        dN = mesh.dN[tets]                                                     # (P, 4, 3)
        for r in range(P):
            J[r, :, :, r, :] += c1 * dLp[r][None, :, None] * dN[r][:, None, :]
            for s in range(max(r - 1, 0), min(r + 2, P)):
                J[s, :, :, r, :] += c1 * w[s][:, None, None] * (_d2L(h, s, r) @ F[r])[None]
    dofs = (3 * nodes[:, :, None] + np.arange(3)).ravel()
    return dofs, J.reshape(12 * P, 3 * P)


def cable_gradient_point_jacobian(system, x: np.ndarray, u: np.ndarray, t: int, r: int,
                                  rest_length: bool = True) -> np.ndarray:
    """``d(dE_cables/dx)/dq_r`` (3n, 3): derivative of the cable term's gradient at x with
    respect to the rest position of point r of tendon t (:func:`tendon_points_jacobian`'s
    columns of that point, as a dense block)."""
    dofs, J = tendon_points_jacobian(system, x, u, t, rest_length)
    out = np.zeros((system.n_dof, 3))
    np.add.at(out, dofs, J[:, 3 * r:3 * r + 3])
    return out


class TendonRouting:
    """Rest positions of via points as design parameters (3 columns per free point, metres).

    ``tendons``: the names of the tendons to route (default: all); a tendon that mirrors an
    earlier routed one, or translates it on the same motor, follows it (module docstring).
    ``fixed``: indices of each tendon's points that stay (default: the last, where the tendon
    leaves the body to its motor)."""

    kind = "routing"

    def __init__(self, robot, tendons: Sequence[str] | None = None, fixed: Sequence[int] = (-1,),
                 mirror_tol: float = 1e-7):
        names = robot.tendon_names
        tendons = list(names if tendons is None else tendons)
        for n in tendons:
            if n not in names:
                raise ValueError(f"{robot.source}: design routing names unknown tendon {n!r} (known: {names})")
        lo, hi = robot.mesh.points.min(axis=0), robot.mesh.points.max(axis=0)
        lateral = int(np.argmax(np.abs(np.cross(robot.forward_axis, robot.up_axis))))
        self.reflect = np.eye(3)
        self.reflect[lateral, lateral] = -1.0
        self.offset = np.zeros(3)
        self.offset[lateral] = lo[lateral] + hi[lateral]
        motor = robot.tendon_motor
        self.leaders = []
        #: follower tendon -> (leader, R, c): its points are ``R q_leader + c`` (c: (3,) or one
        #: offset per point, (P, 3), after :meth:`moved_to`)
        self.followers: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}
        placed: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}     # every routed tendon's map to its leader
        for n in tendons:
            t = names.index(n)
            pts = np.asarray(robot.tendons[t].points)
            found = None
            for o, (lead, R, c) in placed.items():
                other = np.asarray(robot.tendons[o].points)
                if other.shape != pts.shape:
                    continue
                mirrored = other @ self.reflect.T + self.offset
                shift = (pts - other).mean(axis=0)
                if np.abs(pts - mirrored).max() <= mirror_tol:          # the mirror image of o
                    found = (lead, self.reflect @ R, self.reflect @ c + self.offset)
                elif motor[t] >= 0 and motor[t] == motor[o] and np.abs(pts - other - shift).max() <= mirror_tol:
                    found = (lead, R, c + shift)                          # o translated: its pair
                if found:
                    break
            if found is None:
                self.leaders.append(t)
                placed[t] = (t, np.eye(3), np.zeros(3))
            else:
                self.followers[t] = placed[t] = found
        self.free = []                                 # (leader tendon, point index)
        for t in self.leaders:
            P = len(robot.tendons[t].points)
            fix = {i % P for i in fixed}
            self.free += [(t, s) for s in range(P) if s not in fix]
        self.names = tuple(f"routing:{names[t]}[{s}].{AXES[i]}" for t, s in self.free for i in range(3))
        self.values = np.concatenate([robot.tendons[t].points[s] for t, s in self.free]) if self.free \
            else np.zeros(0)
        self.bounds = np.column_stack([np.repeat(lo[None], len(self.free), 0).ravel(),
                                       np.repeat(hi[None], len(self.free), 0).ravel()]).reshape(-1, 2)

    def moved_to(self, robot, values: np.ndarray) -> "TendonRouting":
        """This routing at ``robot`` (the design at ``values``): the same leaders, free points,
        follower maps' linear parts and bounds; the values are ``robot``'s via points and each
        follower's offsets ``c_s = q'_s - R q_s`` (one per point) are read from ``robot``, so the
        relations hold as they do there (a leg morph moves a pair's points by slightly different
        amounts: with per-point offsets the moved robot is reproduced exactly)."""
        new = copy.copy(self)
        pts = [np.asarray(t.points, dtype=np.float64) for t in robot.tendons]
        new.followers = {f: (lead, R, pts[f] - pts[lead] @ R.T) for f, (lead, R, _) in self.followers.items()}
        new.values = np.concatenate([pts[t][s] for t, s in self.free]) if self.free else np.zeros(0)
        new.bounds = self.bounds.copy()
        return new

    def points(self, robot, theta: np.ndarray) -> list[np.ndarray]:
        """Every tendon's rest points for routing ``theta``."""
        pts = [np.array(t.points) for t in robot.tendons]
        for j, (t, s) in enumerate(self.free):
            pts[t][s] = theta[3 * j:3 * j + 3]
        for f, (lead, R, c) in self.followers.items():
            pts[f] = pts[lead] @ R.T + c
        return pts

    def apply(self, robot, theta: np.ndarray) -> dict:
        """The Robot field changes of routing ``theta``: new points; an explicit ``rest_length``
        keeps its offset from the rest polyline's length."""
        new = []
        for t, pts in zip(robot.tendons, self.points(robot, theta)):
            rest = t.rest_length
            if rest is not None:
                old = np.asarray(t.points)
                rest += (np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
                         - np.linalg.norm(np.diff(old, axis=0), axis=1).sum())
            new.append(dataclasses.replace(t, points=pts, rest_length=rest))
        return {"tendons": tuple(new)}

    def _columns(self):
        """For each free point j: the (tendon, point, dq/dq_leader) triples it moves (the
        leader's with the identity, each follower's with its map's linear part)."""
        for j, (t, s) in enumerate(self.free):
            yield j, [(t, s, np.eye(3))] + [(f, s, R) for f, (l, R, _) in self.followers.items() if l == t]

    def force_jacobian(self, system, x, x_prev, u, history) -> np.ndarray:
        """``d(dE/dx)/dtheta`` (3n, 3 n_free): the cable term's part (the only one)."""
        out = np.zeros((system.n_dof, len(self.names)))
        local = {}                                         # per tendon: its dofs and points' Jacobian
        for j, moved in self._columns():
            for t, s, R in moved:
                if t not in local:
                    local[t] = tendon_points_jacobian(system, x, u, t)
                dofs, J = local[t]
                np.add.at(out, (dofs[:, None], np.arange(3 * j, 3 * j + 3)[None, :]), J[:, 3 * s:3 * s + 3] @ R)
        return out

    def deformation_jacobian(self, system, x) -> np.ndarray:
        """``dGamma/dtheta`` (T, 3 n_free) at fixed x: every tendon's deformation against the free
        points (a follower's through its map)."""
        out = np.zeros((system.cables.n_tendons, len(self.names)))
        local = {}
        for j, moved in self._columns():
            for t, s, R in moved:
                if t not in local:
                    local[t] = deformation_point_gradients(system, x, t)
                out[t, 3 * j:3 * j + 3] += local[t][s] @ R
        return out

    def clearance(self, robot) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance of every routed point (each free point of a leader, then its
        followers' at the same index) to the body's surface (n,) and its Jacobian (n, len(names))
        (:mod:`.clearance`; constraint: >= :data:`~.clearance.MIN_CLEARANCE`)."""
        d, J = [], []
        for j, moved in self._columns():
            for t, s, R in moved:
                dist, grad = signed_distance(robot.mesh, np.asarray(robot.tendons[t].points[s]))
                row = np.zeros(len(self.names))
                row[3 * j:3 * j + 3] = grad @ R
                d.append(dist)
                J.append(row)
        return np.array(d), np.array(J).reshape(-1, len(self.names))
