"""Robot: the static model of a cable-driven soft robot (mesh, material, payload, cables, motors).

A robot lives in the simulation frame: metres, +y up, facing +x at rest, ground at y = 0.
Build one in Python with :meth:`Robot.from_mesh`, or load a shipped/own description with
:func:`soft_envs.sim.load_robot` (``assets/<name>/robot.toml``, see :mod:`.robot_file`). The
tendons and motors, their checks and the cables' binding to the mesh are in :mod:`.drive`
(re-exported here).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Mapping

import meshio
import numpy as np

from .box import BOX_NODES, BOX_TETS, Box
from .contact import CONTACT_LAWS, ContactParams
from .ground import HeightField
from .drive import (DEFAULT_MAX_SPEED_RPM, DEFAULT_MAX_TORQUE, DEFAULT_STALL_TORQUE, MOTOR_DEFAULTS, CableData, Motor,
                    Tendon, bind_tendons, cable_data, check_drive)
from .markers import Marker, MarkerSet
from .materials import lame_parameters
from .mesh import TetMesh, load_mesh

__all__ = ["Robot", "Tendon", "Motor", "ContactParams", "CableData", "Marker", "CONTACT_MODELS",
           "DEFAULT_MAX_SPEED_RPM", "DEFAULT_STALL_TORQUE", "DEFAULT_MAX_TORQUE", "MOTOR_DEFAULTS"]

#: The built-in contact laws' names; every law, those registered later included, is a key of
#: :data:`soft_envs.sim.contact.CONTACT_LAWS`.
CONTACT_MODELS = tuple(CONTACT_LAWS)


@dataclass(frozen=True, eq=False)
class Robot:
    """Static description of a robot: frozen, its arrays read-only. Use :meth:`from_mesh` to
    build one; :meth:`replace` gives a changed copy. n is the number of nodes, T of tendons, M of
    motors; indices are into ``mesh.points``. Quantities derived from the fields (masses, the
    contraction ranges, the cable arrays) are properties below.

    Attributes:
        name (str): the robot's name (the folder name of a shipped robot).
        mesh (TetMesh): the tetrahedral mesh in the rest frame: ``mesh.points`` (n, 3) [m],
            ``mesh.tets`` (n_tets, 4) node indices.
        youngs_modulus (float): Young's modulus E of the neo-Hookean material [Pa] (per tet times
            ``modulus_scale``).
        poisson_ratio (float): Poisson's ratio nu [-], in (-1, 0.5).
        density (float): mass density of the body [kg/m^3], > 0.
        tendons (tuple[Tendon, ...]): the T cables (:class:`~soft_envs.sim.drive.Tendon`: points
            (P_t, 3) [m] in the rest frame, stiffness [N/m], rest length [m]).
        motors (tuple[Motor, ...]): the M motors (:class:`~soft_envs.sim.drive.Motor`:
            contraction range [m], spool radius [m], speed [rpm], torques [N m]); the order of
            the controls ``u`` (M,).
        payload_mass (float): mass carried by the body [kg], >= 0 (the motor assembly), spread
            evenly over ``payload_nodes``.
        payload_nodes (np.ndarray): (P,) int64, sorted unique node indices carrying the payload.
        fixed_nodes (np.ndarray): (F,) int64, sorted unique node indices held at their rest
            positions (none for a walking robot; a robot with some is not set on the ground).
        contact (ContactParams): the ground contact law's name and parameters
            (:class:`~soft_envs.sim.contact.ContactParams`).
        body_length (float): the robot's length [m] (speeds are in body lengths per unit time);
            by default the extent of the mesh along x.
        cable_blend (float): width [m] of the C2 blend of the cables' one-sided quadratic energy,
            >= 0 (0: half-quadratic).
        source (str): where the robot came from (a robot.toml path, ``"<python>"``), the prefix of
            its error messages.
        markers (tuple[Marker, ...]): tracked points (:class:`~soft_envs.sim.markers.Marker`: a
            name and a point (3,) [m] in the rest frame), bound to the mesh as :attr:`marker_set`.
        modulus_scale (np.ndarray | None): (n_tets,) positive per-tet factor [-] on
            ``youngs_modulus``, or None for a uniform material; the regional moduli of a design
            (:mod:`soft_envs.sim.design`) set it.
        ground (HeightField | None): the ground the robot stands on
            (:class:`~soft_envs.sim.ground.HeightField`, ``robot.toml``'s ``[ground]``); None
            (default) for the plane ``y = 0``.
        box (Box | None): a second body (:class:`~soft_envs.sim.box.Box`, the last 8 nodes and 5
            tets of ``mesh``: :func:`~soft_envs.sim.box.with_box` adds one), or None (default).
    """

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
    modulus_scale: np.ndarray | None = None
    ground: HeightField | None = None
    box: Box | None = None

    def __post_init__(self):
        lame_parameters(self.youngs_modulus, self.poisson_ratio)   # validates
        self._check_box()
        if self.ground is not None and not isinstance(self.ground, HeightField):
            raise ValueError(f"{self.source}: ground must be a HeightField or None, got {type(self.ground).__name__}")
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
        check_drive(self)
        _ = self._binding         # binds the tendons' points now, so errors surface at construction
        _ = self.marker_set       # binds the markers now, so errors surface at construction

    def _check_box(self) -> None:
        """A box is the mesh's second body, its last 8 nodes at the box's corners."""
        bodies = getattr(self.mesh, "bodies", 1)
        if self.box is None:
            if bodies != 1:
                raise ValueError(f"{self.source}: a mesh of {bodies} bodies needs a box (soft_envs.sim.box.with_box)")
            return
        if not isinstance(self.box, Box):
            raise ValueError(f"{self.source}: box must be a Box or None, got {type(self.box).__name__}")
        if bodies != 2 or not np.allclose(self.mesh.points[-BOX_NODES:], self.box.corners(), rtol=0, atol=1e-12):
            raise ValueError(f"{self.source}: the box must be the mesh's second body, its last {BOX_NODES} nodes "
                             "(soft_envs.sim.box.with_box adds one)")

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

    @cached_property
    def _binding(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per tendon, ``(tets (P_t,), weights (P_t, 4))``: where its points sit in the mesh
        (:func:`~soft_envs.sim.drive.bind_tendons`)."""
        return bind_tendons(self)

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
        over ``payload_nodes`` (the motor assembly on the top nodes, paper II-A); a box's nodes
        carry an eighth of its mass each."""
        m = self.mesh.lumped_masses(self.density)
        if self.payload_mass > 0:
            m[self.payload_nodes] += self.payload_mass / len(self.payload_nodes)
        if self.box is not None:
            m[self.box_nodes] = self.box.mass / BOX_NODES
        m.setflags(write=False)
        return m

    @property
    def box_nodes(self) -> np.ndarray:
        """(8,) the box's nodes (the mesh's last), or (0,) without a box."""
        n = self.mesh.n_nodes
        return np.arange(n - BOX_NODES if self.box is not None else n, n, dtype=np.int64)

    @property
    def n_robot_nodes(self) -> int:
        """Nodes of the robot's own body (all but a box's)."""
        return self.mesh.n_nodes - len(self.box_nodes)

    @cached_property
    def body_node_masses(self) -> np.ndarray:
        """:attr:`node_masses` of the robot's own body: a box's nodes weigh 0 (the COM, the body
        frame); :attr:`node_masses` itself without a box."""
        if self.box is None:
            return self.node_masses
        m = self.node_masses.copy()
        m[self.box_nodes] = 0.0
        m.setflags(write=False)
        return m

    @property
    def body_mass(self) -> float:
        n_tets = self.mesh.n_tets - (0 if self.box is None else len(BOX_TETS))
        return float(self.density * self.mesh.volumes[:n_tets].sum())

    @property
    def total_mass(self) -> float:
        """The robot's mass [kg], payload included, a box not."""
        return float(self.body_node_masses.sum())

    def com(self, x: np.ndarray) -> np.ndarray:
        """Mass-weighted centre of mass of positions ``x`` (..., n, 3) (of the robot's own body)."""
        return np.einsum("...ni,n->...i", x, self.body_node_masses) / self.total_mass

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
    def cable_data(self) -> CableData:
        """The tendons as flat arrays for the cable kernels (:func:`~soft_envs.sim.drive.cable_data`)."""
        return cable_data(self, self._binding)

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

