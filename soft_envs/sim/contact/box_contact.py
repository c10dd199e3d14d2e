r"""Contact between the robot and a box (:mod:`soft_envs.sim.box`): the :class:`BoxContact` term.

Every robot boundary node ``p`` (not fixed) is checked against the box's six faces. Face ``f``
has the corners ``a, b, c, d`` (cyclic, outward), the normal ``n_f = w / |w|`` with ``w = (c -
a) x (d - b)`` (the mean plane of a face that the box's deformation has warped a little) and the
centroid ``o_f = (a + b + c + d) / 4``; ``delta_f(p) = n_f . (p - o_f)`` is the signed distance
from its plane. The box is convex, so ``p`` is inside when every ``delta_f < 0``, and its
penetration is ``s = -max_f delta_f`` (the depth below the nearest face ``f*``), the maximum
taken over the faces but the one opposite the node's nearest face at the previous step's
positions (so a node pressed into the bottom face is pushed back out through it however deep a
Newton iterate puts it, instead of through the top face: no tunnelling within a step):

.. math::
    E_i = Q_b(s_i) + \mu_b N_{k-1,i} G(|t_i|), \qquad t_i = (I - n n^T)(p_i - q_i),

with ``Q_b`` the one-sided quadratic of :mod:`.penalty` (stiffness ``k_b``, blend ``eps_b``) and
the friction of the ground's Coulomb law (:mod:`.coulomb`, docs/contact.md) moved onto the box:
``G`` is the same bristle potential of slip distance ``r_b``, ``N_{k-1} = Q_b'(s)`` at the
previous step's positions (lagged), and the anchor ``q = sum_j phi_j(xi, eta) x_j`` is a
material point of the anchor face (bilinear in its corners, so it moves and turns with the
box), ``n`` that face's normal. The history is per node ``(face, xi, eta)`` (``face = -1``: no
anchor); after each step (:meth:`BoxContact.next_history`) a node whose friction was inactive
(``N_{k-1} = 0``) is re-anchored at its projection on its nearest face when inside the box
(``-1`` otherwise), one within ``r_b`` of its anchor sticks, one beyond slides and drags its
anchor to ``r_b`` behind it in the face's plane. Friction therefore holds a payload on a tilted
robot up to ``tan a = mu_b`` and slides it beyond, with no creep.

Derivatives: per pair (node, face) the energy is a function of 15 coordinates ``y = (p, a, b, c,
d)``; ``dn/dy = (I - n n^T) / |w| dw/dy`` and ``d^2 n / dy^2`` follow from ``w`` being
bilinear in the corners, and the gradient and Hessian of ``delta`` and of ``t`` follow by the
chain rule (:mod:`.box_geometry`, numba kernels). The energy is C2 within a face's region
and, at the switch of the nearest face, continuous with a gradient that jumps (a box has
edges). The Hessian is exact; the Newton solver's projected fallback clamps each pair's negative eigenvalues
(:meth:`BoxContact.assemble_projected`). The sensitivities' products (``d grad / d x_prev``
through ``N_{k-1}``, ``d grad / d anchors``, the anchors' update and their transposes) are
:mod:`.box_sensitivity`'s kernels. Not modelled: the box's corners and edges against the
robot's faces (only robot nodes are tested against the box).
"""
from __future__ import annotations

import numpy as np

from ..box import BOX_FACES
from ..terms import EnergyTerm
from .box_geometry import bilinear, box_assemble, face_geometry, face_planes
from .box_sensitivity import anchor_tangent, history_product, prev_product
from .penalty import one_sided_quadratic

__all__ = ["BoxContact"]


def _faces(hist) -> np.ndarray:
    """(c,) the anchors' faces (:func:`.box_geometry.face_index`)."""
    return np.floor(np.asarray(hist)[:, 0] + 0.5).astype(np.int64)


def _weights(xi, eta) -> np.ndarray:
    """(P, 4) the bilinear weights (:func:`.box_geometry.bilinear`) of every ``(xi, eta)``."""
    return np.array([bilinear(a, b) for a, b in zip(xi, eta)]).reshape(-1, 4)


def _project(F: np.ndarray, pts: np.ndarray):
    """``(xi, eta)`` of the points of faces ``F`` (P, 4, 3) nearest ``pts`` (P, 3) (Gauss-Newton
    on the bilinear map; exact in one step on a parallelogram)."""
    xi = np.full(len(pts), 0.5)
    eta = np.full(len(pts), 0.5)
    a, b, c, d = F[:, 0], F[:, 1], F[:, 2], F[:, 3]
    for _ in range(4):
        q = np.einsum("pj,pjk->pk", _weights(xi, eta), F)
        dxi = (1 - eta)[:, None] * (b - a) + eta[:, None] * (c - d)
        deta = (1 - xi)[:, None] * (d - a) + xi[:, None] * (c - b)
        Jm = np.stack([dxi, deta], axis=2)                                 # (P, 3, 2)
        step = np.linalg.solve(np.einsum("pki,pkj->pij", Jm, Jm), np.einsum("pki,pk->pi", Jm, pts - q)[:, :, None])
        xi, eta = xi + step[:, 0, 0], eta + step[:, 1, 0]
    return xi, eta


class BoxContact(EnergyTerm):
    """Penalty contact and Coulomb friction between the robot's boundary nodes and its box
    (module docstring). Parameters from ``robot.box``: ``stiffness`` k_b [N/m], ``blend``
    eps_b [m], ``friction_coefficient`` mu_b, ``slip_distance`` r_b [m]. History: (c, 3) per
    contact node ``(face, xi, eta)`` of its anchor on the box (face -1: none)."""

    name = "box_contact"
    has_history = True

    def __init__(self, robot):
        box = robot.box
        self.k, self.eps, self.mu, self.rs = box.stiffness, box.blend, box.friction_coefficient, box.slip_distance
        boundary = robot.mesh.boundary_nodes
        self.nodes = np.setdiff1d(boundary[boundary < robot.n_robot_nodes], robot.fixed_nodes).astype(np.int64)
        self.box_nodes = robot.box_nodes
        self.faces = np.ascontiguousarray(self.box_nodes[BOX_FACES])    # (6, 4) global corner nodes
        self._scratch = np.zeros(1)
        # each pair's 15 local indices into the node's 27-dof block (its 3, then the box's 24)
        self._local = np.concatenate([np.tile(np.arange(3), (6, 1)),
                                      (3 + 3 * BOX_FACES[:, :, None] + np.arange(3)).reshape(6, 12)], axis=1)

    def hessian_blocks(self) -> list[np.ndarray]:
        box = np.tile((3 * self.box_nodes[:, None] + np.arange(3)).ravel(), (len(self.nodes), 1))
        return [np.concatenate([3 * self.nodes[:, None] + np.arange(3), box], axis=1)]

    def bind(self, slots, diag_slots) -> None:
        super().bind(slots, diag_slots)
        self.slots = np.ascontiguousarray(slots[0].reshape(len(self.nodes), 27, 27))

    # ------------------------------------------------------------------ geometry
    def _distances(self, x: np.ndarray) -> np.ndarray:
        """(c, 6) ``delta_f`` of every contact node from every face's plane."""
        n, o = face_planes(x, self.faces)
        return x[self.nodes] @ n.T - np.einsum("fk,fk->f", o, n)[None]

    def _lagged(self, x_prev: np.ndarray):
        """``(opposite face (c,), N_{k-1} (c,))`` at ``x_prev``, kept while ``x_prev`` is the same
        (the Newton iterations of one step)."""
        cached = getattr(self, "_lag", None)
        if cached is None or not np.array_equal(cached[0], x_prev):
            delta = self._distances(x_prev)
            f = np.argmax(delta, axis=1)
            N = one_sided_quadratic(-delta[np.arange(len(self.nodes)), f], self.k, self.eps)[1]
            self._lag = cached = (np.array(x_prev), f ^ 1, N)               # faces -x, +x, -y, +y, -z, +z
        return cached[1], cached[2]

    def depths(self, x: np.ndarray, x_prev: np.ndarray | None = None):
        """``(s (c,), nearest face (c,))``: each contact node's penetration ``-max_f delta_f``;
        with ``x_prev``, over the faces but the one opposite the node's nearest at ``x_prev``
        (module docstring: no node tunnels through the box within a step)."""
        delta = self._distances(x)
        if x_prev is not None:
            delta[np.arange(len(self.nodes)), self._lagged(x_prev)[0]] = -np.inf
        f = np.argmax(delta, axis=1)
        return -delta[np.arange(len(self.nodes)), f], f

    def normal_forces(self, x: np.ndarray) -> np.ndarray:
        """``N_i = Q_b'(s_i)`` of every contact node [N] (the nearest face's depth)."""
        return self._lagged(x)[1]

    def _run(self, x, x_prev, hist, grad, hdata, want_grad, want_hess, project=False) -> float:
        opposite, N = self._lagged(x_prev)
        return box_assemble(x, self.nodes, self.faces, opposite, self.mu * N, np.asarray(hist, dtype=np.float64),
                            self.k, self.eps, self.rs, grad, hdata, self.slots, self._local, want_grad, want_hess,
                            project)

    # ------------------------------------------------------------------ the term
    def energy(self, x, x_prev, u, hist=None) -> float:
        hist = self.initial_history(x_prev) if hist is None else hist
        return self._run(x, x_prev, hist, self._scratch, self._scratch, False, False)

    def assemble(self, x, x_prev, u, hist, grad, hdata, want_hess) -> float:
        return self._run(x, x_prev, hist, grad, hdata, True, want_hess)

    def assemble_projected(self, x, x_prev, u, hist, grad, hdata) -> float:
        """Each pair's Hessian with its negative eigenvalues set to 0."""
        return self._run(x, x_prev, hist, grad, hdata, True, True, True)

    # ------------------------------------------------------------------ anchors
    def _anchor(self, x, sel, face, pts):
        F = x[self.faces[face]]
        return _project(F, pts) if len(sel) else (np.zeros(0), np.zeros(0))

    def initial_history(self, x0, x_prev=None) -> np.ndarray:
        """Every node inside the box anchored at its projection on its nearest face (the
        faces of :meth:`depths` with ``x_prev``)."""
        out = np.zeros((len(self.nodes), 3))
        self._fresh_anchors(x0, x_prev, np.arange(len(self.nodes)), out)
        return out

    def _fresh_anchors(self, x, x_prev, rows: np.ndarray, out: np.ndarray) -> None:
        """``out[rows]``: the anchors :meth:`initial_history` gives those nodes at ``x`` (the
        nodes outside the box unanchored, face -1)."""
        s, f = self.depths(x, x_prev)
        out[rows] = (-1.0, 0.0, 0.0)
        on = rows[s[rows] > 0]
        xi, eta = self._anchor(x, on, f[on], x[self.nodes[on]])
        out[on, 0], out[on, 1], out[on, 2] = f[on], xi, eta

    def next_history(self, x, x_prev, hist) -> np.ndarray:
        """The anchors' update of the module docstring."""
        out = np.array(hist, dtype=np.float64)
        face = _faces(hist)
        out[:, 0] = face
        active = self._active(x_prev, hist)
        self._fresh_anchors(x, x_prev, np.flatnonzero(~active), out)     # the others keep or slide theirs
        fr = np.flatnonzero(active)
        if len(fr):
            F = x[self.faces[face[fr]]]
            n = np.array([face_geometry(f, False)[0] for f in F])
            q = np.einsum("pj,pjk->pk", _weights(out[fr, 1], out[fr, 2]), F)
            v = x[self.nodes[fr]] - q
            t = v - np.einsum("pk,pk->p", n, v)[:, None] * n
            r = np.linalg.norm(t, axis=1)
            slide = r > self.rs
            if slide.any():
                sel = fr[slide]
                target = q[slide] + (1.0 - self.rs / r[slide])[:, None] * t[slide]
                out[sel, 1], out[sel, 2] = _project(F[slide], target)
        return out

    # ------------------------------------------------------------------ sensitivities
    def _active(self, x_prev, hist) -> np.ndarray:
        """Whether each node's friction is on during the step from ``x_prev`` (anchored, N > 0)."""
        return (_faces(hist) >= 0) & (self.normal_forces(x_prev) > 0)

    def add_prev_product(self, x, x_prev, u, hist, S, out) -> None:
        prev_product(x, x_prev, self.nodes, self.faces, np.asarray(hist), self.k, self.eps, self.mu, self.rs, S, out,
                     False)

    def add_prev_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        tmp = np.zeros((len(out), 1))
        prev_product(x, x_prev, self.nodes, self.faces, np.asarray(hist), self.k, self.eps, self.mu, self.rs,
                     np.ascontiguousarray(lam).reshape(-1, 1), tmp, True)
        out += tmp[:, 0]

    def add_history_product(self, x, x_prev, u, hist, P, out) -> None:
        history_product(x, self.nodes, self.faces, np.asarray(hist), self.mu * self.normal_forces(x_prev), self.rs,
                        np.ascontiguousarray(P), out, False)

    def add_history_product_T(self, x, x_prev, u, hist, lam, out) -> None:
        tmp = np.zeros((out.shape[0], 1))
        history_product(x, self.nodes, self.faces, np.asarray(hist), self.mu * self.normal_forces(x_prev), self.rs,
                        np.ascontiguousarray(lam).reshape(-1, 1), tmp, True)
        out += tmp[:, 0]

    def history_tangent(self, x, x_prev, hist, S, P) -> np.ndarray:
        out = np.zeros_like(P)
        anchor_tangent(x, self.nodes, self.faces, np.asarray(hist), self.next_history(x, x_prev, hist),
                       self._active(x_prev, hist), self.rs, np.ascontiguousarray(S), np.ascontiguousarray(P), out,
                       False)
        return out

    def history_tangent_T(self, x, x_prev, hist, m, out_x, out_h) -> None:
        sx = np.zeros((len(out_x), 1))
        oh = np.zeros((len(out_h), 1))
        anchor_tangent(x, self.nodes, self.faces, np.asarray(hist), self.next_history(x, x_prev, hist),
                       self._active(x_prev, hist), self.rs, sx, np.ascontiguousarray(m).reshape(-1, 1), oh, True)
        out_x += sx[:, 0]
        out_h += oh[:, 0]
