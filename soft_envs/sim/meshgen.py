"""A small voxel tet mesher: boxes on a rectilinear grid, each split into 6 tets.

The split is the Freudenthal (Kuhn) triangulation along each cell's main diagonal, which is
conforming across neighbouring cells. Used to generate the shipped robots' meshes
(``assets/*/make_mesh.py``) and the test meshes; any other mesher (gmsh, tetgen) works with
the simulator through meshio.
"""
from __future__ import annotations

from itertools import permutations
from typing import Iterable, Sequence

import numpy as np

__all__ = ["voxel_tet_mesh", "box_occupancy", "graded"]


def graded(a: float, b: float, n: int) -> np.ndarray:
    """``n + 1`` equally spaced coordinates from a to b."""
    return np.linspace(a, b, n + 1)


def box_occupancy(xs: Sequence[float], ys: Sequence[float], zs: Sequence[float],
                  boxes: Iterable[tuple[tuple[float, float], tuple[float, float], tuple[float, float]]]
                  ) -> np.ndarray:
    """Boolean (nx-1, ny-1, nz-1) array: cells whose centre lies in any of the axis-aligned
    ``boxes`` ((x0, x1), (y0, y1), (z0, z1))."""
    xs, ys, zs = (np.asarray(v, dtype=np.float64) for v in (xs, ys, zs))
    cx, cy, cz = (0.5 * (v[1:] + v[:-1]) for v in (xs, ys, zs))
    X, Y, Z = np.meshgrid(cx, cy, cz, indexing="ij")
    occ = np.zeros(X.shape, dtype=bool)
    for (x0, x1), (y0, y1), (z0, z1) in boxes:
        occ |= (X > x0) & (X < x1) & (Y > y0) & (Y < y1) & (Z > z0) & (Z < z1)
    return occ


def voxel_tet_mesh(xs: Sequence[float], ys: Sequence[float], zs: Sequence[float],
                   occupied: np.ndarray, mirror_z: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(points, tets)`` of the occupied cells of the grid ``xs x ys x zs``.

    The Freudenthal split has a preferred diagonal, so a mesh of a left/right symmetric body is
    not itself symmetric (and a simulated robot slowly turns). With ``mirror_z`` the cells whose
    centre lies above that plane use the split reflected in z: the mesh is then exactly
    symmetric about the plane (the grid must be too), and still conforming (faces in the
    plane keep their diagonal). Unused grid nodes are dropped; every tet is positively
    oriented."""
    xs, ys, zs = (np.asarray(v, dtype=np.float64) for v in (xs, ys, zs))
    occ = np.asarray(occupied, dtype=bool)
    if occ.shape != (len(xs) - 1, len(ys) - 1, len(zs) - 1):
        raise ValueError(f"occupied must have shape {(len(xs) - 1, len(ys) - 1, len(zs) - 1)}, got {occ.shape}")
    node = lambda i, j, k: (i * len(ys) + j) * len(zs) + k  # noqa: E731
    corner_tets = []
    for perm in permutations(range(3)):
        path = [np.zeros(3, dtype=int)]
        for ax in perm:
            step = path[-1].copy()
            step[ax] = 1
            path.append(step)
        corner_tets.append(np.array(path))
    corner_tets = np.array(corner_tets)                      # (6, 4, 3) offsets
    cells = np.argwhere(occ)                                 # (c, 3)
    offsets = np.broadcast_to(corner_tets, (len(cells), *corner_tets.shape)).copy()
    if mirror_z is not None:
        upper = 0.5 * (zs[cells[:, 2]] + zs[cells[:, 2] + 1]) > mirror_z
        offsets[upper, :, :, 2] = 1 - offsets[upper, :, :, 2]
    idx = cells[:, None, None, :] + offsets                  # (c, 6, 4, 3)
    tets = node(idx[..., 0], idx[..., 1], idx[..., 2]).reshape(-1, 4)
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    points = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    used, inverse = np.unique(tets, return_inverse=True)
    tets = inverse.reshape(-1, 4)
    points = points[used]
    x = points[tets]
    det = np.linalg.det(np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2))
    neg = det < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return points, tets
