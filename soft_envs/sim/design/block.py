r"""A robot's design parameters as one vector theta, and as the parameter block of the
sensitivity recurrence.

:class:`DesignParameters` strings the kinds together (:class:`~.regions.RegionalModuli`,
:class:`~.routing.TendonRouting`, :class:`~.morph.LegMorph`): ``theta`` is their values side by side, :meth:`robot_at`
maps a vector to the modified :class:`~soft_envs.sim.robot.Robot` (to simulate it, to take
finite differences, to write it), and as a :class:`~soft_envs.sim.parameter_block.ParameterBlock`
it gives the recurrence ``d(dE/dx)/dtheta`` (each kind its columns), ``dm/dtheta`` and the
histories' dependence (none: the Coulomb anchors' update depends on positions only). So

>>> design = DesignParameters(robot, [RegionalModuli(robot, regions), TendonRouting(robot)])
>>> traj = Simulator(robot).rollout(u, params=design)     # traj.dcomdtheta (K+1, 3, len(design))

runs the same forward sensitivities as ``calibrate``'s physical parameters, the rest state's
derivative included (:meth:`~soft_envs.sim.Simulator.rest_sensitivity`), under either contact
law. The derivatives hold at the robot the block was built for; :meth:`moved_to` rebuilds the
block at ``robot_at(theta)`` to differentiate there.

Total mass: moduli and routing do not change the masses, leg morphs do (the masses follow the
volumes); :meth:`total_mass` and :meth:`total_mass_jacobian` are the constraint's value and
gradient (the design may not lose more than 2 % of the shipped robot's mass).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..parameter_block import ParameterBlock
from .clearance import signed_distance

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["DesignParameters", "MAX_MASS_LOSS"]

#: the largest fraction of the shipped robot's total mass a design may lose
MAX_MASS_LOSS = 0.02


class DesignParameters(ParameterBlock):
    """The design parameters ``kinds`` of ``robot`` as one block (columns in the kinds' order)."""

    def __init__(self, robot, kinds: Sequence):
        self.robot = robot
        self.kinds = tuple(kinds)
        self.names = tuple(n for k in self.kinds for n in k.names)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"{robot.source}: a design parameter is declared twice")
        self._slices, start = [], 0
        for k in self.kinds:
            self._slices.append(slice(start, start + len(k.names)))
            start += len(k.names)

    @property
    def values(self) -> np.ndarray:
        """theta of :attr:`robot`."""
        return np.concatenate([k.values for k in self.kinds]) if self.kinds else np.zeros(0)

    @property
    def bounds(self) -> np.ndarray:
        """(len, 2) lower and upper bounds of theta."""
        return np.concatenate([k.bounds for k in self.kinds]).reshape(-1, 2) if self.kinds else np.zeros((0, 2))

    def robot_at(self, theta) -> "Robot":
        """The robot with design ``theta`` (a ValueError naming the parameter for a bad value)."""
        theta = np.asarray(theta, dtype=np.float64)
        if theta.shape != (len(self),):
            raise ValueError(f"a design vector of {self.robot.name!r} has {len(self)} entries, got shape {theta.shape}")
        bad = ~np.isfinite(theta)
        if bad.any():
            raise ValueError(f"design parameter {self.names[int(np.argmax(bad))]!r} is not finite")
        robot = self.robot
        # morphs last: they carry the (routed) tendon points with the mesh
        for i in sorted(range(len(self.kinds)), key=lambda i: self.kinds[i].kind == "legs"):
            robot = robot.replace(**self.kinds[i].apply(robot, theta[self._slices[i]]))
        return robot

    def moved_to(self, theta) -> "DesignParameters":
        """The same declaration rebuilt at ``robot_at(theta)``, to linearise there: the same
        names and (global) bounds, ``values`` equal to theta (routing: the via points as they
        are in the moved robot, which a leg morph carries with their tets; legs: the cumulative
        added lengths), the same regions' tets, leg tets and absolute hip height, and
        ``new.robot_at(new.values)`` is ``new.robot``; its derivatives are those of
        ``new.robot_at`` at ``new.values``."""
        theta = np.asarray(theta, dtype=np.float64)
        robot = self.robot_at(theta)
        return DesignParameters(robot, [k.moved_to(robot, theta[sl]) for k, sl in zip(self.kinds, self._slices)])

    def describe_changes(self, theta_before, theta_after) -> list[dict]:
        """Every parameter that differs between ``theta_before`` and ``theta_after``: a dict of
        ``name``, ``before``, ``after``, ``unit`` and a plain ``description`` ("Young's modulus
        of middle_leg x1.50", "via point 1 of front_a moved 1.2 mm inwards (x)", "leg1 3.0 mm
        longer"), for the co-design report. Inwards/outwards: along the clearance gradient at
        the point before (else forward/backward, up/down, left/right)."""
        before, after = (np.asarray(t, dtype=np.float64) for t in (theta_before, theta_after))
        for t in (before, after):
            if t.shape != (len(self),):
                raise ValueError(f"a design vector of {self.robot.name!r} has {len(self)} entries, got shape {t.shape}")
        robot = None
        out = []
        for k, sl in zip(self.kinds, self._slices):
            for i in np.flatnonzero(before[sl] != after[sl]):
                if k.kind == "routing" and robot is None:
                    robot = self.robot_at(before)
                b, a = float(before[sl][i]), float(after[sl][i])
                out.append({"name": k.names[i], "before": b, "after": a, "unit": "Pa" if k.kind == "stiffness" else "m",
                            "description": _describe(k, int(i), b, a, robot)})
        return out

    # ------------------------------------------------------------------ parameter block
    def check(self, system) -> "DesignParameters":
        if system.robot is not self.robot:
            raise ValueError(f"these design parameters belong to robot {self.robot.name!r} "
                             f"({self.robot.source}), not to the simulated one ({system.robot.source}); "
                             "build them for the robot you simulate")
        return self

    def force_jacobian(self, system, x, x_prev, u, history) -> np.ndarray:
        out = np.zeros((system.n_dof, len(self)))
        for k, sl in zip(self.kinds, self._slices):
            out[:, sl] = k.force_jacobian(system, x, x_prev, u, history)
        return out

    def mass_jacobian(self, system) -> np.ndarray:
        return np.repeat(self.node_mass_jacobian(), 3, axis=0)

    def deformation_jacobian(self, system, x) -> np.ndarray:
        """``dGamma/dtheta`` (T, len) at fixed x: routing and leg morphs move the cables' points
        and assembly lengths, moduli do not."""
        out = np.zeros((system.cables.n_tendons, len(self)))
        for k, sl in zip(self.kinds, self._slices):
            if hasattr(k, "deformation_jacobian"):
                out[:, sl] = k.deformation_jacobian(system, x)
        return out

    def node_mass_jacobian(self) -> np.ndarray:
        """``dm_i/dtheta`` (n_nodes, len): zero for moduli and routing, the volumes' change for
        leg morphs."""
        out = np.zeros((self.robot.mesh.n_nodes, len(self)))
        for k, sl in zip(self.kinds, self._slices):
            if hasattr(k, "node_mass_jacobian"):
                out[:, sl] = k.node_mass_jacobian(self.robot)
        return out

    def rest_position_jacobian(self, robot) -> np.ndarray | None:
        """``dX/dtheta`` (n, 3, len) of the rest nodes (None: no kind moves them)."""
        if not any(hasattr(k, "rest_position_jacobian") for k in self.kinds):
            return None
        out = np.zeros((robot.mesh.n_nodes, 3, len(self)))
        for k, sl in zip(self.kinds, self._slices):
            if hasattr(k, "rest_position_jacobian"):
                out[:, :, sl] = k.rest_position_jacobian(robot)
        return out

    # ------------------------------------------------------------------ constraints
    def total_mass(self, theta=None) -> float:
        """Total mass [kg] of the design ``theta`` (default: of :attr:`robot`)."""
        return self.robot.total_mass if theta is None else self.robot_at(theta).total_mass

    def total_mass_jacobian(self) -> np.ndarray:
        """``d total_mass / dtheta`` (len,)."""
        return self.node_mass_jacobian().sum(axis=0)


def _describe(kind, i: int, before: float, after: float, robot) -> str:
    """A plain sentence for the change of ``kind``'s parameter i (:meth:`DesignParameters.describe_changes`)."""
    name = kind.names[i].split(":", 1)[1]
    if kind.kind == "stiffness":
        return f"Young's modulus of {name} x{after / before:.2f} ({before:.3g} -> {after:.3g} Pa)"
    if kind.kind == "legs":
        return f"{name.replace('+', ' and ')} {1e3 * abs(after - before):.1f} mm {'longer' if after > before else 'shorter'}"
    t, s = kind.free[i // 3]
    axis = i % 3
    delta = after - before
    _, grad = signed_distance(robot.mesh, np.asarray(robot.tendons[t].points[s]))
    if abs(grad[axis]) > 0.5:
        way = "inwards" if grad[axis] * delta > 0 else "outwards"
    else:
        fwd, up = np.asarray(robot.forward_axis, float), np.asarray(robot.up_axis, float)
        words = {tuple(fwd): ("forward", "backward"), tuple(up): ("up", "down"),
                 tuple(np.cross(fwd, up)): ("right", "left")}      # left is -lateral (docs/robots.md)
        e = np.eye(3)[axis]
        way = next((pos if delta * (e @ np.asarray(v)) > 0 else neg) for v, (pos, neg) in words.items()
                   if abs(e @ np.asarray(v)) > 0.5)
    return f"via point {s} of {robot.tendon_names[t]} moved {1e3 * abs(delta):.1f} mm {way} ({'xyz'[axis]})"
