"""The robot's drive: its tendons (cables through the body) and the motors that wind them.

:class:`Tendon` and :class:`Motor` (with the motors' default figures), their checks against
each other (:func:`check_drive`), the binding of the tendons' points to the tets that contain
them (:func:`bind_tendons`) and the flat arrays the cable kernels read (:class:`CableData`,
:func:`cable_data`). :class:`~soft_envs.sim.robot.Robot` holds a tuple of each and calls these;
``soft_envs.sim.robot`` re-exports the names.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Tendon", "Motor", "CableData", "DEFAULT_MAX_SPEED_RPM", "DEFAULT_STALL_TORQUE", "DEFAULT_MAX_TORQUE",
           "MOTOR_DEFAULTS", "check_drive", "bind_tendons", "cable_data"]

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
    """Flat tendon arrays for the kernels (see :mod:`soft_envs.sim.cables`), P points of T
    tendons in all: ``pt_nodes`` (P, 4) int64 the nodes of each point's tet, ``pt_w`` (P, 4) its
    barycentric weights, ``ptr`` (T+1,) int64 each tendon's first point, ``rest_length`` (T,) the
    assembly lengths alpha0 [m], ``stiffness`` (T,) [N/m], ``tendon_motor`` (T,) int64 the motor
    driving each tendon (-1: passive)."""

    pt_nodes: np.ndarray
    pt_w: np.ndarray
    ptr: np.ndarray
    rest_length: np.ndarray
    stiffness: np.ndarray
    tendon_motor: np.ndarray


def check_drive(robot) -> None:
    """ValueError unless ``robot``'s tendons and motors fit together: unique names, every motor
    drives known tendons (each tendon at most one motor) with a finite range ``u_min < u_max``,
    positive spool radius, speed and torques, and a mirror map that is an involution."""
    names = [t.name for t in robot.tendons]
    if len(set(names)) != len(names):
        raise ValueError(f"{robot.source}: duplicate tendon names {sorted(names)}")
    mnames = [m.name for m in robot.motors]
    if len(set(mnames)) != len(mnames):
        raise ValueError(f"{robot.source}: duplicate motor names {sorted(mnames)}")
    for i, m in enumerate(robot.motors):
        where = f"{robot.source}: motors[{i}] ({m.name!r})"
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
            back = robot.motors[mnames.index(m.mirror)].mirror
            if back != m.name:
                raise ValueError(f"{where}.mirror: the mirror map is not an involution: "
                                 f"{m.name!r} -> {m.mirror!r} -> {back!r}")
    used = [t for m in robot.motors for t in m.tendons]
    dup = {t for t in used if used.count(t) > 1}
    if dup:
        raise ValueError(f"{robot.source}: tendons driven by more than one motor: {sorted(dup)}")


def bind_tendons(robot) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per tendon, the tet containing each of its points and the point's barycentric weights in
    it: ``(tets (P_t,), weights (P_t, 4))``. ValueError for fewer than two 3-D points, a
    stiffness that is not positive, a point outside the body or coincident consecutive points."""
    out = []
    for i, t in enumerate(robot.tendons):
        pts = np.asarray(t.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
            raise ValueError(f"{robot.source}: tendons[{i}] ({t.name!r}).points must be a list of at "
                             f"least two 3-D points, got shape {pts.shape}")
        if not (np.isfinite(t.stiffness) and t.stiffness > 0):
            raise ValueError(f"{robot.source}: tendons[{i}] ({t.name!r}).stiffness must be positive")
        tets, ws = [], []
        scale = 1e-6 * robot.body_length
        for j, p in enumerate(pts):
            hit = robot.mesh.locate(p, tol=1e-6)
            if hit is None:
                raise ValueError(f"{robot.source}: tendons[{i}] ({t.name!r}).points[{j}] = {p.tolist()} "
                                 "lies outside the body")
            e, w = hit
            w = np.clip(w, 0.0, None)
            tets.append(e)
            ws.append(w / w.sum())
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        if (seg <= scale).any():
            raise ValueError(f"{robot.source}: tendons[{i}] ({t.name!r}) has coincident consecutive points")
        out.append((np.array(tets), np.array(ws)))
    return out


def cable_data(robot, binding: list[tuple[np.ndarray, np.ndarray]]) -> CableData:
    """The flat tendon arrays of ``robot`` from its tendons' ``binding`` (:func:`bind_tendons`)."""
    bind = binding
    nodes = [robot.mesh.tets[tets] for tets, _ in bind]
    ws = [w for _, w in bind]
    ptr = np.cumsum([0] + [len(n) for n in nodes]).astype(np.int64)
    rest = []
    for t in robot.tendons:
        pts = np.asarray(t.points, dtype=np.float64)
        rest.append(t.rest_length if t.rest_length is not None
                    else float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()))
    cd = CableData(
        pt_nodes=np.ascontiguousarray(np.concatenate(nodes) if nodes else np.zeros((0, 4), np.int64)),
        pt_w=np.ascontiguousarray(np.concatenate(ws) if ws else np.zeros((0, 4))),
        ptr=ptr, rest_length=np.array(rest, dtype=np.float64),
        stiffness=np.array([t.stiffness for t in robot.tendons], dtype=np.float64),
        tendon_motor=robot.tendon_motor)
    return cd
