"""Tracked markers: named points bound to the mesh like tendon points (barycentric coordinates in
the tet that contains them at rest), so they move with the body.

A marker ``p = sum_a w_a x_{n_a}`` is linear in the node positions, so its sensitivity is the
same weighted sum of the nodes' (``MarkerSet.jacobian``). Markers come from a robot.toml's
``[[markers]]`` table (:attr:`soft_envs.sim.Robot.markers`) or are bound on the fly
(:meth:`MarkerSet.bind`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["Marker", "MarkerSet"]


@dataclass(frozen=True, eq=False)
class Marker:
    """A tracked point: ``name`` and its rest position ``point`` (3,) [m, simulation frame]."""

    name: str
    point: np.ndarray


@dataclass(frozen=True, eq=False)
class MarkerSet:
    """Markers bound to a mesh: ``names`` (m,), rest ``points`` (m, 3), and per marker the four
    ``nodes`` (m, 4) of its tet with barycentric ``weights`` (m, 4)."""

    names: tuple[str, ...]
    points: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray

    @classmethod
    def bind(cls, mesh, names: Sequence[str], points, source: str = "markers") -> "MarkerSet":
        """Bind ``points`` (m, 3) [m, simulation frame at rest] named ``names`` to ``mesh`` (a
        :class:`~soft_envs.sim.TetMesh`). ValueError naming ``source`` and the marker when a
        name repeats or a point is not a finite 3-vector inside the body."""
        names = tuple(str(n) for n in names)
        try:
            pts = np.asarray(points, dtype=np.float64).reshape(len(names), 3)
        except ValueError:
            raise ValueError(f"{source}: marker points must be one [x, y, z] per marker "
                             f"({len(names)} names)") from None
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"{source}: duplicate marker names {dup}")
        nodes = np.zeros((len(names), 4), dtype=np.int64)
        weights = np.zeros((len(names), 4))
        for i, (n, p) in enumerate(zip(names, pts)):
            if not np.isfinite(p).all():
                raise ValueError(f"{source}: marker {n!r} has a non-finite point {p.tolist()}")
            hit = mesh.locate(p, tol=1e-6)
            if hit is None:
                raise ValueError(f"{source}: marker {n!r} at {p.tolist()} lies outside the body")
            e, w = hit
            w = np.clip(w, 0.0, None)
            nodes[i], weights[i] = mesh.tets[e], w / w.sum()
        for a in (pts, nodes, weights):
            a.setflags(write=False)
        return cls(names, pts, nodes, weights)

    def __len__(self) -> int:
        return len(self.names)

    def positions(self, x: np.ndarray) -> np.ndarray:
        """Marker positions (..., m, 3) at node positions ``x`` (..., n, 3)."""
        x = np.asarray(x, dtype=np.float64)
        return np.einsum("ma,...mai->...mi", self.weights, x[..., self.nodes, :])

    def jacobian(self, dxd: np.ndarray) -> np.ndarray:
        """Marker sensitivities (..., m, 3, p) from state sensitivities ``dxd`` (..., 3n, p)."""
        dxd = np.asarray(dxd, dtype=np.float64)
        per_node = dxd.reshape(*dxd.shape[:-2], -1, 3, dxd.shape[-1])           # (..., n, 3, p)
        return np.einsum("ma,...maip->...mip", self.weights, per_node[..., self.nodes, :, :])
