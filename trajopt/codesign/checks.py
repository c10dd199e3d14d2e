"""The independent check of a co-designed robot folder: every constraint must hold
in the written files, checked independently of the optimiser.

:func:`check_designed_robot` reads the written files themselves (the robot.toml through
:mod:`tomllib`, the mesh through :mod:`meshio`), not the optimiser's objects, and computes every
quantity here:

* **same motors**: the ``[[motors]]`` tables equal the source's (name, tendons, mirror, u_min,
  u_max, spool_radius, max_speed_rpm, stall_torque, max_torque; a missing key as its default) and
  the ``[[tendons]]`` keep their names, stiffness and number of points;
* **total mass**: tet volumes of the mesh file times ``[material].density`` (file units times
  ``[robot].scale`` cubed: SI, as :mod:`soft_envs.sim.robot_file` scales lengths) plus
  ``[payload].mass``, at least ``mass_floor`` times the source's;
* **moduli**: each ``[[material.regions]]`` table's ``youngs_modulus`` over the source's
  ``[material].youngs_modulus`` within ``modulus_bounds`` (default: the source's
  ``[design].modulus_bounds``, else 0.3 to 3), each tet in at most one region, and the base
  material (modulus, Poisson ratio, density) and the payload unchanged;
* **clearance**: every tendon via point at least ``min_clearance`` inside the body (to
  :data:`CLEARANCE_TOL`), except the points ``[design].fixed_points`` names (the designed
  file's, else the source's; default: the last, where the tendon leaves the body to its motor),
  which must lie inside or on the surface. The distance is this module's own: boundary
  triangles of the written mesh (tet faces used once), the point projected onto each triangle's
  plane (inside the triangle: the distance to the plane, else the nearest of its three edges),
  inside or outside by a containing tet (barycentric coordinates);
* **loads and simulates**: the folder loads (:func:`~soft_envs.sim.load_robot`, through
  :func:`~soft_envs.envs.make_gradient_env`) and a few environment steps run.

:func:`format_checks` gives the markdown table, :func:`require_design_checks` raises
:class:`DesignCheckError` listing the failures.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np

__all__ = ["DesignCheck", "DesignCheckError", "check_designed_robot", "format_checks", "require_design_checks",
           "signed_clearance", "boundary_triangles", "CLEARANCE_TOL", "DEFAULT_MODULUS_BOUNDS"]

#: slack of the clearance check [m]: the shipped robots' via points sit at exactly 2 mm
CLEARANCE_TOL = 1e-9
#: the moduli's bounds (factors of the fitted modulus) when the source declares none
DEFAULT_MODULUS_BOUNDS = (0.3, 3.0)
#: relative slack of the modulus bounds and the mass floor (round-off of the written numbers)
_REL_TOL = 1e-12
#: a ``[[motors]]`` key's value when absent (written independently of the loader; the motor's own
#: numbers are ``soft_envs.envs.MOTOR_DEFAULTS``, tests/test_motor_model.py pins the two)
_MOTOR_DEFAULTS = {"mirror": None, "u_min": 0.0, "spool_radius": 0.005, "max_speed_rpm": 100.0,
                   "stall_torque": 0.39, "max_torque": 0.196}


@dataclass(frozen=True)
class DesignCheck:
    """One constraint on the written robot: ``value`` against ``limit`` (SI units, ``unit``)."""

    name: str
    passed: bool
    value: float | str
    limit: float | str
    detail: str
    unit: str = ""


class DesignCheckError(ValueError):
    """A designed robot breaks constraints; ``checks`` are the failed ones."""

    def __init__(self, checks: list[DesignCheck]):
        self.checks = list(checks)
        lines = [f"  {c.name}: {c.detail}" for c in self.checks]
        super().__init__(f"the designed robot breaks {len(self.checks)} constraint(s):\n" + "\n".join(lines))


def _robot_toml(path: str | Path) -> Path:
    """The robot.toml of a path, a folder or a shipped robot's name."""
    p = Path(path)
    if not p.exists() and p.suffix == "" and len(p.parts) == 1:
        from soft_envs.envs import load_robot        # a shipped robot's name (else its ValueError)
        return Path(load_robot(str(path)).source)
    if p.is_dir():
        p = p / "robot.toml"
    if not p.is_file():
        raise ValueError(f"{p}: robot file not found")
    return p


def _read(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot be read as TOML: {exc}") from exc


@dataclass(frozen=True)
class _Body:
    """A robot file's tets and lengths in the file's frame; ``scale``: file units -> metres."""

    file: Path
    doc: dict
    points: np.ndarray
    tets: np.ndarray
    scale: float

    @classmethod
    def read(cls, file: Path) -> "_Body":
        doc = _read(file)
        for table, key in (("robot", "mesh"), ("material", "youngs_modulus"), ("material", "density")):
            if not isinstance(doc.get(table), dict) or key not in doc[table]:
                raise ValueError(f"{file}: [{table}].{key} is missing")
        for table, key in (("material", "youngs_modulus"), ("material", "density"), ("robot", "scale"),
                           ("payload", "mass")):
            v = doc.get(table, {}).get(key, 1.0)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise ValueError(f"{file}: [{table}].{key} must be a non-negative number, got {v!r}")
        mesh_file = file.parent / str(doc["robot"]["mesh"])
        try:
            m = meshio.read(mesh_file)
        except Exception as exc:    # meshio raises many types
            raise ValueError(f"{file}: [robot].mesh {str(mesh_file)!r} cannot be read: {exc}") from exc
        blocks = [c.data for c in m.cells if c.type == "tetra"]
        if not blocks:
            raise ValueError(f"{file}: the mesh {str(mesh_file)!r} has no tetra cells")
        scale = float(doc["robot"].get("scale", 1.0))
        return cls(file, doc, np.asarray(m.points, dtype=np.float64), np.concatenate(blocks).astype(np.int64), scale)

    @property
    def volumes(self) -> np.ndarray:
        """Tet volumes [m^3]."""
        x = self.points[self.tets]
        return np.abs(np.linalg.det(x[:, 1:] - x[:, :1])) / 6.0 * self.scale ** 3

    @property
    def total_mass(self) -> float:
        """Body (density x volume) plus payload [kg]."""
        return float(self.doc["material"]["density"]) * float(self.volumes.sum()) + \
            float(self.doc.get("payload", {}).get("mass", 0.0))


def boundary_triangles(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tet faces used by one tet only (f, 3), and that tet of each (f,)."""
    faces = np.asarray(tets)[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3)
    _, first, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    once = np.sort(first[counts == 1])
    return faces[once], once // 4


def _segment_distances(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.einsum("ij,ij->i", ab, ab), 0.0, 1.0)
    return np.linalg.norm(q - (a + t[:, None] * ab), axis=1)


def _contains(points: np.ndarray, tets: np.ndarray, q: np.ndarray, tol: float = 1e-12) -> bool:
    """Whether a tet contains ``q``: its barycentric coordinates all >= -tol."""
    x = points[tets]
    T = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))           # columns x1-x0, x2-x0, x3-x0
    ok = np.abs(np.linalg.det(T)) > 0
    lam = np.linalg.solve(T[ok], (q - x[ok, 0])[..., None])[..., 0]
    bary = np.column_stack([1.0 - lam.sum(axis=1), lam])
    return bool((bary >= -tol).all(axis=1).any())


def signed_clearance(points: np.ndarray, tets: np.ndarray, q: np.ndarray,
                     triangles: np.ndarray | None = None) -> float:
    """Distance of ``q`` to the boundary surface of the tet mesh (``points``, ``tets``), positive
    inside, in the mesh's units: the point projected onto each boundary triangle's plane; inside
    the triangle the distance to the plane, else the nearest of the triangle's three edges."""
    tri = boundary_triangles(tets)[0] if triangles is None else triangles
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    h = np.einsum("ij,ij->i", q - a, n)
    p = q - h[:, None] * n                                       # projection onto the plane
    inside = np.ones(len(tri), bool)
    for u, v in ((a, b), (b, c), (c, a)):                        # same side of every edge as the normal
        inside &= np.einsum("ij,ij->i", np.cross(v - u, p - u), n) >= 0
    edges = np.minimum.reduce([_segment_distances(q[None].repeat(len(tri), 0), u, v)
                               for u, v in ((a, b), (b, c), (c, a))])
    d = float(np.where(inside, np.abs(h), edges).min())
    return d if _contains(points, tets, q) else -d


def check_designed_robot(source: str | Path, designed: str | Path, *, min_clearance: float = 0.002,
                         mass_floor: float = 0.98, modulus_bounds: tuple[float, float] | None = None,
                         simulate_steps: int = 3) -> list[DesignCheck]:
    """Every co-design constraint checked on the written files of ``designed`` (a robot.toml or
    its folder) against ``source`` (the robot it was designed from: also a shipped robot's name)."""
    src, out = _Body.read(_robot_toml(source)), _Body.read(_robot_toml(designed))
    if modulus_bounds is None:
        modulus_bounds = tuple(src.doc.get("design", {}).get("modulus_bounds", DEFAULT_MODULUS_BOUNDS))
    return [*_motor_checks(src, out), _mass_check(src, out, mass_floor), *_material_checks(src, out, modulus_bounds),
            *_clearance_checks(out, _fixed_points(out, src), min_clearance), _simulation_check(out.file, simulate_steps)]


def _fixed_points(*bodies: _Body) -> list[int]:
    """``[design].fixed_points`` of the first body that states it, else ``[-1]`` (the last point)."""
    for body in bodies:
        fixed = body.doc.get("design", {}).get("fixed_points")
        if fixed is not None:
            if not (isinstance(fixed, list) and all(isinstance(i, int) and not isinstance(i, bool) for i in fixed)):
                raise ValueError(f"{body.file}: [design].fixed_points must be a list of point indices, got {fixed!r}")
            return fixed
    return [-1]


def _motor_checks(src: _Body, out: _Body) -> list[DesignCheck]:
    def motors(body):
        return [{**_MOTOR_DEFAULTS, **m} for m in body.doc.get("motors", [])]

    a, b = motors(src), motors(out)
    problems = []
    if [m.get("name") for m in a] != [m.get("name") for m in b]:
        problems.append(f"motors {[m.get('name') for m in b]} instead of {[m.get('name') for m in a]}")
    else:
        for ma, mb in zip(a, b):
            for key in sorted(set(ma) | set(mb)):
                if ma.get(key) != mb.get(key):
                    problems.append(f"motor {ma['name']!r}: {key} = {mb.get(key)!r} instead of {ma.get(key)!r}")
    tendon_problems = []
    ta, tb = src.doc.get("tendons", []), out.doc.get("tendons", [])
    if [t.get("name") for t in ta] != [t.get("name") for t in tb]:
        tendon_problems.append(f"tendons {[t.get('name') for t in tb]} instead of {[t.get('name') for t in ta]}")
    else:
        for x, y in zip(ta, tb):
            if x.get("stiffness", 1e5) != y.get("stiffness", 1e5):
                tendon_problems.append(f"tendon {x['name']!r}: stiffness {y.get('stiffness', 1e5)!r} instead of "
                                       f"{x.get('stiffness', 1e5)!r}")
            if len(x.get("points", [])) != len(y.get("points", [])):
                tendon_problems.append(f"tendon {x['name']!r}: {len(y.get('points', []))} points instead of "
                                       f"{len(x.get('points', []))}")
    return [DesignCheck("same motors", not problems, len(b), len(a),
                        f"{out.file}: " + "; ".join(problems) if problems else f"{len(b)} motors as in {src.file}"),
            DesignCheck("same tendons", not tendon_problems, len(tb), len(ta),
                        f"{out.file}: " + "; ".join(tendon_problems) if tendon_problems
                        else f"{len(tb)} tendons: names, stiffness and number of points as in {src.file}")]


def _mass_check(src: _Body, out: _Body, mass_floor: float) -> DesignCheck:
    m0, m1 = src.total_mass, out.total_mass
    ok = m1 >= mass_floor * m0 * (1 - _REL_TOL)
    return DesignCheck("total mass", ok, m1, mass_floor * m0,
                       f"{out.file}: {1e3 * m1:.4f} g = {100 * m1 / m0:.3f} % of the source's {1e3 * m0:.4f} g "
                       f"(floor {100 * mass_floor:g} %)", "kg")


def _material_checks(src: _Body, out: _Body, bounds) -> list[DesignCheck]:
    lo, hi = (float(v) for v in bounds)
    mat0, mat1 = src.doc["material"], out.doc["material"]
    E0 = float(mat0["youngs_modulus"])
    regions = mat1.get("regions", [])
    worst, bad, factors = None, [], []
    owner = np.full(len(out.tets), -1)
    overlap = []
    for i, r in enumerate(regions):
        name = r.get("name", f"#{i}") if isinstance(r, dict) else f"#{i}"
        E, tets = (r.get("youngs_modulus"), r.get("tets")) if isinstance(r, dict) else (None, None)
        if isinstance(E, bool) or not isinstance(E, (int, float)) or not (isinstance(tets, list) and all(
                isinstance(t, int) and not isinstance(t, bool) for t in tets)):
            bad.append(f"region {name!r}: needs a youngs_modulus (number) and tets (list of tet indices)")
            continue
        f = float(E) / E0
        factors.append(f)
        if not (lo * (1 - _REL_TOL) <= f <= hi * (1 + _REL_TOL)):
            bad.append(f"region {name!r}: youngs_modulus {float(r['youngs_modulus']):.6g} Pa = {f:.4g} x "
                       f"{E0:.6g} Pa outside [{lo:g}, {hi:g}]")
        tets = np.asarray(tets, dtype=np.int64)
        if tets.size and (tets.min() < 0 or tets.max() >= len(out.tets)):
            overlap.append(f"region {name!r}: tet indices outside 0..{len(out.tets) - 1}")
            continue
        again = tets[owner[tets] >= 0]
        if again.size:
            overlap.append(f"region {name!r}: tet {int(again[0])} also in {regions[owner[again[0]]].get('name')!r}")
        owner[tets] = i
    if factors:
        worst = max(factors, key=lambda f: max(f / hi, lo / f))
    changed = [f"{k} = {mat1.get(k)!r} instead of {mat0.get(k)!r}"
               for k in ("youngs_modulus", "poisson_ratio", "density") if mat0.get(k) != mat1.get(k)]
    if src.doc.get("payload", {}) != out.doc.get("payload", {}):
        changed.append(f"[payload] = {out.doc.get('payload')!r} instead of {src.doc.get('payload')!r}")
    return [DesignCheck("moduli within bounds", not bad, "-" if worst is None else worst, f"[{lo:g}, {hi:g}]",
                        f"{out.file}: " + "; ".join(bad) if bad
                        else f"{len(regions)} regions, factors {', '.join(f'{f:.3g}' for f in factors) or 'none'}",
                        "x fitted E"),
            DesignCheck("regions disjoint", not overlap, len(regions), "-",
                        f"{out.file}: " + "; ".join(overlap) if overlap else "each tet in at most one region"),
            DesignCheck("base material and payload unchanged", not changed, "-", "-",
                        f"{out.file}: " + "; ".join(changed) if changed
                        else f"E = {E0:.6g} Pa, density {mat0['density']} kg/m^3, payload as in {src.file}")]


def _clearance_checks(out: _Body, fixed: list[int], min_clearance: float) -> list[DesignCheck]:
    tri = boundary_triangles(out.tets)[0]
    free, ends = [], []
    for i, t in enumerate(out.doc.get("tendons", [])):
        try:
            pts = np.asarray(t["points"], dtype=np.float64).reshape(-1, 3)
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"{out.file}: tendons[{i}].points must be a list of [x, y, z]") from None
        keep = {i % len(pts) for i in fixed}
        for s, q in enumerate(pts):
            d = out.scale * signed_clearance(out.points, out.tets, q, tri)
            (ends if s in keep else free).append((d, f"{t['name']}[{s}]"))
    low = [(d, w) for d, w in free if d < min_clearance - CLEARANCE_TOL]
    out_ = [(d, w) for d, w in ends if d < -CLEARANCE_TOL]
    dmin = min(free)[0] if free else math.inf
    emin = min(ends)[0] if ends else math.inf
    where = lambda bad: "; ".join(f"tendon point {w} at {1e3 * d:.4f} mm" for d, w in sorted(bad))  # noqa: E731
    return [DesignCheck("via points inside by the clearance", not low, dmin, min_clearance,
                        f"{out.file}: " + where(low) if low else f"{len(free)} via points, the closest "
                        f"{min(free)[1] if free else '-'} at {1e3 * dmin:.4f} mm from the surface", "m"),
            DesignCheck("fixed points in the body", not out_, emin, 0.0,
                        f"{out.file}: " + where(out_) + " (outside the body)" if out_
                        else f"{len(ends)} fixed points (fixed_points = {fixed}) inside or on the surface", "m")]


def _simulation_check(file: Path, steps: int) -> DesignCheck:
    from soft_envs.envs import make_gradient_env
    try:
        env = make_gradient_env(file)        # load_robot, the rest state
        low, high = env.action_space.low, env.action_space.high
        obs = [env.step(low + 0.25 * (high - low))[0] for _ in range(steps)]
        ok = bool(np.isfinite(np.asarray(obs, dtype=np.float64)).all())
        detail = f"load_robot and {steps} steps at a quarter of each motor's range" if ok else "non-finite states"
    except Exception as exc:     # noqa: BLE001 -- any failure to load or step is the finding
        ok, detail = False, f"{type(exc).__name__}: {exc}"
    return DesignCheck("loads and simulates", ok, steps if ok else 0, steps,
                       detail if ok or str(file) in detail else f"{file}: {detail}", "steps")


def format_checks(checks: list[DesignCheck]) -> str:
    """The checks as a markdown table."""
    def fmt(v):
        return f"{v:.6g}" if isinstance(v, float) else str(v)
    rows = ["| check | passed | value | limit | unit | detail |", "|---|---|---|---|---|---|"]
    rows += [f"| {c.name} | {'yes' if c.passed else '**NO**'} | {fmt(c.value)} | {fmt(c.limit)} | {c.unit} | "
             f"{c.detail.replace('|', '/')} |" for c in checks]
    return "\n".join(rows) + "\n"


def require_design_checks(source: str | Path, designed: str | Path, **kwargs) -> list[DesignCheck]:
    """:func:`check_designed_robot`, raising :class:`DesignCheckError` if any check fails."""
    checks = check_designed_robot(source, designed, **kwargs)
    failed = [c for c in checks if not c.passed]
    if failed:
        raise DesignCheckError(failed)
    return checks
