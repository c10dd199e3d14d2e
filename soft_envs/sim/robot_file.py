"""Robot description files (``robot.toml``), read with :mod:`tomllib`.

Format (all lengths in the mesh file's units times ``robot.scale``, then SI)::

    [robot]
    name = "puppy"
    mesh = "puppy.vtu"           # any tetrahedral format meshio reads; relative to this file
    body_length = 0.13           # [m], optional (default: extent along the forward axis)
    forward_axis = "+x"          # mesh axis pointing forward: +x -x +y -y +z -z
    up_axis = "+y"               # mesh axis pointing up
    scale = 1.0                  # mesh units -> metres (0.001 for millimetres)

    [material]                   # compressible neo-Hookean, paper eq. 1
    youngs_modulus = 1.2e5       # [Pa]
    poisson_ratio = 0.3
    density = 220.0              # [kg/m^3]

    [payload]                    # motor assembly, spread over the top nodes (paper II-A)
    mass = 0.140                 # [kg]
    nodes = "top"                # "top" or a list of node indices
    top_tolerance = 1e-4         # [m] nodes this close to the highest point are "top"

    [contact]                    # optional, defaults of ContactParams; each law reads its own keys
    model = "coulomb"            # a contact law (soft_envs.sim.contact.CONTACT_LAWS): "coulomb" (mu N
                                 # bound; the shipped robots') or "paper" (II-C, viscous-like; the
                                 # default of a file without model, so older files keep their law)
    stiffness = 2000.0           # [N/m]
    friction = 500.0             # [1/m]
    blend = 5e-4                 # [m] C2 blend of the normal law (0: half-quadratic, coulomb)
    friction_coefficient = 0.8   # Coulomb's mu (model = "coulomb")
    slip_distance = 3e-4         # [m] offset from its stick anchor at which a node slides (coulomb)

    [ground]                     # optional: the ground's height field (soft_envs.sim.ground.ground_from_table:
    type = "rough"               # flat, incline, step, trench, rough or grid and its keys); absent: y = 0
    amplitude = 0.002            # [m] RMS height, with wavelength = 0.05 [m]

    [fixed]                      # optional: clamped nodes
    nodes = [0, 1, 2]            # and/or box = [[x0, x1], [y0, y1], [z0, z1]] (mesh frame and units)

    [[material.regions]]         # optional, written by co-design: Young's modulus per set of tets
    name = "middle_leg"
    youngs_modulus = 2.4e5       # [Pa]
    tets = [12, 13, 14]          # indices into the mesh's tets

    [cables]
    blend = 2e-4                 # [m] width of the one-sided quadratic's C2 blend (0: half-quadratic)

    [[tendons]]
    name = "fore_left_front_a"
    points = [[0.128, 0.005, 0.005], [0.128, 0.05, 0.005]]   # mesh frame, inside the body
    stiffness = 1e5              # [N/m]
    # rest_length = 0.045        # assembly length alpha0 [m]; default: rest polyline length

    [[markers]]                  # optional: tracked points (trajopt calibrate), bound like tendon points
    name = "nose"
    point = [0.13, 0.03, 0.02]   # mesh frame, inside the body or on its surface

    [[motors]]
    name = "fore_left_front"
    tendons = ["fore_left_front_a", "fore_left_front_b"]
    mirror = "fore_right_front"  # optional, must be an involution
    u_min = 0.0                  # [m]
    u_max = 0.008                # [m]
    spool_radius = 0.005         # [m]
    max_speed_rpm = 100.0        # [rpm] no-load output speed (default 100: Pololu 298:1 HP, 6 V);
                                 # the contraction moves at most max_speed_rpm * 2 pi / 60 * spool_radius
    stall_torque = 0.39          # [N m] where the torque-speed line reaches zero speed (default: 298:1 HP, 6 V)
    max_torque = 0.196           # [N m] the gearbox's limit (default: Pololu's 2 kg cm); the law:
                                 # soft_envs.sim.motors (docs/robots.md)

    [design]                     # optional: what co-design may change (soft_envs.sim.design;
    routing = ["fore_left_front_a"]   # absent: the robot is fixed); see docs/codesign.md
    hip_height = 0.03            # legs: connected parts below it (above the lowest node) vary in length
    [[design.regions]]           # Young's modulus per region: boxes or a mesh cell tag
    name = "legs"
    boxes = [[0.0, 0.0, 0.0, 0.13, 0.03, 0.08]]   # [x0, y0, z0, x1, y1, z1], mesh frame

Every error is a ``ValueError`` that names the file and the field: a file that is not UTF-8,
not TOML, an unknown or missing key, a value of the wrong type, and any number that is not
finite (TOML's ``inf`` and ``nan``).

:func:`~soft_envs.sim.fingerprint.robot_fingerprint` (its own module) identifies a robot
description (its ``robot.toml`` and mesh, normalised) so that a gait can be tied to the robot it
was made for.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from .mesh import TetMesh, load_mesh
from .ground import ground_from_table
from .robot import MOTOR_DEFAULTS, ContactParams, Marker, Motor, Robot, Tendon

__all__ = ["load_robot", "asset_path", "robot_file_path", "robot_document", "read_robot_toml", "SHIPPED_ROBOTS"]

SHIPPED_ROBOTS = ("tripod", "puppy", "hexapod", "inchworm")

_SCHEMA: dict[str, dict[str, tuple[type | tuple[type, ...], bool]]] = {
    "robot": {"name": (str, True), "mesh": (str, True), "body_length": ((int, float), False),
              "forward_axis": (str, False), "up_axis": (str, False), "scale": ((int, float), False),
              "description": (str, False)},
    "material": {"youngs_modulus": ((int, float), True), "poisson_ratio": ((int, float), True),
                 "density": ((int, float), True), "regions": (list, False)},
    "payload": {"mass": ((int, float), True), "nodes": ((str, list), False),
                "top_tolerance": ((int, float), False)},
    # [contact]: the fields of ContactParams (model and the keys the contact laws read)
    "contact": {f.name: ((str if f.name == "model" else (int, float)), False)
                for f in dataclasses.fields(ContactParams)},
    "fixed": {"nodes": (list, False), "box": (list, False)},
    "cables": {"blend": ((int, float), False)},
}
_TENDON = {"name": (str, True), "points": (list, True), "stiffness": ((int, float), False),
           "rest_length": ((int, float), False)}
_MARKER = {"name": (str, True), "point": (list, True)}
_MOTOR = {"name": (str, True), "tendons": (list, True), "mirror": (str, False),
          "u_min": ((int, float), False), "u_max": ((int, float), True),
          "spool_radius": ((int, float), False), "max_speed_rpm": ((int, float), False),
          "stall_torque": ((int, float), False), "max_torque": ((int, float), False)}
_AXES = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0), "+z": (2, 1.0), "-z": (2, -1.0)}


def asset_path(name: str) -> Path:
    """Path of a shipped robot's ``robot.toml``."""
    here = Path(__file__).resolve()
    candidates = [here.parents[2] / "assets" / name / "robot.toml"]
    try:
        from importlib.resources import files
        candidates.append(Path(str(files("soft_envs.assets") / name / "robot.toml")))
    except (ModuleNotFoundError, TypeError):
        pass
    for c in candidates:
        if c.is_file():
            return c
    raise ValueError(f"unknown robot {name!r}: not a shipped robot {SHIPPED_ROBOTS} nor a robot.toml path")


def _check_table(table: Any, schema: dict, where: str, src: str) -> dict:
    if not isinstance(table, dict):
        raise ValueError(f"{src}: {where} must be a table")
    for key in table:
        if key not in schema:
            raise ValueError(f"{src}: unknown key {where}.{key} (allowed: {', '.join(schema)})")
    for key, (typ, required) in schema.items():
        if key not in table:
            if required:
                raise ValueError(f"{src}: {where}.{key} is missing")
            continue
        v = table[key]
        if isinstance(v, bool) or not isinstance(v, typ):
            raise ValueError(f"{src}: {where}.{key} has the wrong type ({type(v).__name__})")
    return table


def _frame(robot_tbl: dict, src: str) -> np.ndarray:
    fwd = robot_tbl.get("forward_axis", "+x")
    up = robot_tbl.get("up_axis", "+y")
    for key, v in (("forward_axis", fwd), ("up_axis", up)):
        if v not in _AXES:
            raise ValueError(f"{src}: [robot].{key} must be one of {list(_AXES)}, got {v!r}")
    f = np.zeros(3)
    f[_AXES[fwd][0]] = _AXES[fwd][1]
    u = np.zeros(3)
    u[_AXES[up][0]] = _AXES[up][1]
    if abs(f @ u) > 0:
        raise ValueError(f"{src}: [robot].forward_axis and up_axis must be different axes")
    return np.stack([f, u, np.cross(f, u)])     # rows: sim x, y, z in mesh coordinates


def _to_sim(robot_tbl: dict, src: str):
    """``(to_sim, R)``: the map of file coordinates (scaled by [robot].scale) to the simulation
    frame, and the frame's rotation."""
    scale = float(robot_tbl.get("scale", 1.0))
    if not scale > 0:
        raise ValueError(f"{src}: [robot].scale must be positive")
    R = _frame(robot_tbl, src)
    return (lambda q: scale * np.asarray(q, dtype=np.float64) @ R.T), R


def robot_document(name_or_path: str | Path) -> tuple[dict[str, Any], Any]:
    """The parsed robot.toml of ``name_or_path`` and its map from file coordinates to the
    simulation frame (for tables read outside :func:`load_robot`, e.g. ``[design]``)."""
    path = robot_file_path(name_or_path)
    doc = read_robot_toml(path)
    return doc, _to_sim(doc.get("robot", {}), str(path))[0]


def robot_file_path(name_or_path: str | Path) -> Path:
    """The ``robot.toml`` of a shipped robot name or a path (which must exist)."""
    p = Path(name_or_path)
    path = p if (p.suffix == ".toml" or p.is_file()) else asset_path(str(name_or_path))
    if not path.is_file():
        raise ValueError(f"{path}: robot file not found")
    return path


def read_robot_toml(path: Path) -> dict[str, Any]:
    """The parsed document of the robot.toml ``path``; not UTF-8, unreadable, not TOML or a non-finite number: a
    ValueError naming the file (and the field)."""
    src = str(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{src}: not UTF-8 text (TOML files must be UTF-8): byte {exc.object[exc.start]:#04x} "
                         f"at offset {exc.start}") from None
    except OSError as exc:
        raise ValueError(f"{src}: cannot be read ({exc.strerror or exc})") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{src}: not valid TOML: {exc}") from exc
    _check_finite(doc, src)
    return doc


def _check_finite(doc: dict[str, Any], src: str) -> None:
    """Every number of the document finite (TOML allows ``inf`` and ``nan``)."""
    def walk(v: Any, where: str) -> None:
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"{src}: {where} must be a finite number, got {v}")
        if isinstance(v, dict):
            for k, x in v.items():
                walk(x, f"{where}.{k}")
        elif isinstance(v, list):
            for i, x in enumerate(v):
                walk(x, f"{where}[{i}]")
    for key, value in doc.items():
        if isinstance(value, dict):
            for k, x in value.items():
                walk(x, f"[{key}].{k}")
        else:
            walk(value, key)


def load_robot(name_or_path: str | Path, **overrides: Any) -> Robot:
    """Load a shipped robot (:data:`SHIPPED_ROBOTS`) or a ``robot.toml`` path. ``overrides`` replace Robot
    fields afterwards (e.g. ``youngs_modulus=2e5``)."""
    path = robot_file_path(name_or_path)
    src = str(path)
    doc = read_robot_toml(path)
    allowed = set(_SCHEMA) | {"tendons", "motors", "markers", "design", "ground"}   # [design]: soft_envs.sim.design
    for key in doc:
        if key not in allowed:
            raise ValueError(f"{src}: unknown table [{key}] (allowed: {', '.join(sorted(allowed))})")
    for key in ("robot", "material"):
        if key not in doc:
            raise ValueError(f"{src}: table [{key}] is missing")
    tables = {k: _check_table(doc.get(k, {}), s, f"[{k}]", src) for k, s in _SCHEMA.items()}
    rt = tables["robot"]
    to_sim, R = _to_sim(rt, src)
    mesh_file = path.parent / rt["mesh"]
    if not mesh_file.is_file():
        raise ValueError(f"{src}: [robot].mesh file {str(mesh_file)!r} not found")
    raw = load_mesh(mesh_file)
    pts = to_sim(raw.points)
    tets = np.array(raw.tets)
    if np.linalg.det(R) < 0:   # cannot happen for a right-handed frame built by cross; keep safe
        tets = tets[:, [0, 2, 1, 3]]
    mesh = TetMesh(pts, tets, source=str(mesh_file))
    pay = tables["payload"]
    payload_nodes = _payload_nodes(pay, pts, src)
    fixed_nodes = _fixed_nodes(tables["fixed"], raw.points, mesh.n_nodes, src)
    tendons = _tendons(doc.get("tendons", []), to_sim, src)
    motors = _motors(doc.get("motors", []), src)
    markers = _markers(doc.get("markers", []), to_sim, src)
    mat = tables["material"]
    try:      # model: one of CONTACT_LAWS; each value within the bounds its law declares
        contact = ContactParams(**{k: (v if k == "model" else float(v)) for k, v in tables["contact"].items()})
    except ValueError as exc:
        raise ValueError(f"{src}: [contact] {exc}") from exc
    kwargs = dict(name=rt["name"], mesh=mesh, youngs_modulus=float(mat["youngs_modulus"]),
                  poisson_ratio=float(mat["poisson_ratio"]), density=float(mat["density"]),
                  tendons=tuple(tendons), motors=tuple(motors), payload_mass=float(pay.get("mass", 0.0)),
                  payload_nodes=payload_nodes if float(pay.get("mass", 0.0)) > 0 else np.zeros(0, np.int64),
                  fixed_nodes=fixed_nodes, contact=contact,
                  body_length=float(rt["body_length"]) if "body_length" in rt else None,
                  cable_blend=float(tables["cables"].get("blend", 2e-4)), source=src, markers=markers,
                  ground=ground_from_table(doc["ground"], src) if "ground" in doc else None)
    if "regions" in mat:
        kwargs["modulus_scale"] = _material_regions(mat["regions"], mesh, float(mat["youngs_modulus"]), src)
    kwargs.update(overrides)
    try:
        return Robot(**kwargs)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith(src) else f"{src}: {msg}") from exc


def _material_regions(raw: list, mesh: TetMesh, youngs_modulus: float, src: str) -> np.ndarray:
    """Per-tet factors on ``[material].youngs_modulus`` from ``[[material.regions]]`` tables
    (``name``, ``youngs_modulus`` [Pa], ``tets``: indices into the mesh's tets; written by
    co-design, :mod:`soft_envs.sim.design`). Regions may not overlap."""
    scale = np.ones(mesh.n_tets)
    seen = np.zeros(mesh.n_tets, dtype=bool)
    for i, r in enumerate(raw):
        where = f"[[material.regions]][{i}]"
        if not isinstance(r, dict):
            raise ValueError(f"{src}: {where} must be a table")
        _check_table(r, {"name": (str, True), "youngs_modulus": ((int, float), True), "tets": (list, True)}, where, src)
        tets = _index_list(r["tets"], f"{where}.tets", mesh.n_tets, src)
        if seen[tets].any():
            raise ValueError(f"{src}: {where} ({r['name']!r}) overlaps an earlier region")
        E = float(r["youngs_modulus"])
        if not E > 0:
            raise ValueError(f"{src}: {where}.youngs_modulus must be positive, got {E!r}")
        seen[tets] = True
        scale[tets] = E / youngs_modulus
    return scale


def _payload_nodes(pay: dict, pts: np.ndarray, src: str) -> np.ndarray:
    """``[payload].nodes``: ``"top"`` (the nodes within ``top_tolerance`` of the highest one, in
    the simulation frame) or a list of node indices."""
    nodes_spec = pay.get("nodes", "top")
    if isinstance(nodes_spec, str):
        if nodes_spec != "top":
            raise ValueError(f"{src}: [payload].nodes must be \"top\" or a list of node indices")
        tol = float(pay.get("top_tolerance", 1e-4))
        return np.flatnonzero(pts[:, 1] >= pts[:, 1].max() - tol)
    return _index_list(nodes_spec, "[payload].nodes", len(pts), src)


def _fixed_nodes(fixed: dict, mesh_points: np.ndarray, n_nodes: int, src: str) -> np.ndarray:
    """``[fixed]``: node indices and / or the nodes inside ``box`` (mesh frame and units)."""
    fixed_nodes = _index_list(fixed.get("nodes", []), "[fixed].nodes", n_nodes, src)
    if "box" in fixed:
        try:
            box = np.asarray(fixed["box"], dtype=np.float64)
        except (TypeError, ValueError):
            box = np.zeros(0)
        if box.shape != (3, 2):
            raise ValueError(f"{src}: [fixed].box must be [[x0, x1], [y0, y1], [z0, z1]] (mesh frame and units)")
        q = mesh_points            # mesh frame and units, like the tendon points
        inside = np.all((q >= box[:, 0] - 1e-12) & (q <= box[:, 1] + 1e-12), axis=1)
        fixed_nodes = np.union1d(fixed_nodes, np.flatnonzero(inside))
    return fixed_nodes


def _tendons(raw_t: Any, to_sim, src: str) -> list[Tendon]:
    """The ``[[tendons]]`` tables, their points mapped to the simulation frame by ``to_sim``."""
    if not isinstance(raw_t, list):
        raise ValueError(f"{src}: tendons must be an array of tables [[tendons]]")
    tendons = []
    for i, t in enumerate(raw_t):
        _check_table(t, _TENDON, f"tendons[{i}]", src)
        try:
            points = to_sim(np.asarray(t["points"], dtype=np.float64))
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{src}: tendons[{i}].points must be a list of [x, y, z]") from exc
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"{src}: tendons[{i}].points must be a list of [x, y, z]")
        tendons.append(Tendon(t["name"], points, float(t.get("stiffness", 1e5)),
                              None if "rest_length" not in t else float(t["rest_length"])))
    return tendons


def _motors(raw_m: Any, src: str) -> list[Motor]:
    """The ``[[motors]]`` tables."""
    if not isinstance(raw_m, list):
        raise ValueError(f"{src}: motors must be an array of tables [[motors]]")
    motors = []
    for i, m in enumerate(raw_m):
        _check_table(m, _MOTOR, f"motors[{i}]", src)
        if not all(isinstance(s, str) for s in m["tendons"]):
            raise ValueError(f"{src}: motors[{i}].tendons must be a list of tendon names")
        motors.append(Motor(m["name"], tuple(m["tendons"]), m.get("mirror"), float(m.get("u_min", 0.0)),
                            float(m["u_max"]), float(m.get("spool_radius", 0.005)),
                            **{key: float(m.get(key, default)) for key, default in MOTOR_DEFAULTS.items()}))
    return motors


def _markers(raw: Any, to_sim, src: str) -> tuple[Marker, ...]:
    """The ``[[markers]]`` tables as markers in the simulation frame."""
    if not isinstance(raw, list):
        raise ValueError(f"{src}: markers must be an array of tables [[markers]]")
    out = []
    for i, m in enumerate(raw):
        _check_table(m, _MARKER, f"markers[{i}]", src)
        try:
            p = to_sim(np.asarray(m["point"], dtype=np.float64))
        except (ValueError, TypeError):
            p = np.zeros(0)
        if p.shape != (3,):
            raise ValueError(f"{src}: markers[{i}] ({m['name']!r}).point must be [x, y, z]")
        out.append(Marker(m["name"], p))
    return tuple(out)


def _index_list(values: Any, where: str, n: int, src: str) -> np.ndarray:
    if not isinstance(values, list) or not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        raise ValueError(f"{src}: {where} must be a list of integer node indices")
    arr = np.asarray(values, dtype=np.int64)
    if arr.size and (arr.min() < 0 or arr.max() >= n):
        raise ValueError(f"{src}: {where} has indices outside 0..{n - 1}")
    return arr
