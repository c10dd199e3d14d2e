"""From a designer's closed surface (STL, OBJ, PLY, OFF, VTK ... anything meshio reads) to a
tetrahedral mesh in the robot frame, with quality figures.

    >>> from soft_envs.meshing import mesh_surface
    >>> result = mesh_surface("body.stl", scale=1e-3, up="+z", forward="+x", edge_length=0.02)
    >>> result.points, result.tets, result.quality        # metres, +y up, facing +x, feet at y = 0

The surface is checked first (:func:`check_surface`: closed, edge-manifold, consistently
oriented, one connected body, no degenerate triangles; a surface whose normals point inward is
flipped with a warning), moved into the robot frame (:func:`to_robot_frame`: ``forward`` -> +x,
``up`` -> +y, lowest point at y = 0, front-to-back from x = 0, centred on z = 0), and
tetrahedralised by gmsh (:func:`tetrahedralize`; the optional extra ``soft-envs[mesh]``, gmsh is
GPL-2.0-or-later): by default the surface is re-meshed to the target edge length (gmsh's
classify/reparametrise route, so a finely tessellated CAD export still gives the coarse mesh the
simulator wants, paper II-A), the volume is meshed by Delaunay and optimised (gmsh + Netgen).
Quality (:func:`tet_quality`): dihedral angles and the radius ratio ``3 r_in / R_circ`` (1 for
the regular tet, 0 for a flat one). Before gmsh starts, the element count is estimated
(:func:`estimate_elements`) and an edge length that would make more than ``max_elements``
(default :data:`MAX_ELEMENTS`) tets is refused: gmsh cannot be interrupted and a millimetre
edge on a hand-sized body would mesh for hours.
"""
from __future__ import annotations

import signal

from dataclasses import dataclass, field
from pathlib import Path

import meshio
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["SurfaceError", "Surface", "MeshQuality", "MeshResult", "read_surface", "check_surface",
           "frame_rotation", "to_robot_frame", "tetrahedralize", "tet_quality", "estimate_elements",
           "check_element_count", "mesh_surface", "AXES", "MAX_ELEMENTS"]

#: axis names accepted by ``forward``/``up`` (as in robot.toml's ``forward_axis``/``up_axis``)
AXES = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0), "+z": (2, 1.0), "-z": (2, -1.0)}
#: quality below which :func:`mesh_surface` warns (slivers make the elements stiff and Newton slow)
MIN_DIHEDRAL_WARN_DEG = 5.0
MIN_RADIUS_RATIO_WARN = 0.1
#: sharp-feature angle [deg] kept as an edge when gmsh re-meshes the surface
FEATURE_ANGLE_DEG = 40.0
#: most tets :func:`mesh_surface` makes unless told otherwise (``trajopt mesh --max-elements``): about
#: a minute of gmsh on one core, and far finer than the simulator wants (paper II-A: a few thousand)
MAX_ELEMENTS = 200_000


class SurfaceError(ValueError):
    """A surface (or the mesh made from it) that cannot become a robot; the message names the file."""


@dataclass(frozen=True)
class Surface:
    """A closed triangle surface: ``points`` (n, 3), outward ``triangles`` (m, 3)."""

    points: np.ndarray
    triangles: np.ndarray
    source: str = "<surface>"

    @property
    def volume(self) -> float:
        """Enclosed volume (positive for outward normals), by the divergence theorem."""
        p = self.points[self.triangles]
        return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


@dataclass(frozen=True)
class MeshQuality:
    """Quality figures of a tet mesh: dihedral angles [deg] and radius ratios ``3 r_in / R``."""

    min_dihedral_deg: float
    max_dihedral_deg: float
    min_radius_ratio: float
    median_radius_ratio: float
    min_volume: float
    n_tets: int

    def rows(self) -> list[tuple[str, str]]:
        return [("dihedral angles", f"{self.min_dihedral_deg:.1f} .. {self.max_dihedral_deg:.1f} deg"),
                ("radius ratio", f"min {self.min_radius_ratio:.3f}, median {self.median_radius_ratio:.3f} "
                                 "(1 = regular tet)")]

    def warnings(self) -> list[str]:
        out = []
        if self.min_dihedral_deg < MIN_DIHEDRAL_WARN_DEG or self.min_radius_ratio < MIN_RADIUS_RATIO_WARN:
            out.append(f"poor elements (min dihedral {self.min_dihedral_deg:.1f} deg, min radius ratio "
                       f"{self.min_radius_ratio:.3f}): slivers stiffen the body and slow Newton; try another "
                       "--edge-length or clean up the surface")
        return out


@dataclass
class MeshResult:
    """A tet mesh in the robot frame (metres, +y up, facing +x, lowest point at y = 0)."""

    points: np.ndarray
    tets: np.ndarray
    quality: MeshQuality
    surface: Surface
    warnings: list[str] = field(default_factory=list)

    @property
    def body_length(self) -> float:
        return float(np.ptp(self.points[:, 0]))

    @property
    def volume(self) -> float:
        return float(_signed_volumes(self.points, self.tets).sum())


# ------------------------------------------------------------------------------ surfaces
def read_surface(path: str | Path) -> Surface:
    """Read the triangles (quads are split) of a surface file with meshio and weld coincident
    points. Raises :class:`SurfaceError` naming the file when there is nothing to mesh."""
    name = str(path)
    if not Path(path).is_file():
        raise SurfaceError(f"{name}: surface file not found")
    try:
        with np.errstate(over="ignore"):       # meshio's STL binary/ASCII test overflows harmlessly
            mesh = meshio.read(path)
    except (Exception, SystemExit) as exc:     # meshio raises many types (even SystemExit)
        raise SurfaceError(f"{name}: meshio could not read the surface: {exc}") from exc
    if any(c.type.startswith("tetra") for c in mesh.cells):
        raise SurfaceError(f"{name}: this is a volume mesh already (tetra cells); name it in robot.toml's "
                           "[robot].mesh instead of meshing it again")
    tris = [c.data[:, :3] for c in mesh.cells if c.type == "triangle"]
    tris += [c.data[:, [0, 1, 2, 0, 2, 3]].reshape(-1, 3) for c in mesh.cells if c.type == "quad"]
    if not tris:
        types = sorted({c.type for c in mesh.cells}) or ["none"]
        raise SurfaceError(f"{name}: no triangles in the file (cell types: {', '.join(types)})")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise SurfaceError(f"{name}: points must be finite 3-D coordinates")
    tris = np.concatenate(tris).astype(np.int64)
    unique, inverse = np.unique(points, axis=0, return_inverse=True)   # weld exact duplicates
    tris = inverse.reshape(-1)[tris]
    used, compact = np.unique(tris, return_inverse=True)
    return Surface(unique[used], compact.reshape(-1, 3), name)


def check_surface(surface: Surface) -> tuple[Surface, list[str]]:
    """Check that a surface bounds one solid; return it with outward normals and the warnings.

    Refuses (:class:`SurfaceError`) degenerate triangles, open or non-manifold edges,
    inconsistent orientation, several connected components and a zero enclosed volume; a
    consistently inward surface is flipped with a warning."""
    src, p, t = surface.source, surface.points, surface.triangles
    diag = float(np.linalg.norm(np.ptp(p, axis=0))) or 1.0
    area2 = np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    bad = np.flatnonzero((t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2])
                         | (area2 <= 1e-12 * diag**2))
    if bad.size:
        raise SurfaceError(f"{src}: {bad.size} degenerate (zero-area) triangles, e.g. {bad[:5].tolist()}; "
                           "remove them (MeshLab: Cleaning and Repairing, or pymeshfix) and export again")
    directed = t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key, inv, count = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    where = lambda edges: np.round(p[edges[:3, 0]], 6).tolist()   # noqa: E731
    if (count == 1).any():
        e = key[count == 1]
        raise SurfaceError(f"{src}: the surface is not closed: {len(e)} boundary edges (in one triangle "
                           f"only), e.g. at {where(e)}; close the holes before meshing")
    if (count > 2).any():
        e = key[count > 2]
        raise SurfaceError(f"{src}: {len(e)} non-manifold edges (in more than two triangles), e.g. at "
                           f"{where(e)}; touching or duplicated parts must be merged into one solid")
    forward = directed[:, 0] < directed[:, 1]          # each closed-manifold edge twice:
    same = np.bincount(inv, weights=forward, minlength=len(key)) != 1   # once each way if consistent
    if same.any():
        raise SurfaceError(f"{src}: triangles are not consistently oriented ({int(same.sum())} edges run the "
                           f"same way in both their triangles, e.g. at {where(key[same])}); re-orient the faces "
                           "coherently (MeshLab, pymeshfix) and export again")
    adj = coo_matrix((np.ones(len(key)), (key[:, 0], key[:, 1])), shape=(len(p), len(p)))
    n_comp, labels = connected_components(adj, directed=False)
    if n_comp > 1:
        sizes = np.bincount(labels[t[:, 0]], minlength=n_comp)
        raise SurfaceError(f"{src}: {n_comp} separate bodies (connected components of {sorted(sizes.tolist())} "
                           "triangles); a robot is one body: join them in the CAD model")
    vol = surface.volume
    if abs(vol) <= 1e-9 * diag**3:
        raise SurfaceError(f"{src}: the surface encloses no volume ({vol:.3g})")
    warnings = []
    if vol < 0:
        warnings.append(f"{src}: the surface normals point inward (enclosed volume {vol:.4g} < 0); flipped them")
        surface = Surface(p, t[:, [0, 2, 1]], src)
    return surface, warnings


# ------------------------------------------------------------------------------ frame
def frame_rotation(forward: str = "+x", up: str = "+y") -> np.ndarray:
    """Rotation whose rows are the robot frame's x (forward), y (up), z = x cross y in the
    surface's coordinates (the rule of :func:`soft_envs.sim.load_robot`)."""
    for key, v in (("forward", forward), ("up", up)):
        if v not in AXES:
            raise ValueError(f"{key} must be one of {list(AXES)}, got {v!r}")
    f, u = np.zeros(3), np.zeros(3)
    f[AXES[forward][0]], u[AXES[up][0]] = AXES[forward][1], AXES[up][1]
    if f @ u != 0:
        raise ValueError(f"forward ({forward}) and up ({up}) must be different axes")
    return np.stack([f, u, np.cross(f, u)])


def to_robot_frame(surface: Surface, scale: float = 1.0, forward: str = "+x", up: str = "+y") -> Surface:
    """The surface in metres in the robot frame: ``forward`` -> +x, ``up`` -> +y, the lowest point
    at y = 0, the rearmost at x = 0 and the bounding box centred on z = 0."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be positive, got {scale!r}")
    q = scale * surface.points @ frame_rotation(forward, up).T      # proper rotation: orientation kept
    lo, hi = q.min(axis=0), q.max(axis=0)
    q = q - np.array([lo[0], lo[1], 0.5 * (lo[2] + hi[2])])
    return Surface(q, surface.triangles.copy(), surface.source)


# ------------------------------------------------------------------------------ quality
def _signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    x = points[tets]
    return np.einsum("ij,ij->i", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0])) / 6.0


def tet_quality(points: np.ndarray, tets: np.ndarray) -> MeshQuality:
    """Dihedral angles and radius ratios ``rho = 3 r_in / R_circ`` of every tet.

    ``r_in = 3 V / (sum of face areas)``; ``R_circ = |a^2 (b x c) + b^2 (c x a) + c^2 (a x b)| / (12 V)``
    with ``a, b, c`` the edges from vertex 0. A regular tet has rho = 1 and dihedral angles of
    70.5 deg; a flat one rho = 0 and a dihedral angle of 0 or 180 deg."""
    x = np.asarray(points, dtype=np.float64)[np.asarray(tets)]
    a, b, c = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    faces = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))       # outward for vol > 0
    normals = np.stack([np.cross(x[:, j] - x[:, i], x[:, k] - x[:, i]) for i, j, k in faces], axis=1)
    areas = 0.5 * np.linalg.norm(normals, axis=2)
    unit = normals / np.maximum(2.0 * areas, 1e-300)[..., None]
    pairs = [(i, j) for i in range(4) for j in range(i + 1, 4)]   # faces i, j meet at an edge
    cos = np.stack([np.einsum("ij,ij->i", unit[:, i], unit[:, j]) for i, j in pairs], axis=1)
    dihedral = 180.0 - np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    sq = lambda v: np.einsum("ij,ij->i", v, v)[:, None]   # noqa: E731
    circ = np.linalg.norm(sq(a) * np.cross(b, c) + sq(b) * np.cross(c, a) + sq(c) * np.cross(a, b), axis=1)
    absvol = np.abs(vol)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(absvol > 0, 3.0 * (3.0 * absvol / areas.sum(axis=1)) * 12.0 * absvol / circ, 0.0)
    return MeshQuality(float(dihedral.min()), float(dihedral.max()), float(rho.min()), float(np.median(rho)),
                       float(vol.min()), len(vol))


# ------------------------------------------------------------------------------ gmsh
def _gmsh():
    try:
        import gmsh
    except ImportError as exc:
        raise ImportError("meshing a surface needs gmsh (GPL-2.0-or-later), an optional extra: "
                          "pip install 'soft-envs[mesh]'  (or: pip install gmsh)") from exc
    return gmsh


def tetrahedralize(surface: Surface, edge_length: float, remesh: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Tet mesh ``(points, tets)`` of the solid bounded by a checked surface, by gmsh.

    ``remesh=True`` re-meshes the surface at ``edge_length`` first (features sharper than
    ``FEATURE_ANGLE_DEG`` kept); ``remesh=False`` keeps the input triangles as the boundary and
    only the interior follows ``edge_length``. Tets come back positively oriented."""
    if not (np.isfinite(edge_length) and edge_length > 0):
        raise ValueError(f"edge_length must be positive, got {edge_length!r}")
    gmsh = _gmsh()
    sigpipe = signal.getsignal(signal.SIGPIPE) if hasattr(signal, "SIGPIPE") else None
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.logger.start()
        gmsh.model.add("body")
        tag = gmsh.model.addDiscreteEntity(2)
        n = len(surface.points)
        gmsh.model.mesh.addNodes(2, tag, np.arange(1, n + 1), surface.points.ravel())
        gmsh.model.mesh.addElementsByType(tag, 2, [], (surface.triangles + 1).ravel())
        if remesh:
            angle = np.radians(FEATURE_ANGLE_DEG)
            gmsh.model.mesh.classifySurfaces(angle, True, True, np.pi)
            gmsh.model.mesh.createGeometry()
        loop = gmsh.model.geo.addSurfaceLoop([s for _, s in gmsh.model.getEntities(2)])
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        for key, value in (("Mesh.MeshSizeMax", edge_length), ("Mesh.MeshSizeMin", 0.2 * edge_length),
                           ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.MeshSizeFromPoints", 0),
                           ("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.OptimizeNetgen", 1),
                           ("Mesh.Algorithm3D", 1), ("General.NumThreads", 1)):
            gmsh.option.setNumber(key, value)
        gmsh.model.mesh.generate(3)
        node_tags, coords, _ = gmsh.model.mesh.getNodes()
        _, tet_nodes = gmsh.model.mesh.getElementsByType(4)
    except Exception as exc:       # gmsh raises plain Exceptions with its last error message
        log = [m for m in gmsh.logger.get() if m.startswith("Error") and str(exc).strip() not in m]
        raise SurfaceError(f"{surface.source}: gmsh could not mesh the volume: {str(exc).strip()}"
                           + (f" ({'; '.join(log[-3:])})" if log else "")
                           + "; check the surface for self-intersections") from exc
    finally:
        gmsh.logger.stop()
        gmsh.finalize()
        if sigpipe is not None:
            # gmsh's initialize() sets SIGPIPE to its default action, behind Python's back: a
            # later write to a closed pipe (a process pool's queue to a terminated worker, `| head`)
            # would end this process instead of raising BrokenPipeError. Python's disposition back.
            signal.signal(signal.SIGPIPE, sigpipe)
    if len(tet_nodes) == 0:
        raise SurfaceError(f"{surface.source}: gmsh made no tetrahedra (is the surface self-intersecting?)")
    lookup = np.zeros(int(node_tags.max()) + 1, dtype=np.int64)
    lookup[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    tets = lookup[np.asarray(tet_nodes, dtype=np.int64)].reshape(-1, 4)
    used, inverse = np.unique(tets, return_inverse=True)
    points, tets = coords.reshape(-1, 3)[used], inverse.reshape(-1, 4)
    neg = _signed_volumes(points, tets) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return points, tets


def estimate_elements(surface: Surface, edge_length: float, remesh: bool = True) -> int:
    """Tets gmsh is expected to make of ``surface`` at ``edge_length`` ``a`` (before meshing).

    ``N = V / (a^3 / (6 sqrt 2)) = 6 sqrt(2) V / a^3``: the enclosed volume ``V`` over the volume
    of the regular tet of edge ``a``; plus ``2 n_triangles`` when the surface is kept
    (``remesh=False``: every kept boundary triangle carries about two tets however coarse ``a``).
    On examples/data/quadruped.obj gmsh makes 0.6-1.1 x the volume term at edges of body
    length / 13 .. / 30 (its edges are shorter than ``a``, and at coarser edges the surface sets
    the count); the estimate is for refusing runaway meshes, not a prediction to a few percent."""
    if not (np.isfinite(edge_length) and edge_length > 0):
        raise ValueError(f"edge_length must be positive, got {edge_length!r}")
    n = 6.0 * np.sqrt(2.0) * abs(surface.volume) / edge_length**3
    if not remesh:
        n += 2.0 * len(surface.triangles)
    return int(round(min(n, 1e18)))


def check_element_count(surface: Surface, edge_length: float, remesh: bool = True,
                        max_elements: int = MAX_ELEMENTS) -> int:
    """The :func:`estimate_elements` of ``surface``; :class:`SurfaceError` naming the file, the
    edge length, the estimate and the edge length the cap allows when it is above ``max_elements``."""
    if int(max_elements) < 1:
        raise ValueError(f"max_elements must be >= 1, got {max_elements!r}")
    n = estimate_elements(surface, edge_length, remesh)
    if n > max_elements:
        smallest = (6.0 * np.sqrt(2.0) * abs(surface.volume) / max_elements) ** (1.0 / 3.0)
        raise SurfaceError(f"{surface.source}: edge length {edge_length:g} m would make about {n:.3g} tets "
                           f"(6 sqrt(2) x volume {abs(surface.volume):.4g} m^3 / edge^3), more than the cap of "
                           f"{max_elements}; use --edge-length {smallest:.3g} or more (the simulator wants a few "
                           "thousand), or raise the cap with --max-elements N")
    return n


def mesh_surface(path: str | Path, *, scale: float = 1.0, forward: str = "+x", up: str = "+y",
                 edge_length: float | None = None, remesh: bool = True, max_elements: int = MAX_ELEMENTS,
                 on_estimate=None) -> MeshResult:
    """Read, check, move into the robot frame and tetrahedralise a closed surface.

    ``edge_length`` [m, after ``scale``] defaults to a sixth of the body length (coarse on
    purpose, paper II-A). Before gmsh starts, :func:`check_element_count` refuses an edge length
    whose estimated tet count is above ``max_elements``; ``on_estimate(n, edge_length)`` is called
    with the estimate when given. Refuses inverted or degenerate tets in the result."""
    surface, warnings = check_surface(read_surface(path))
    surface = to_robot_frame(surface, scale, forward, up)
    length = float(np.ptp(surface.points[:, 0]))
    if not 0.01 <= length <= 2.0:
        warnings.append(f"{surface.source}: the body is {length:.4g} m long after scale {scale:g}; "
                        "is --scale right (0.001 for millimetres)?")
    h = length / 6.0 if edge_length is None else float(edge_length)
    n_estimate = check_element_count(surface, h, remesh, max_elements)
    if on_estimate is not None:
        on_estimate(n_estimate, h)
    points, tets = tetrahedralize(surface, h, remesh)
    quality = tet_quality(points, tets)
    vols = _signed_volumes(points, tets)
    h_mean = np.linalg.norm(points[tets[:, 1]] - points[tets[:, 0]], axis=1).mean()
    if (np.abs(vols) <= 1e-8 * h_mean**3).any():
        raise SurfaceError(f"{surface.source}: the mesh has {int((np.abs(vols) <= 1e-8 * h_mean**3).sum())} "
                           "degenerate (zero-volume) tets; try another edge length")
    rel = abs(vols.sum() - surface.volume) / surface.volume
    if rel > 0.02:
        warnings.append(f"{surface.source}: the tet mesh's volume differs from the surface's by "
                        f"{100 * rel:.1f} %")
    return MeshResult(points, tets, quality, surface, warnings + quality.warnings())
