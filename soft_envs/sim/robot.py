"""Robot: the static model of a cable-driven soft robot (mesh, material, payload, cables, motors).

A robot lives in the simulation frame: metres, +y up, facing +x at rest, ground at y = 0.
Build one in Python with :meth:`Robot.from_mesh`, or load a shipped/own description with
:func:`soft_envs.sim.load_robot` (``assets/<name>/robot.toml``, see :mod:`.robot_file`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Mapping

import meshio
import numpy as np

from .contact import CONTACT_LAWS, ContactParams
from .markers import Marker, MarkerSet
from .materials import lame_parameters
from .mesh import TetMesh, load_mesh

__all__ = ["Robot", "Tendon", "Motor", "ContactParams", "CableData", "Marker", "CONTACT_MODELS",
           "DEFAULT_MAX_SPEED_RPM", "DEFAULT_STALL_TORQUE", "DEFAULT_MAX_TORQUE", "MOTOR_DEFAULTS"]

#: [rpm] a motor's no-load output speed when its ``[[motors]]`` entry gives none: the Pololu 298:1
#: micro metal gearmotor, HP (high-power) motor at 6 V (docs/robots.md: figures and sources)
DEFAULT_MAX_SPEED_RPM = 100.0
#: [N m] a motor's stall torque when its ``[[motors]]`` entry gives none: the 298:1 HP at 6 V,
#: about 4 kg cm (docs/robots.md)
DEFAULT_STALL_TORQUE = 0.39
#: [N m] the torque a motor's gearbox must not exceed when its ``[[motors]]`` entry gives none:
#: Pololu's recommended limit for the micro metal gearboxes up to 298:1, 2 kg cm
DEFAULT_MAX_TORQUE = 0.196
#: each optional number of a ``[[motors]]`` entry that describes the motor itself, with its default
MOTOR_DEFAULTS = {"max_speed_rpm": DEFAULT_MAX_SPEED_RPM, "stall_torque": DEFAULT_STALL_TORQUE,
                  "max_torque": DEFAULT_MAX_TORQUE}

#: The built-in contact laws' names; every law, those registered later included, is a key of
#: :data:`soft_envs.sim.contact.CONTACT_LAWS`.
CONTACT_MODELS = tuple(CONTACT_LAWS)


@dataclass(frozen=True, eq=False)
class Tendon:
    """A cable: polyline through ``points`` (P, 3) given in the rest frame, each bound to the tet
    that contains it. ``stiffness`` [N/m]; ``rest_length`` = assembly length alpha0 [m]
    (default: the polyline's rest length, i.e. just taut at assembly)."""

    name: str
    points: np.ndarray
    stiffness: float = 1e5
    rest_length: float | None = None


def _is_positive_number(value: Any) -> bool:
    """A finite number > 0 (not a bool, not a string)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    return bool(np.isfinite(value) and value > 0)


@dataclass(frozen=True)
class Motor:
    """A motor winding all its ``tendons`` by the same contraction u [m] (a tendon pair).

    ``mirror`` names the motor on the other side (bilateral symmetry), ``u_min``/``u_max`` bound
    the contraction [m], ``spool_radius`` [m] converts u to motor angle (u = r theta),
    ``max_speed_rpm`` is the output shaft's no-load speed [rpm] (default
    :data:`DEFAULT_MAX_SPEED_RPM`): the contraction moves at most ``max_contraction_speed``;
    ``stall_torque`` [N m] is where the motor's speed falls to zero along its torque-speed line,
    ``max_torque`` [N m] the torque its gearbox must not exceed (defaults
    :data:`DEFAULT_STALL_TORQUE`, :data:`DEFAULT_MAX_TORQUE`; the law: :mod:`.motors`)."""

    name: str
    tendons: tuple[str, ...]
    mirror: str | None = None
    u_min: float = 0.0
    u_max: float = 0.01
    spool_radius: float = 0.005
    max_speed_rpm: float = DEFAULT_MAX_SPEED_RPM
    stall_torque: float = DEFAULT_STALL_TORQUE
    max_torque: float = DEFAULT_MAX_TORQUE

    @property
    def max_contraction_speed(self) -> float:
        """Largest speed of the contraction [m/s]: ``max_speed_rpm * 2 pi / 60 * spool_radius``."""
        return self.max_speed_rpm * 2.0 * np.pi / 60.0 * self.spool_radius


@dataclass(frozen=True, eq=False)
class CableData:
    """Flat tendon arrays for the kernels (see :mod:`soft_envs.sim.cables`)."""

    pt_nodes: np.ndarray
    pt_w: np.ndarray
    ptr: np.ndarray
    rest_length: np.ndarray
    stiffness: np.ndarray
    tendon_motor: np.ndarray


@dataclass(frozen=True, eq=False)
class Robot:
    """Static description of a robot. Use :meth:`from_mesh` to build one."""

    name: str
    mesh: TetMesh
    youngs_modulus: float
    poisson_ratio: float
    density: float
    tendons: tuple[Tendon, ...] = ()
    motors: tuple[Motor, ...] = ()
    payload_mass: float = 0.0
    payload_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    fixed_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    contact: ContactParams = ContactParams()
    body_length: float | None = None
    cable_blend: float = 2e-4
    source: str = "<python>"
    markers: tuple[Marker, ...] = ()
    #: per-tet factor on ``youngs_modulus`` (None: uniform); the regional moduli of a design
    #: (:mod:`soft_envs.sim.design`) set it
    modulus_scale: np.ndarray | None = None

    def __post_init__(self):
        lame_parameters(self.youngs_modulus, self.poisson_ratio)   # validates
        if self.modulus_scale is not None:
            scale = np.array(self.modulus_scale, dtype=np.float64)
            if scale.shape != (self.mesh.n_tets,) or not (np.isfinite(scale).all() and (scale > 0).all()):
                raise ValueError(f"{self.source}: modulus_scale must be {self.mesh.n_tets} positive finite "
                                 f"factors (one per tet), got shape {scale.shape}")
            scale.setflags(write=False)
            object.__setattr__(self, "modulus_scale", scale)
        if not (np.isfinite(self.density) and self.density > 0):
            raise ValueError(f"{self.source}: material.density must be positive, got {self.density!r}")
        if not (np.isfinite(self.payload_mass) and self.payload_mass >= 0):
            raise ValueError(f"{self.source}: payload.mass must be >= 0, got {self.payload_mass!r}")
        for attr in ("payload_nodes", "fixed_nodes"):
            nodes = np.unique(np.asarray(getattr(self, attr), dtype=np.int64))
            if nodes.size and (nodes.min() < 0 or nodes.max() >= self.mesh.n_nodes):
                raise ValueError(f"{self.source}: {attr} has indices outside 0..{self.mesh.n_nodes - 1}")
            object.__setattr__(self, attr, nodes)
        if self.payload_mass > 0 and self.payload_nodes.size == 0:
            raise ValueError(f"{self.source}: payload.mass > 0 needs payload nodes")
        if self.body_length is None:
            object.__setattr__(self, "body_length", float(np.ptp(self.mesh.points[:, 0])))
        if not (np.isfinite(self.body_length) and self.body_length > 0):
            raise ValueError(f"{self.source}: robot.body_length must be positive, got {self.body_length!r}")
        if not (np.isfinite(self.cable_blend) and self.cable_blend >= 0):
            raise ValueError(f"{self.source}: cables.blend must be >= 0 (0: half-quadratic), got {self.cable_blend!r}")
        # own read-only copies of the tendon points: the binding and the rest lengths are
        # derived from them and must not change behind the robot's back
        tendons = []
        for i, t in enumerate(self.tendons):
            pts = np.array(t.points, dtype=np.float64)
            pts.setflags(write=False)
            if t.rest_length is not None and not (np.isfinite(t.rest_length) and t.rest_length > 0):
                raise ValueError(f"{self.source}: tendons[{i}] ({t.name!r}).rest_length must be positive, "
                                 f"got {t.rest_length!r}")
            tendons.append(dataclasses.replace(t, points=pts))
        object.__setattr__(self, "tendons", tuple(tendons))
        markers = tuple(m if isinstance(m, Marker) else Marker(str(m["name"]), np.asarray(m["point"], float))
                        for m in self.markers)
        object.__setattr__(self, "markers", markers)
        self._check_cables()
        _ = self.marker_set       # binds the markers now, so errors surface at construction

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_mesh(cls, mesh: meshio.Mesh | TetMesh | str | Path, *, youngs_modulus: float,
                  poisson_ratio: float, density: float, tendons: Iterable[Tendon | Mapping] = (),
                  motors: Iterable[Motor | Mapping] = (), **kwargs: Any) -> "Robot":
        """A robot from a mesh (meshio.Mesh, TetMesh or file) already in the simulation frame.

        ``tendons``/``motors`` may be :class:`Tendon`/:class:`Motor` or plain dicts with their
        fields; other keyword arguments are :class:`Robot` fields (``fixed_nodes``,
        ``payload_mass``, ``payload_nodes``, ``contact``, ``body_length``, ``name`` ...)."""
        tm = mesh if isinstance(mesh, TetMesh) else load_mesh(mesh)
        tds = tuple(t if isinstance(t, Tendon) else Tendon(**dict(t)) for t in tendons)
        mts = []
        for m in motors:
            if isinstance(m, Motor):
                mts.append(m)
            else:
                m = dict(m)
                m["tendons"] = tuple(m.get("tendons", ()))
                mts.append(Motor(**m))
        kwargs.setdefault("name", "robot")
        if "contact" in kwargs and isinstance(kwargs["contact"], Mapping):
            kwargs["contact"] = ContactParams(**kwargs["contact"])
        return cls(mesh=tm, youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio,
                   density=density, tendons=tds, motors=tuple(mts), **kwargs)

    def replace(self, **changes: Any) -> "Robot":
        """A copy with some fields changed (e.g. ``youngs_modulus`` for domain randomisation)."""
        return dataclasses.replace(self, **changes)

    def _check_cables(self) -> None:
        names = [t.name for t in self.tendons]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.source}: duplicate tendon names {sorted(names)}")
        mnames = [m.name for m in self.motors]
        if len(set(mnames)) != len(mnames):
            raise ValueError(f"{self.source}: duplicate motor names {sorted(mnames)}")
        for i, m in enumerate(self.motors):
            where = f"{self.source}: motors[{i}] ({m.name!r})"
            if not m.tendons:
                raise ValueError(f"{where}.tendons is empty")
            for t in m.tendons:
                if t not in names:
                    raise ValueError(f"{where}.tendons names unknown tendon {t!r} (known: {names})")
            if not (np.isfinite(m.u_min) and np.isfinite(m.u_max) and m.u_min < m.u_max):
                raise ValueError(f"{where}: need finite u_min < u_max, got {m.u_min}, {m.u_max}")
            if not (np.isfinite(m.spool_radius) and m.spool_radius > 0):
                raise ValueError(f"{where}.spool_radius must be a finite positive number, got {m.spool_radius}")
            for key, unit in (("max_speed_rpm", "rpm"), ("stall_torque", "N m"), ("max_torque", "N m")):
                value = getattr(m, key)
                if not _is_positive_number(value):
                    raise ValueError(f"{where}.{key} must be a finite positive number [{unit}], got {value!r}")
            if m.mirror is not None:
                if m.mirror not in mnames:
                    raise ValueError(f"{where}.mirror names unknown motor {m.mirror!r}")
                back = self.motors[mnames.index(m.mirror)].mirror
                if back != m.name:
                    raise ValueError(f"{where}.mirror: the mirror map is not an involution: "
                                     f"{m.name!r} -> {m.mirror!r} -> {back!r}")
        used = [t for m in self.motors for t in m.tendons]
        dup = {t for t in used if used.count(t) > 1}
        if dup:
            raise ValueError(f"{self.source}: tendons driven by more than one motor: {sorted(dup)}")
        _ = self._binding   # binds the points now, so errors surface at construction

    @cached_property
    def _binding(self) -> list[tuple[np.ndarray, np.ndarray]]:
        out = []
        for i, t in enumerate(self.tendons):
            pts = np.asarray(t.points, dtype=np.float64)
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
                raise ValueError(f"{self.source}: tendons[{i}] ({t.name!r}).points must be a list of at "
                                 f"least two 3-D points, got shape {pts.shape}")
            if not (np.isfinite(t.stiffness) and t.stiffness > 0):
                raise ValueError(f"{self.source}: tendons[{i}] ({t.name!r}).stiffness must be positive")
            tets, ws = [], []
            scale = 1e-6 * self.body_length
            for j, p in enumerate(pts):
                hit = self.mesh.locate(p, tol=1e-6)
                if hit is None:
                    raise ValueError(f"{self.source}: tendons[{i}] ({t.name!r}).points[{j}] = {p.tolist()} "
                                     "lies outside the body")
                e, w = hit
                w = np.clip(w, 0.0, None)
                tets.append(e)
                ws.append(w / w.sum())
            seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            if (seg <= scale).any():
                raise ValueError(f"{self.source}: tendons[{i}] ({t.name!r}) has coincident consecutive points")
            out.append((np.array(tets), np.array(ws)))
        return out

    # ------------------------------------------------------------------ derived data
    @property
    def motor_names(self) -> list[str]:
        return [m.name for m in self.motors]

    @property
    def tendon_names(self) -> list[str]:
        return [t.name for t in self.tendons]

    @property
    def n_motors(self) -> int:
        return len(self.motors)

    @property
    def max_contraction_speed(self) -> np.ndarray:
        """(M,) each motor's contraction speed limit [m/s] (:attr:`Motor.max_contraction_speed`:
        ``max_speed_rpm * 2 pi / 60 * spool_radius``)."""
        return np.array([m.max_contraction_speed for m in self.motors], dtype=np.float64)

    @property
    def stall_torques(self) -> np.ndarray:
        """(M,) each motor's stall torque [N m] (:attr:`Motor.stall_torque`)."""
        return np.array([m.stall_torque for m in self.motors], dtype=np.float64)

    @property
    def max_torques(self) -> np.ndarray:
        """(M,) the torque each motor's gearbox must not exceed [N m] (:attr:`Motor.max_torque`)."""
        return np.array([m.max_torque for m in self.motors], dtype=np.float64)

    @property
    def spool_radii(self) -> np.ndarray:
        """(M,) each motor's spool radius [m]."""
        return np.array([m.spool_radius for m in self.motors], dtype=np.float64)

    def max_contraction_step(self, dt: float) -> np.ndarray:
        """(M,) largest change of each motor's contraction in a time step of ``dt`` seconds [m]."""
        return self.max_contraction_speed * float(dt)

    @property
    def forward_axis(self) -> np.ndarray:
        return np.array([1.0, 0.0, 0.0])

    @property
    def up_axis(self) -> np.ndarray:
        return np.array([0.0, 1.0, 0.0])

    @cached_property
    def mirror_map(self) -> np.ndarray:
        """``mirror_map[i]`` = index of motor i's mirror motor (i itself when it has none)."""
        names = self.motor_names
        return np.array([names.index(m.mirror) if m.mirror else i for i, m in enumerate(self.motors)],
                        dtype=np.int64)

    @cached_property
    def tendon_motor(self) -> np.ndarray:
        """Index of the motor driving each tendon (-1: passive tendon)."""
        out = -np.ones(len(self.tendons), dtype=np.int64)
        names = self.tendon_names
        for mi, m in enumerate(self.motors):
            for t in m.tendons:
                out[names.index(t)] = mi
        return out

    @property
    def u_bounds(self) -> np.ndarray:
        """(n_motors, 2) lower and upper contraction bounds [m]."""
        return np.array([[m.u_min, m.u_max] for m in self.motors], dtype=np.float64).reshape(-1, 2)

    @property
    def u_rest(self) -> np.ndarray:
        """(n_motors,) contractions at rest [m]: 0 clipped into each motor's [u_min, u_max]
        (where an environment's reset, the rollouts of its gradient hooks and trajopt's prep
        phase start)."""
        b = self.u_bounds
        return np.clip(0.0, b[:, 0], b[:, 1])

    @cached_property
    def node_masses(self) -> np.ndarray:
        """Lumped masses [kg]: density * volume / 4 per tet node plus the payload spread evenly
        over ``payload_nodes`` (the motor assembly on the top nodes, paper II-A)."""
        m = self.mesh.lumped_masses(self.density)
        if self.payload_mass > 0:
            m[self.payload_nodes] += self.payload_mass / len(self.payload_nodes)
        m.setflags(write=False)
        return m

    @property
    def body_mass(self) -> float:
        return float(self.density * self.mesh.volumes.sum())

    @property
    def total_mass(self) -> float:
        return float(self.node_masses.sum())

    def com(self, x: np.ndarray) -> np.ndarray:
        """Mass-weighted centre of mass of positions ``x`` (..., n, 3)."""
        return np.einsum("...ni,n->...i", x, self.node_masses) / self.total_mass

    def element_lame(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-tet Lame parameters ``(mu, lam)``: those of ``youngs_modulus`` times
        :attr:`modulus_scale` (both are linear in E)."""
        mu, lam = lame_parameters(self.youngs_modulus, self.poisson_ratio)
        scale = self.element_modulus_scale
        return mu * scale, lam * scale

    @property
    def element_modulus_scale(self) -> np.ndarray:
        """Per-tet factor on ``youngs_modulus`` (ones when uniform)."""
        return np.ones(self.mesh.n_tets) if self.modulus_scale is None else np.array(self.modulus_scale)

    @cached_property
    def cable_data(self) -> "CableData":
        bind = self._binding
        nodes = [self.mesh.tets[tets] for tets, _ in bind]
        ws = [w for _, w in bind]
        ptr = np.cumsum([0] + [len(n) for n in nodes]).astype(np.int64)
        rest = []
        for t in self.tendons:
            pts = np.asarray(t.points, dtype=np.float64)
            rest.append(t.rest_length if t.rest_length is not None
                        else float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()))
        cd = CableData(
            pt_nodes=np.ascontiguousarray(np.concatenate(nodes) if nodes else np.zeros((0, 4), np.int64)),
            pt_w=np.ascontiguousarray(np.concatenate(ws) if ws else np.zeros((0, 4))),
            ptr=ptr, rest_length=np.array(rest, dtype=np.float64),
            stiffness=np.array([t.stiffness for t in self.tendons], dtype=np.float64),
            tendon_motor=self.tendon_motor)
        return cd

    @cached_property
    def marker_set(self) -> MarkerSet:
        """The tracked markers (:attr:`markers`) bound to the mesh."""
        return MarkerSet.bind(self.mesh, [m.name for m in self.markers], [m.point for m in self.markers],
                              source=f"{self.source}: markers")

    def summary(self) -> str:
        return (f"{self.name}: {self.mesh.n_nodes} nodes, {self.mesh.n_tets} tets, "
                f"body {1e3 * self.body_mass:.1f} g + payload {1e3 * self.payload_mass:.1f} g, "
                f"length {100 * self.body_length:.1f} cm, {len(self.tendons)} tendons, "
                f"{self.n_motors} motors")

