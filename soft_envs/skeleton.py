"""A ``robot.toml`` skeleton for a tet mesh in the robot frame (see :mod:`soft_envs.meshing`).

:func:`find_legs` finds the legs as the connected groups of nodes near the ground,
:func:`leg_motors` places a tendon pair on the front and the back face of each leg (the
shipped Puppy's layout: each motor winds a pair of parallel polylines from the foot up into the
body; left/right motors mirrored), and :func:`write_robot_toml` writes a commented file that
loads as it is (:func:`soft_envs.sim.load_robot`) and says how to choose each number.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .sim.mesh import TetMesh
from .sim.robot import DEFAULT_MAX_SPEED_RPM

__all__ = ["Leg", "find_legs", "leg_motors", "example_motors", "write_robot_toml", "skeleton_text", "make_robot"]

#: heights of a leg tendon's points, as fractions of the body height (the shipped Puppy's)
TENDON_HEIGHTS = (0.06, 0.23, 0.40, 0.74)
#: motor range u_max as a fraction of its tendons' rest length (Puppy: 16 mm of 48 mm)
U_MAX_FRACTION = 0.33


@dataclass(frozen=True)
class Leg:
    """A leg: the nodes within ``foot_height`` of the ground that hang together."""

    name: str
    nodes: np.ndarray
    x: tuple[float, float]          # extent of those nodes [m]
    z: tuple[float, float]

    @property
    def centre(self) -> np.ndarray:
        return np.array([0.5 * sum(self.x), 0.5 * sum(self.z)])


def find_legs(points: np.ndarray, tets: np.ndarray, foot_fraction: float = 0.1) -> list[Leg]:
    """Legs of a body in the robot frame: connected (through tet edges) groups of the nodes below
    ``foot_fraction`` of the height. Named ``fore``/``hind`` (front or back half) and
    ``left``/``right``/``middle`` (left is -z), with a number when a name repeats; sorted by name."""
    y = points[:, 1]
    low = y <= foot_fraction * np.ptp(y) + y.min()
    e = np.concatenate([tets[:, [i, j]] for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))])
    e = e[low[e[:, 0]] & low[e[:, 1]]]
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(points),) * 2)
    _, labels = connected_components(graph, directed=False)
    length, width = np.ptp(points[:, 0]), np.ptp(points[:, 2])
    mid_x = points[:, 0].min() + 0.5 * length
    legs = []
    for lab in np.unique(labels[low]):
        nodes = np.flatnonzero(low & (labels == lab))
        px, pz = points[nodes, 0], points[nodes, 2]
        cz = 0.5 * (pz.min() + pz.max())
        side = "middle" if abs(cz) < 0.1 * width else ("left" if cz < 0 else "right")
        end = "fore" if 0.5 * (px.min() + px.max()) >= mid_x else "hind"
        legs.append(Leg(f"{end}_{side}", nodes, (px.min(), px.max()), (pz.min(), pz.max())))
    legs.sort(key=lambda g: g.centre[0])
    names = [g.name for g in legs]
    out = []
    for g in legs:
        if names.count(g.name) > 1:
            g = Leg(f"{g.name}_{sum(1 for h in out if h.name.startswith(g.name)) + 1}", g.nodes, g.x, g.z)
        out.append(g)
    return sorted(out, key=lambda g: g.name)


def _inside(mesh: TetMesh, p: np.ndarray) -> bool:
    return mesh.locate(p, tol=-1e-9) is not None


def _tendon(mesh: TetMesh, leg: Leg, x: float, z: float, heights: np.ndarray) -> list[list[float]]:
    """A vertical polyline at (x, z) through ``heights``, each point pulled towards the leg's axis
    until it lies inside the body (points that cannot be placed are dropped)."""
    c = leg.centre
    pts = []
    for y in heights:
        for k in range(8):
            q = c + 0.5**k * (np.array([x, z]) - c)
            p = np.array([q[0], y, q[1]]).round(5)
            if _inside(mesh, p):
                pts.append(p.tolist())
                break
    if len(pts) < 2:
        raise ValueError(f"could not place a tendon inside leg {leg.name!r} at x = {x:.4f}, z = {z:.4f}")
    return pts


def _motor(mesh: TetMesh, name: str, leg: Leg, face: str, heights: np.ndarray, mirror: str | None) -> dict:
    x0, x1 = leg.x
    inset = 0.15 * (x1 - x0)
    x = x1 - inset if face == "front" else x0 + inset
    z0, z1 = leg.z
    tendons = [(f"{name}_{tag}", _tendon(mesh, leg, x, z0 + f * (z1 - z0), heights))
               for tag, f in (("a", 0.25), ("b", 0.75))]
    rest = np.mean([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for _, p in tendons])
    return dict(name=name, tendons=tendons, mirror=mirror,
                u_max=float(max(5e-4, round(U_MAX_FRACTION * rest / 5e-4) * 5e-4)))


def leg_motors(points: np.ndarray, tets: np.ndarray, legs: list[Leg] | None = None) -> list[dict]:
    """Two motors per leg (``<leg>_front``, ``<leg>_back``), each a tendon pair on that face;
    a left leg's motors mirror those of the right leg opposite it (same place in x)."""
    mesh = TetMesh(points, tets)
    legs = find_legs(points, tets) if legs is None else legs
    heights = np.asarray(TENDON_HEIGHTS) * np.ptp(points[:, 1]) + points[:, 1].min()
    length = np.ptp(points[:, 0])
    mirror_of: dict[str, str] = {}
    for g in legs:
        if "left" in g.name:
            opp = [h for h in legs if "right" in h.name]
            if opp:
                d = [np.hypot(h.centre[0] - g.centre[0], h.centre[1] + g.centre[1]) for h in opp]
                h = opp[int(np.argmin(d))]
                if min(d) < 0.15 * length and h.name not in mirror_of:
                    mirror_of[g.name], mirror_of[h.name] = h.name, g.name
    motors = []
    for g in legs:
        for face in ("front", "back"):
            other = mirror_of.get(g.name)
            motors.append(_motor(mesh, f"{g.name}_{face}", g, face, heights,
                                 f"{other}_{face}" if other else None))
    return motors


def example_motors(points: np.ndarray, tets: np.ndarray) -> list[dict]:
    """One worked example: a tendon pair on the front face of the front-most leg."""
    legs = find_legs(points, tets)
    x_front = max(g.centre[0] for g in legs)
    front = min((g for g in legs if g.centre[0] >= x_front - 0.1 * np.ptp(points[:, 0])), key=lambda g: g.name)
    heights = np.asarray(TENDON_HEIGHTS) * np.ptp(points[:, 1]) + points[:, 1].min()
    return [_motor(TetMesh(points, tets), f"{front.name}_front", front, "front", heights, None)]


def _pts(pts) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{c:.5g}" for c in p) + "]" for p in pts) + "]"


def skeleton_text(name: str, mesh_file: str, points: np.ndarray, tets: np.ndarray, motors: list[dict], *,
                  source: str = "", density: float = 220.0, youngs_modulus: float = 1.0e5,
                  poisson_ratio: float = 0.3, payload_mass: float | None = None) -> str:
    """The text of a commented robot.toml for a mesh in the robot frame (metres)."""
    mesh = TetMesh(points, tets)
    volume = float(mesh.volumes.sum())
    body = density * volume
    payload = 1.5 * body if payload_mass is None else float(payload_mass)
    depth = np.sort(points[:, 1].max() - points[:, 1])
    top_tol = max(1e-4, float(depth[min(3, len(depth) - 1)]) + 1e-6)     # at least 4 top nodes
    n_top = int((depth <= top_tol).sum())
    lines = [
        f"# {name}: robot description made by `trajopt mesh`{f' from {source}' if source else ''}.",
        f"# Mesh {mesh_file}: {mesh.n_nodes} nodes, {mesh.n_tets} tets, volume {volume:.4e} m^3, in the robot",
        "# frame (metres, +y up, facing +x, lowest point at y = 0, left is -z). Edit the numbers, then",
        "# `trajopt check robot.toml` validates the file and draws the mesh, its tendons and payload nodes.",
        "", "[robot]", f'name = "{name}"', f'mesh = "{mesh_file}"',
        f"body_length = {np.ptp(points[:, 0]):.4g}   # [m], speeds are in body lengths per minute",
        'forward_axis = "+x"', 'up_axis = "+y"', "scale = 1.0",
        "", "[material]   # compressible neo-Hookean (paper eq. 1)",
        f"youngs_modulus = {youngs_modulus:.4g}   # [Pa]. Coarse meshes stiffen numerically (paper II-A): fit E",
        "#   on THIS mesh so that simulation matches the real body (a leg's sag under a known weight, the",
        "#   bend from one cable contraction) instead of the foam's datasheet value. The shipped robots use",
        "#   1e5 Pa on ~200-node meshes; a finer mesh of the same foam needs a larger E.",
        f"poisson_ratio = {poisson_ratio:g}   # foams are compressible: 0.2-0.35",
        f"density = {density:.4g}   # [kg/m^3] = cast body mass / {volume:.4e} m^3; this gives {1e3 * body:.1f} g",
        "", "[payload]   # motor assembly (motors, spools, platform) on the top nodes (paper II-A)",
        f"mass = {payload:.4g}   # [kg]; default 1.5 x body mass, like the paper's robots (Puppy 140 g on 90 g)",
        'nodes = "top"   # or a list of node indices',
        f"top_tolerance = {top_tol:.3g}   # [m] nodes this close to the highest point carry it ({n_top} nodes)",
        "", "[contact]   # penalty ground contact; stiffness and friction act per contact node (docs/contact.md)",
        'model = "coulomb"   # Coulomb friction, feet that stick (the default); "paper": the paper\'s law (II-C)',
        "stiffness = 2000.0   # [N/m]: more nodes on the ground make a stiffer ground",
        "friction = 1000.0   # [1/m] the paper law's friction weight mu_f (shipped robots: 1000)",
        "blend = 5e-4   # [m] smoothing width of the contact onset",
        "friction_coefficient = 0.8   # Coulomb's mu (foam on a table)",
        "slip_distance = 3e-4   # [m] offset from its stick anchor at which a node slides (Coulomb)",
        "", "[cables]", "blend = 2e-4   # [m] smoothing of a cable going slack",
        "", "# Tendons: polylines through points (robot frame, metres) that must lie inside the body; each is",
        "# bound to the tet containing each point. A motor winds all its tendons by the same contraction u",
        "# in [u_min, u_max] (a tendon pair: two parallel cables, so the leg bends without twisting).",
        "# `mirror` names the motor on the other side (left <-> right) for symmetric gaits.",
        "# Template (copy, uncomment, edit):",
        "# [[tendons]]", '# name = "fore_left_front_a"', "# points = [[0.12, 0.004, -0.03], [0.12, 0.05, -0.03]]",
        "# stiffness = 1e5        # [N/m]", "# rest_length = 0.045    # [m] optional: default the polyline's length",
        "# [[motors]]", '# name = "fore_left_front"', '# tendons = ["fore_left_front_a", "fore_left_front_b"]',
        '# mirror = "fore_right_front"', "# u_min = 0.0",
        "# u_max = 0.016          # [m] about a third of the tendon length",
        "# spool_radius = 0.005   # [m] u = radius * motor angle",
        "# max_speed_rpm = 100.0  # [rpm] no-load output speed (default: Pololu 298:1 HP, 6 V)",
        "# stall_torque = 0.39    # [N m] torque at which the motor stalls (default: 298:1 HP, 6 V)",
        "# max_torque = 0.196     # [N m] the gearbox's limit (default: Pololu's 2 kg cm)", "",
    ]
    for m in motors:
        for tname, pts in m["tendons"]:
            lines += ["[[tendons]]", f'name = "{tname}"', f"points = {_pts(pts)}", "stiffness = 1e5", ""]
    for m in motors:
        names = ", ".join(f'"{t}"' for t, _ in m["tendons"])
        lines += ["[[motors]]", f'name = "{m["name"]}"', f"tendons = [{names}]"]
        if m.get("mirror"):
            lines.append(f'mirror = "{m["mirror"]}"')
        lines += ["u_min = 0.0", f"u_max = {m['u_max']:.4g}", "spool_radius = 0.005",
                  f"max_speed_rpm = {DEFAULT_MAX_SPEED_RPM}", ""]
    return "\n".join(lines)


def write_robot_toml(path: str | Path, text: str, overwrite: bool = False) -> Path:
    """Write ``text`` to ``path`` atomically after checking that it loads; never replaces a file
    the user may have edited unless ``overwrite``."""
    from .sim.robot_file import load_robot

    path = Path(path)
    if path.exists() and not overwrite:
        raise ValueError(f"{path}: exists already (it may hold your edits); pass --force to replace it")
    tmp = path.with_name(f".{path.stem}.tmp.toml")
    tmp.write_text(text)
    try:
        load_robot(tmp)
    except ValueError:
        tmp.unlink()
        raise
    os.replace(tmp, path)
    return path


def make_robot(surface: str | Path, out: str | Path, *, name: str | None = None, scale: float = 1.0,
               forward: str = "+x", up: str = "+y", edge_length: float | None = None, remesh: bool = True,
               tendons: str = "example", overwrite: bool = False, max_elements: int | None = None,
               on_estimate=None, **material):
    """Mesh a closed surface and write ``out/<name>.vtu`` and ``out/robot.toml`` (the skeleton with
    the example tendon pair, or with ``tendons="legs"`` a pair on each face of every leg).
    ``material``: ``density``, ``youngs_modulus``, ``poisson_ratio``, ``payload_mass`` of
    :func:`skeleton_text`. Returns ``(MeshResult, vtu path, toml path)``; nothing is written
    when the surface is refused or robot.toml exists (unless ``overwrite``). ``max_elements`` and
    ``on_estimate``: as in :func:`soft_envs.meshing.mesh_surface` (None: its default cap)."""
    import meshio

    from .meshing import mesh_surface

    if tendons not in ("example", "legs"):
        raise ValueError(f"tendons must be 'example' or 'legs', got {tendons!r}")
    out = Path(out)
    name = name or Path(surface).stem
    toml = out / "robot.toml"
    if toml.exists() and not overwrite:
        raise ValueError(f"{toml}: exists already (it may hold your edits); pass --force to replace it")
    cap = {} if max_elements is None else {"max_elements": max_elements}
    result = mesh_surface(surface, scale=scale, forward=forward, up=up, edge_length=edge_length, remesh=remesh,
                          on_estimate=on_estimate, **cap)
    motors = (leg_motors if tendons == "legs" else example_motors)(result.points, result.tets)
    text = skeleton_text(name, f"{name}.vtu", result.points, result.tets, motors, source=Path(surface).name,
                         **material)
    out.mkdir(parents=True, exist_ok=True)
    vtu = out / f"{name}.vtu"
    tmp = out / f".{name}.tmp.vtu"
    meshio.write(tmp, meshio.Mesh(result.points, [("tetra", result.tets)]))
    os.replace(tmp, vtu)
    write_robot_toml(toml, text, overwrite=overwrite)
    return result, vtu, toml
