r"""A second body beside the robot: a small stiff FEM box (the payload carried on top, the box
pushed along the ground), simulated in the same implicit-Euler Newton solve.

The box is one hexahedron of 8 nodes split into 5 linear tets (the central tet of the corners
1, 2, 4, 7 and one tet at each other corner), appended to the robot's mesh after its own nodes
and tets (:func:`with_box`): the mesh then has two bodies (``TetMesh(bodies=2)``) and the robot
carries the :class:`Box` as ``Robot.box``. So the box is ordinary mesh nodes to the rest of the
physics:

* **mass**: ``mass / 8`` on each of its nodes (``Robot.node_masses``; the robot's ``density``
  and ``payload`` do not touch them), and gravity on it;
* **elasticity**: the robot's neo-Hookean law with Young's modulus ``youngs_modulus`` (through
  ``Robot.modulus_scale``, ``E_box / E``; the robot's Poisson ratio), stiff against the foam;
* **ground contact**: its nodes are boundary nodes, so the robot's ground law (paper or Coulomb,
  plane or height field) acts on its 8 corners as on the robot's nodes;
* **contact with the robot**: :class:`~soft_envs.sim.contact.box_contact.BoxContact`, a penalty
  on every robot boundary node inside the box plus Coulomb friction on the box's faces, with
  its own ``stiffness``, ``blend``, ``friction_coefficient`` and ``slip_distance``.

The robot's centre of mass, frame and mass (``Robot.com``, ``Robot.body_node_masses``,
``Robot.total_mass``) leave the box out. Corners: node ``i`` of the box is at ``center + (b_x
- 1/2, b_y - 1/2, b_z - 1/2) * size`` with ``i = b_x + 2 b_y + 4 b_z``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .mesh import TetMesh

__all__ = ["Box", "with_box", "BOX_TETS", "BOX_FACES", "BOX_NODES", "MAX_OVERLAP"]

#: how far a robot node may lie inside the box at rest [m]
MAX_OVERLAP = 1e-3

#: nodes of the box
BOX_NODES = 8
#: the 5 tets of the hexahedron (local corner indices; oriented positively by :func:`_box_tets`)
_TETS = np.array([[1, 2, 4, 7], [0, 1, 2, 4], [3, 1, 2, 7], [5, 1, 4, 7], [6, 2, 4, 7]])
#: the 6 faces -x, +x, -y, +y, -z, +z, their corners in cyclic order (made outward by :func:`_box_faces`)
_FACES = np.array([[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]])


def _unit_corners() -> np.ndarray:
    i = np.arange(BOX_NODES)
    return np.stack([i & 1, (i >> 1) & 1, (i >> 2) & 1], axis=1).astype(np.float64) - 0.5


def _box_tets() -> np.ndarray:
    c = _unit_corners()
    tets = _TETS.copy()
    for t in tets:
        if np.linalg.det(np.stack([c[t[1]] - c[t[0]], c[t[2]] - c[t[0]], c[t[3]] - c[t[0]]], axis=1)) < 0:
            t[[2, 3]] = t[[3, 2]]
    return tets


def _box_faces() -> np.ndarray:
    c = _unit_corners()
    faces = _FACES.copy()
    for f in faces:
        a, b, cc, d = c[f]
        if np.cross(cc - a, d - b) @ (c[f].mean(axis=0)) < 0:       # the box's centre is the origin
            f[:] = f[::-1]
    return faces


#: the box's tets and outward faces (``(c - a) x (d - b)`` points out of face ``[a, b, c, d]``)
BOX_TETS = _box_tets()
BOX_FACES = _box_faces()


def _positive(value, name: str, allow_zero: bool = False) -> float:
    v = float(value)
    if not (math.isfinite(v) and (v >= 0 if allow_zero else v > 0)):
        raise ValueError(f"box.{name} must be {'>= 0' if allow_zero else 'positive'}, got {value!r}")
    return v


@dataclass(frozen=True)
class Box:
    """A stiff FEM box (module docstring).

    Attributes:
        size (tuple[float, float, float]): its edges along x, y, z [m], at rest.
        center (tuple[float, float, float]): its centre at rest [m], in the robot's rest frame
            (the frame of ``robot.mesh.points``; the rest state's relaxation settles it).
        mass (float): its mass [kg], an eighth on each corner.
        youngs_modulus (float): Young's modulus of its material [Pa] (default 2 MPa: 20 times
            the shipped robots' foam).
        stiffness (float): ``k_b`` of the penalty on a robot node inside it [N/m].
        blend (float): ``eps_b``, the width of that penalty's C2 blend [m] (0: half-quadratic).
        friction_coefficient (float): Coulomb's ``mu_b`` between the robot and the box.
        slip_distance (float): ``r_b``, the offset from its anchor on the box's face at which a
            robot node slides [m].
    """

    size: tuple[float, float, float]
    center: tuple[float, float, float]
    mass: float
    youngs_modulus: float = 2e6
    stiffness: float = 2000.0
    blend: float = 5e-4
    friction_coefficient: float = 0.8
    slip_distance: float = 3e-4

    def __post_init__(self):
        for name in ("size", "center"):
            v = np.array(getattr(self, name), dtype=np.float64)
            if v.shape != (3,) or not np.isfinite(v).all():
                raise ValueError(f"box.{name} must be 3 finite numbers [m], got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(a) for a in v))
        if min(self.size) <= 0:
            raise ValueError(f"box.size must be positive, got {self.size!r}")
        for name in ("mass", "youngs_modulus", "stiffness", "slip_distance"):
            object.__setattr__(self, name, _positive(getattr(self, name), name))
        for name in ("blend", "friction_coefficient"):
            object.__setattr__(self, name, _positive(getattr(self, name), name, allow_zero=True))

    def corners(self) -> np.ndarray:
        """(8, 3) the corners at rest [m] (module docstring's order)."""
        return np.array(self.center) + _unit_corners() * np.array(self.size)

    def moved(self, center) -> "Box":
        """The same box centred at ``center`` [m]."""
        return Box(self.size, tuple(center), self.mass, self.youngs_modulus, self.stiffness, self.blend,
                   self.friction_coefficient, self.slip_distance)


def with_box(robot, box: Box):
    """``robot`` with ``box`` appended to its mesh (8 nodes, 5 tets after its own; a robot with a
    box already is refused). The box may press into the robot at rest by at most
    :data:`MAX_OVERLAP` (a payload placed with its bottom a little below the robot's top is
    held by friction from the first step of the rest state's relaxation on). Its tets' modulus
    scale is ``box.youngs_modulus / robot.youngs_modulus``."""
    if not isinstance(box, Box):
        raise ValueError(f"box must be a Box, got {type(box).__name__}")
    if robot.box is not None:
        raise ValueError(f"{robot.source}: the robot has a box already (one second body at most)")
    mesh, corners = robot.mesh, box.corners()
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    depth = np.minimum(mesh.points - lo, hi - mesh.points).min(axis=1)
    if depth.max() > MAX_OVERLAP:
        raise ValueError(f"{robot.source}: the box at {box.center} overlaps the robot at rest "
                         f"({int((depth > MAX_OVERLAP).sum())} nodes more than {1e3 * MAX_OVERLAP:g} mm inside it)")
    n = mesh.n_nodes
    points = np.concatenate([mesh.points, corners])
    tets = np.concatenate([mesh.tets, n + BOX_TETS])
    scale = np.concatenate([robot.element_modulus_scale,
                            np.full(len(BOX_TETS), box.youngs_modulus / robot.youngs_modulus)])
    return robot.replace(mesh=TetMesh(points, tets, source=mesh.source, bodies=2), box=box, modulus_scale=scale,
                         body_length=robot.body_length)
