r"""Leg lengths as design parameters: a smooth morph of the rest shape along the up axis
(a change of the robot's geometry).

A leg is a connected set of tets below the hip height ``y_h`` (:func:`legs_below`). Lengthening
leg l by ``s_l`` [m] moves the rest nodes

.. math::
    X' = X - \sum_l s_l\, w_l(X)\, e_{up}, \qquad
    w_l(X) = 1 - \operatorname{smoothstep}\Big(\frac{y - y_{foot,l}}{y_h - y_{foot,l}}\Big)

on the leg's nodes (0 elsewhere): the foot moves down by ``s_l``, the hip stays, the leg's tets
in between stretch smoothly (smoothstep ``3t^2 - 2t^3``, clipped to [0, 1]). Tendon points and
markers ride with their tets (their rest positions move by the barycentric interpolation of the
node moves, so they keep their tet and weights; only the tendons' rest polyline lengths, the
assembly lengths alpha0, change). The morph is linear in ``s``: ``dX/ds_l = -w_l e_up``.

Mirror legs are tied (:func:`mirror_groups`): a leg whose tets are the mirror image of another
leg's in the body's mid-plane (normal to the lateral axis, as routing's mirror relation) follows
it, one parameter ``s_g`` per group (``legs:leg0+leg1``, ``dX/ds_g = -sum_{l in g} w_l e_up``),
so a co-designed Puppy keeps the bilateral symmetry its gaits assume. A leg spanning the full
width (the Tripod's) is its own mirror image: a group of one.

Derivatives (:mod:`.rest_shape`, FD-checked): the elastic gradient, the lumped masses (the
masses follow the volumes: ``dm_i = rho sum_e dV_e / 4``; the payload and density stay) and the
cable force, chained through ``dX/ds``; gravity's force ``-m g`` changes by ``-dm g``. The
rest relaxation starts from the rest mesh set on the ground (``Simulator.initial_placement``),
so its derivative starts from ``dX/ds`` with the lowest node's height change removed
(:meth:`LegMorph.rest_position_jacobian`, used by ``Simulator.rest_sensitivity``); when several
feet tie for lowest, that derivative is one-sided.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..mesh import TetMesh
from .regions import Region
from .rest_shape import (cable_rest_derivative, deformation_rest_derivative, elastic_rest_derivative,
                         lumped_mass_rest_derivative)

__all__ = ["legs_below", "mirror_groups", "LegMorph"]


def legs_below(robot, hip_height: float) -> list[Region]:
    """The legs of ``robot``: connected sets of tets (sharing nodes) whose centroids lie below
    ``hip_height`` (up axis), named ``leg0, leg1, ...`` by their centroids' forward then lateral
    coordinate."""
    mesh = robot.mesh
    up = int(np.argmax(np.abs(robot.up_axis)))
    below = np.flatnonzero(mesh.points[mesh.tets].mean(axis=1)[:, up] < hip_height)
    if not below.size:
        raise ValueError(f"{robot.source}: no tet lies below hip height {hip_height!r} m")
    rows = np.repeat(np.arange(below.size), 4)
    incidence = sp.csr_matrix((np.ones(rows.size), (rows, mesh.tets[below].ravel())),
                              shape=(below.size, mesh.n_nodes))
    _, label = connected_components(incidence @ incidence.T, directed=False)
    groups = [below[label == k] for k in range(label.max() + 1)]
    fwd = int(np.argmax(np.abs(robot.forward_axis)))
    lat = 3 - up - fwd
    centre = [mesh.points[mesh.tets[g]].mean(axis=(0, 1)) for g in groups]
    order = sorted(range(len(groups)), key=lambda k: (round(centre[k][fwd], 9), round(centre[k][lat], 9)))
    return [Region(f"leg{i}", groups[k]) for i, k in enumerate(order)]


def _smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def mirror_groups(robot, legs: Sequence[Region], tol: float = 1e-7) -> list[tuple[int, ...]]:
    """The legs tied by bilateral symmetry: indices of ``legs`` whose tets are the mirror images
    of each other's in the body's mid-plane (normal to the lateral axis, as routing's mirror
    relation), each group in order of its first leg; a leg that is its own mirror image (it spans
    the full width, e.g. the Tripod's) or has none is a group of its own."""
    mesh = robot.mesh
    lateral = int(np.argmax(np.abs(np.cross(robot.forward_axis, robot.up_axis))))
    mid2 = mesh.points[:, lateral].min() + mesh.points[:, lateral].max()
    centroids = [mesh.points[mesh.tets[leg.elements]].mean(axis=1) for leg in legs]
    groups, taken = [], set()
    for a in range(len(legs)):
        if a in taken:
            continue
        mirrored = centroids[a].copy()
        mirrored[:, lateral] = mid2 - mirrored[:, lateral]
        group = [a]
        for b in range(a + 1, len(legs)):
            if b not in taken and len(centroids[b]) == len(mirrored):
                dist, _ = cKDTree(centroids[b]).query(mirrored)
                if dist.max() <= tol:
                    group.append(b)
                    break
        taken.update(group)
        groups.append(tuple(group))
    return groups


class LegMorph:
    """The lengths of ``legs`` (regions below ``hip_height``, the up coordinate in metres) as
    design parameters: ``s_g`` [m] per group of legs, 0 for the robot as it is, bounded by half
    the leg's height either way.

    ``groups``: tuples of indices of ``legs`` that share one parameter (default
    :func:`mirror_groups`: a leg and its mirror image follow each other, so the design stays
    bilaterally symmetric), named ``legs:leg0+leg1``. :meth:`moved_to` rebuilds the morph at a
    moved robot."""

    kind = "legs"

    def __init__(self, robot, legs: Sequence[Region], hip_height: float,
                 groups: Sequence[Sequence[int]] | None = None):
        mesh = robot.mesh
        self.up = np.asarray(robot.up_axis, dtype=np.float64)
        y = mesh.points @ self.up
        self.legs = tuple(legs)
        self.hip_height = float(hip_height)
        self.groups = tuple(tuple(g) for g in (mirror_groups(robot, self.legs) if groups is None else groups))
        if sorted(i for g in self.groups for i in g) != list(range(len(self.legs))):
            raise ValueError(f"{robot.source}: leg groups {self.groups} must hold each of the {len(self.legs)} "
                             "legs once")
        self.names = tuple("legs:" + "+".join(self.legs[i].name for i in g) for g in self.groups)
        self.weights = np.zeros((len(self.groups), mesh.n_nodes))
        height = np.zeros(len(self.groups))
        for k, group in enumerate(self.groups):
            for l in group:
                leg = self.legs[l]
                nodes = np.unique(mesh.tets[leg.elements])
                foot = y[nodes].min()
                if not foot < hip_height:
                    raise ValueError(f"{robot.source}: leg {leg.name!r} has no node below hip height "
                                     f"{hip_height!r}")
                self.weights[k, nodes] += 1.0 - _smoothstep((y[nodes] - foot) / (hip_height - foot))
                height[k] = min(height[k], hip_height - foot) if height[k] else hip_height - foot
        self.values = np.zeros(len(self.groups))
        #: the values at which this morph's mesh is the robot's (:meth:`moved_to`)
        self.offset = np.zeros(len(self.groups))
        self.bounds = np.column_stack([-0.5 * height, 0.5 * height]).reshape(-1, 2)

    def moved_to(self, robot, values: np.ndarray) -> "LegMorph":
        """This morph at ``robot`` (the design at ``values``): the same legs (tets), groups,
        absolute hip height and bounds, the weights from ``robot``'s rest nodes, and
        ``values`` as its values (the morph moves by ``theta - values``)."""
        new = LegMorph(robot, self.legs, self.hip_height, self.groups)
        new.values = np.array(values, dtype=np.float64)
        new.offset = new.values.copy()
        new.bounds = self.bounds.copy()
        return new

    def node_moves(self) -> np.ndarray:
        """``dX/ds`` (n, 3, n_groups)."""
        return -self.weights.T[:, None, :] * self.up[None, :, None]

    @staticmethod
    def _embedded_moves(robot, dX: np.ndarray) -> list[np.ndarray]:
        """Each tendon's rest-point moves (P_t, 3) when the points ride with their tets."""
        return [np.einsum("sa,sai->si", ws, dX[robot.mesh.tets[tets]]) for tets, ws in robot._binding]

    def apply(self, robot, theta: np.ndarray) -> dict:
        """The Robot field changes of leg lengths ``theta``: the morphed mesh, tendon points and
        markers (each point with its tet's interpolated move)."""
        dX = self.node_moves() @ (np.asarray(theta, dtype=np.float64) - self.offset)
        mesh = TetMesh(robot.mesh.points + dX, robot.mesh.tets, robot.mesh.source)
        moves = self._embedded_moves(robot, dX)
        tendons = []
        for t, dq in zip(robot.tendons, moves):
            pts = np.asarray(t.points) + dq
            rest = t.rest_length
            if rest is not None:          # keep the offset from the rest polyline's length
                rest += (np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
                         - np.linalg.norm(np.diff(np.asarray(t.points), axis=0), axis=1).sum())
            tendons.append(dataclasses.replace(t, points=pts, rest_length=rest))
        ms = robot.marker_set
        markers = tuple(dataclasses.replace(m, point=np.asarray(m.point) + w @ dX[nodes])
                        for m, nodes, w in zip(robot.markers, ms.nodes, ms.weights))
        return {"mesh": mesh, "tendons": tuple(tendons), "markers": markers}

    def force_jacobian(self, system, x, x_prev, u, history) -> np.ndarray:
        """``d(dE/dx)/ds_g`` (3n, n_groups): elastic, cable and gravity parts."""
        robot = system.robot
        out = np.zeros((system.n_dof, len(self.names)))
        dm = self.node_mass_jacobian(robot)
        for l, dX in enumerate(np.moveaxis(self.node_moves(), 2, 0)):
            out[:, l] = elastic_rest_derivative(system.elastic, robot.mesh, x, dX)[1]
            out[:, l] += cable_rest_derivative(system, x, u, dX, self._embedded_moves(robot, dX))
            out[:, l] -= (dm[:, l, None] * system.gravity[None, :]).ravel()
        return out

    def deformation_jacobian(self, system, x) -> np.ndarray:
        """``dGamma/ds_g`` (T, n_groups) at fixed x: the points ride with their tets (their
        positions in x stay), the assembly lengths follow the rest polylines."""
        robot = system.robot
        return np.column_stack([deformation_rest_derivative(system, x, dX, self._embedded_moves(robot, dX))
                                for dX in np.moveaxis(self.node_moves(), 2, 0)]).reshape(len(robot.tendons), -1)

    def node_mass_jacobian(self, robot) -> np.ndarray:
        """``dm_i/ds_g`` (n, n_groups)."""
        return np.column_stack([lumped_mass_rest_derivative(robot.mesh, robot.density, dX)
                                for dX in np.moveaxis(self.node_moves(), 2, 0)]).reshape(robot.mesh.n_nodes, -1)

    def rest_position_jacobian(self, robot) -> np.ndarray:
        """``dX/ds`` (n, 3, n_groups) of the rest nodes."""
        return self.node_moves()

