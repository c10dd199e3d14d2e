"""Tetrahedral meshes: loading through meshio, validation, rest geometry and lumped masses.

A :class:`TetMesh` is immutable static data (the ``Model`` side of a simulation):
rest positions, linear tetrahedra, the inverse rest shape matrices ``Dm^-1`` used by
the deformation gradient ``F = Ds Dm^-1``, element volumes, the boundary surface and
its nodes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import meshio
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__ = ["TetMesh", "load_mesh", "boundary_faces", "shape_gradients"]

#: Relative volume below which a rest element counts as degenerate (volume / h^3, h = mean edge).
DEGENERATE_RTOL = 1e-8
#: Nodes closer than this times the mean edge length count as coincident (a crack in the mesh).
COINCIDENT_RTOL = 1e-6


def boundary_faces(tets: np.ndarray, points: np.ndarray | None = None) -> np.ndarray:
    """Faces of a tet mesh that belong to exactly one tet, oriented outward, in the order of
    their first appearance.

    Without ``points`` the tets must be positively oriented (``det[x1-x0, x2-x0, x3-x0] > 0``,
    as :class:`TetMesh` guarantees); with ``points`` each face is oriented geometrically, away
    from the opposite vertex of its tet (tets of either orientation).

    Returns an (f, 3) int array of triangles whose normals ``(b - a) x (c - a)`` point out of
    the body.
    """
    tets = np.asarray(tets)
    if tets.ndim != 2 or tets.shape[1] != 4 or not np.issubdtype(tets.dtype, np.integer):
        raise ValueError(f"tets must be an (n_tets, 4) integer array, got {tets.dtype} {tets.shape}")
    tets = tets.astype(np.int64)
    # For a positively oriented tet (0,1,2,3) these faces have outward normals.
    local = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    faces = tets[:, local].reshape(-1, 3)
    opposite = tets.reshape(-1)                  # face i of a tet is opposite its vertex i
    if len(faces) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    _, first, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    keep = np.sort(first[counts == 1])
    faces, opposite = faces[keep].copy(), opposite[keep]
    if points is not None:
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] <= tets.max():
            raise ValueError(f"points must be (n_nodes, 3) covering every tet index, got {pts.shape}")
        p0, p1, p2 = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
        inward = np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), pts[opposite] - p0) > 0
        faces[inward] = faces[inward][:, [0, 2, 1]]
    return faces


def shape_gradients(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rest-shape data of linear tets.

    Returns ``(dN, vol)``: ``dN[e, a]`` is the gradient of node ``a``'s shape function in
    element ``e`` (so ``F = sum_a x_a (x) dN_a``; rows 1..3 are the rows of ``Dm^-1`` and row
    0 is minus their sum), and ``vol[e]`` the signed rest volume ``det(Dm) / 6``.
    """
    x = points[tets]
    dm = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2)
    det = np.linalg.det(dm)
    vol = det / 6.0
    dN = np.zeros((len(tets), 4, 3))
    ok = np.abs(det) > 0
    dN[ok, 1:] = np.linalg.inv(dm[ok])
    dN[:, 0] = -dN[:, 1:].sum(axis=1)
    return dN, vol


@dataclass(frozen=True, eq=False)
class TetMesh:
    """A validated linear tetrahedral mesh (SI units, metres): finite coordinates, every node in
    a tet, no degenerate or inverted element, no two nodes at one place (a crack: the elements
    on either side would not be joined), and one connected body (nodes shared between tets), or
    exactly ``bodies`` of them (a robot with a second body, :mod:`soft_envs.sim.box`).

    Attributes
    ----------
    points : (n, 3) rest node positions.
    tets : (m, 4) node indices, positively oriented.
    dN : (m, 4, 3) shape-function gradients (``Dm^-1`` rows; see :func:`shape_gradients`).
    volumes : (m,) rest volumes.
    surface : (f, 3) outward boundary triangles.
    boundary_nodes : sorted indices of the nodes on the surface.
    source : where the mesh came from (file name), used in error messages.
    bodies : the number of connected bodies (1 for a robot; 2 with a second body).
    """

    points: np.ndarray
    tets: np.ndarray
    source: str = "<mesh>"
    bodies: int = 1
    dN: np.ndarray = field(init=False, repr=False)
    volumes: np.ndarray = field(init=False, repr=False)
    surface: np.ndarray = field(init=False, repr=False)
    boundary_nodes: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=np.float64)
        tets = np.ascontiguousarray(self.tets, dtype=np.int64)
        _validate(points, tets, self.source, self.bodies)
        dN, vol = shape_gradients(points, tets)
        _check_orientation(points, tets, vol, self.source)
        surface = boundary_faces(tets)
        for name, value in (("points", points), ("tets", tets), ("dN", dN), ("volumes", vol),
                            ("surface", surface), ("boundary_nodes", np.unique(surface))):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def n_tets(self) -> int:
        return len(self.tets)

    def lumped_masses(self, density: float) -> np.ndarray:
        """Node masses from a uniform density: each tet gives a quarter of its mass to each node."""
        if not np.isfinite(density) or density <= 0:
            raise ValueError(f"{self.source}: density must be positive, got {density!r}")
        m = np.zeros(self.n_nodes)
        np.add.at(m, self.tets.ravel(), np.repeat(density * self.volumes / 4.0, 4))
        return m

    def locate(self, p: np.ndarray, tol: float = 1e-9) -> tuple[int, np.ndarray] | None:
        """The tet containing point ``p`` and its barycentric coordinates, or None if outside.

        ``tol`` is how far below zero a barycentric coordinate may be (points on faces count as
        inside). Among containing tets the one with the largest minimum coordinate is chosen.
        """
        p = np.asarray(p, dtype=np.float64)
        x0 = self.points[self.tets[:, 0]]
        # barycentric of nodes 1..3 are dN[:, 1:] @ (p - x0); node 0 gets the rest.
        lam123 = np.einsum("eij,ej->ei", self.dN[:, 1:], p - x0)
        lam = np.concatenate([1.0 - lam123.sum(axis=1, keepdims=True), lam123], axis=1)
        worst = lam.min(axis=1)
        e = int(np.argmax(worst))
        if worst[e] < -tol:
            return None
        return e, lam[e]

    def to_meshio(self) -> meshio.Mesh:
        return meshio.Mesh(np.array(self.points), [("tetra", np.array(self.tets))])


def load_mesh(source: str | Path | meshio.Mesh) -> TetMesh:
    """Read a tetrahedral mesh from any file meshio reads (.msh, .vtu, .vtk, .mesh ...) or a
    :class:`meshio.Mesh`. Only linear ``tetra`` cells are used; other cell types (the
    triangles and lines that mesh generators also write) are ignored. Raises ``ValueError``
    naming the file and the problem for meshes that cannot be simulated."""
    if isinstance(source, meshio.Mesh):
        mesh, name = source, "<meshio.Mesh>"
    else:
        name = str(source)
        path = Path(source)
        if not path.is_file():
            raise ValueError(f"{name}: mesh file not found")
        try:
            mesh = meshio.read(path)
        except (Exception, SystemExit) as exc:  # meshio raises many types (even SystemExit)
            raise ValueError(f"{name}: meshio could not read the mesh: {exc}") from exc
    blocks = [c.data for c in mesh.cells if c.type == "tetra"]
    if not blocks:
        types = sorted({c.type for c in mesh.cells}) or ["none"]
        raise ValueError(f"{name}: no linear 'tetra' cells in the mesh (cell types: {', '.join(types)})")
    tets = np.concatenate(blocks).astype(np.int64)
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{name}: points must be 3-D, got shape {points.shape}")
    return TetMesh(points, tets, source=name)


def _validate(points: np.ndarray, tets: np.ndarray, name: str, bodies: int = 1) -> None:
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{name}: points must have shape (n, 3), got {points.shape}")
    if tets.ndim != 2 or tets.shape[1] != 4 or len(tets) == 0:
        raise ValueError(f"{name}: tets must have shape (m, 4) with m > 0, got {tets.shape}")
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if bad.size:
        raise ValueError(f"{name}: non-finite (NaN or inf) coordinates at nodes {bad[:10].tolist()}")
    if tets.min() < 0 or tets.max() >= len(points):
        raise ValueError(f"{name}: tet node indices outside 0..{len(points) - 1}")
    rep = np.flatnonzero([len(set(t)) < 4 for t in tets])
    if rep.size:
        raise ValueError(f"{name}: degenerate elements (repeated nodes) {rep[:10].tolist()}")
    used = np.zeros(len(points), dtype=bool)
    used[tets.ravel()] = True
    if not used.all():
        idx = np.flatnonzero(~used)
        raise ValueError(f"{name}: {idx.size} unreferenced nodes (not in any tet), e.g. {idx[:10].tolist()}")
    _check_one_body(points, tets, name, bodies)


def _check_one_body(points: np.ndarray, tets: np.ndarray, name: str, bodies: int = 1) -> None:
    """No coincident nodes (a crack) and a single connected component (``bodies`` of them)."""
    h = float(np.linalg.norm(points[tets[:, 1:]] - points[tets[:, :1]], axis=2).mean())
    pairs = cKDTree(points).query_pairs(COINCIDENT_RTOL * h, output_type="ndarray")
    if len(pairs):
        i, j = sorted(pairs[0].tolist())
        raise ValueError(f"{name}: {len(pairs)} pairs of coincident nodes, e.g. nodes {i} and {j} at "
                         f"{np.array2string(points[i], precision=6)} (a crack: the elements on either side are "
                         "not joined); merge the duplicate nodes")
    n = len(points)
    graph = coo_matrix((np.ones(3 * len(tets)), (np.repeat(tets[:, 0], 3), tets[:, 1:].ravel())), shape=(n, n))
    n_parts, labels = connected_components(graph, directed=False)
    if bodies != 1:
        if n_parts != bodies:
            raise ValueError(f"{name}: the mesh is {n_parts} connected bodies, {bodies} expected")
        return
    if n_parts > 1:
        sizes = np.bincount(labels)
        main = int(np.argmax(sizes))
        others = np.flatnonzero(labels != main)
        dist, idx = cKDTree(points[labels == main]).query(points[others])
        k = int(np.argmin(dist))
        a, b = int(np.flatnonzero(labels == main)[idx[k]]), int(others[k])
        counts = ", ".join(map(str, sorted(sizes, reverse=True)[:5]))
        raise ValueError(f"{name}: the mesh is {n_parts} disconnected bodies ({counts} nodes; the nearest two, nodes "
                         f"{a} and {b}, are {dist[k]:.3g} apart); a robot must be one connected body")


def _check_orientation(points: np.ndarray, tets: np.ndarray, vol: np.ndarray, name: str) -> None:
    edges = points[tets[:, [1, 2, 3, 2, 3, 3]]] - points[tets[:, [0, 0, 0, 1, 1, 2]]]
    h = np.linalg.norm(edges, axis=2).mean(axis=1)
    rel = vol / h**3
    degen = np.flatnonzero(np.abs(rel) <= DEGENERATE_RTOL)
    if degen.size:
        raise ValueError(f"{name}: degenerate (zero-volume) elements {degen[:10].tolist()}")
    inverted = np.flatnonzero(rel < 0)
    if inverted.size:
        raise ValueError(
            f"{name}: {inverted.size} inverted elements (negative rest volume), e.g. {inverted[:10].tolist()}; "
            "reorder their nodes (swap two) so det[x1-x0, x2-x0, x3-x0] > 0")
