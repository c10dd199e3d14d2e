r"""Clearance of a point in the body: its signed distance to the boundary surface of the rest
mesh (positive inside), with the gradient, for the routing constraint that keeps each via point at
least 2 mm inside the body.

``d(q) = s(q) min_f |q - c_f(q)|`` with ``c_f`` the closest point of boundary triangle f and
``s = +1`` inside the body (:meth:`~soft_envs.sim.mesh.TetMesh.locate`), -1 outside. Where the
closest point is unique, ``grad d = s (q - c) / |q - c|`` (the closest point moves tangentially
to first order), the usual derivative of a distance field away from the medial axis.
"""
from __future__ import annotations

import numpy as np

__all__ = ["MIN_CLEARANCE", "closest_points_on_triangles", "signed_distance"]

#: the clearance each via point keeps from the surface [m]
MIN_CLEARANCE = 0.002


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point to ``p`` (3,) on each triangle ``(a, b, c)`` (f, 3) each (Ericson,
    Real-Time Collision Detection 5.1.5: the Voronoi regions of vertices, edges and face)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        den = 1.0 / (va + vb + vc)
        face = a + ab * (vb * den)[:, None] + ac * (vc * den)[:, None]
    out = face
    cases = [  # checked last to first: the first true region wins
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t_bc[:, None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None]),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for cond, q in cases:
        out = np.where(cond[:, None], q, out)
    return out


def signed_distance(mesh, q: np.ndarray) -> tuple[float, np.ndarray]:
    """``(d, grad d)`` of point ``q`` (3,) in the rest ``mesh``: distance to its boundary
    surface, positive inside."""
    q = np.asarray(q, dtype=np.float64)
    tri = mesh.points[mesh.surface]
    c = closest_points_on_triangles(q, tri[:, 0], tri[:, 1], tri[:, 2])
    dist = np.linalg.norm(q - c, axis=1)
    f = int(np.argmin(dist))
    d = float(dist[f])
    sign = 1.0 if mesh.locate(q, tol=0.0) is not None else -1.0
    grad = sign * (q - c[f]) / d if d > 0 else np.zeros(3)
    return sign * d, grad
