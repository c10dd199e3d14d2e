r"""Material distribution as design parameters: Young's modulus per named region.

A region is a set of tets: those whose centroid lies in one of its boxes, or those carrying a
cell tag of the mesh. Regions are disjoint; tets in no region keep the robot's fitted modulus.
The design parameter of region r is its modulus ``E_r`` [Pa]; the robot stores it as the
per-tet factor ``modulus_scale_e = E_r / E`` (:attr:`~soft_envs.sim.robot.Robot.modulus_scale`).

Derivative. The elastic gradient is linear in the per-element Lame parameters (eq. 1,
:mod:`soft_envs.sim.elastic`), ``mu_e = E_e / (2(1 + nu))`` and ``lam_e = E_e nu / ((1 + nu)(1
- 2nu))`` are linear in ``E_e``, so

.. math::
    \frac{\partial (dE/dx)}{\partial E_r} = \frac{d\mu}{dE} G_\mu^{(r)} + \frac{d\lambda}{dE}
    G_\lambda^{(r)},

the gradient kernel evaluated with ``(mu_e, lam_e) = mask_r (dmu/dE, dlam/dE)``
(:meth:`~soft_envs.sim.elastic.Elastic.lame_gradient`, the kernel of the ``youngs_modulus``
parameter restricted to the region). The masses do not depend on E.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..parameters import lame_jacobian

__all__ = ["Region", "region_from_boxes", "region_from_cell_tags", "RegionalModuli"]

#: default bounds of a regional modulus, as factors of the fitted one (castable foams)
MODULUS_BOUNDS = (0.3, 3.0)


@dataclass(frozen=True, eq=False)
class Region:
    """A named set of tets (``elements``: sorted indices)."""

    name: str
    elements: np.ndarray


def region_from_boxes(robot, name: str, boxes: Sequence[Sequence[float]]) -> Region:
    """The tets of ``robot`` whose centroid lies in one of ``boxes`` (each ``[xmin, ymin, zmin,
    xmax, ymax, zmax]`` in the simulation frame, metres). An empty region is a ValueError."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 6) if len(boxes) else np.zeros((0, 6))
    if not np.isfinite(b).all() or (b[:, 3:] < b[:, :3]).any():
        raise ValueError(f"{robot.source}: design region {name!r}: boxes must be finite [xmin, ymin, zmin, "
                         f"xmax, ymax, zmax] with min <= max, got {np.asarray(boxes).tolist()}")
    c = robot.mesh.points[robot.mesh.tets].mean(axis=1)
    inside = np.zeros(len(c), bool)
    for box in b:
        inside |= ((c >= box[:3]) & (c <= box[3:])).all(axis=1)
    if not inside.any():
        raise ValueError(f"{robot.source}: design region {name!r}: no tet centroid lies in its boxes "
                         f"{b.tolist()}")
    return Region(name, np.flatnonzero(inside))


def region_from_cell_tags(robot, name: str, tags: np.ndarray, tag: int) -> Region:
    """The tets whose entry of ``tags`` (one integer per tet, e.g. a mesh's cell data) is ``tag``."""
    tags = np.asarray(tags)
    if tags.shape != (robot.mesh.n_tets,):
        raise ValueError(f"{robot.source}: design region {name!r}: cell tags must have one entry per tet "
                         f"({robot.mesh.n_tets}), got shape {tags.shape}")
    elements = np.flatnonzero(tags == tag)
    if not elements.size:
        raise ValueError(f"{robot.source}: design region {name!r}: no tet has cell tag {tag!r}")
    return Region(name, elements)


class RegionalModuli:
    """Young's modulus per region as design parameters (one column per region, in Pa).

    ``bounds`` (factors of the robot's fitted modulus, default 0.3x to 3x) gives
    :attr:`bounds` (len, 2) in Pa. The modulus must be uniform inside each region of ``robot``."""

    kind = "stiffness"

    def __init__(self, robot, regions: Sequence[Region], bounds: tuple[float, float] = MODULUS_BOUNDS):
        seen = np.zeros(robot.mesh.n_tets, dtype=np.int64)
        for r in regions:
            seen[r.elements] += 1
        if (seen > 1).any():
            raise ValueError(f"{robot.source}: design regions overlap (tet {int(np.argmax(seen > 1))} is in "
                             "more than one)")
        names = [r.name for r in regions]
        if len(set(names)) != len(names):
            raise ValueError(f"{robot.source}: design region names repeat: {names}")
        lo, hi = (float(v) for v in bounds)
        if not (0 < lo <= 1 <= hi and np.isfinite(hi)):
            raise ValueError(f"{robot.source}: design modulus bounds must satisfy 0 < low <= 1 <= high, got {bounds}")
        self.regions = tuple(regions)
        self.factor_bounds = (lo, hi)
        self.names = tuple(f"stiffness:{r.name}" for r in regions)
        scale = robot.element_modulus_scale
        for r in regions:
            if np.ptp(scale[r.elements]) > 1e-12 * scale[r.elements].max():
                raise ValueError(f"{robot.source}: design region {r.name!r}: the modulus is not uniform in it")
        E = robot.youngs_modulus
        self.values = np.array([E * scale[r.elements[0]] for r in regions])
        self.bounds = np.array([[lo * E, hi * E]] * len(regions)).reshape(-1, 2)
        self._dlame = lame_jacobian(E, robot.poisson_ratio)["youngs_modulus"]    # (dmu/dE, dlam/dE)

    def moved_to(self, robot, values: np.ndarray) -> "RegionalModuli":
        """These regions at ``robot`` (the design at ``values``): the same tets, values ``values``
        (robot's moduli), bounds relative to the original fitted modulus (``youngs_modulus``,
        which no design changes)."""
        new = RegionalModuli(robot, self.regions, self.factor_bounds)
        if not np.allclose(new.values, values, rtol=1e-12, atol=0):
            raise ValueError(f"{robot.source}: the moduli of the moved robot are not the design's")
        return new

    def apply(self, robot, theta: np.ndarray) -> dict:
        """The :class:`~soft_envs.sim.robot.Robot` field changes of moduli ``theta`` (Pa)."""
        scale = robot.element_modulus_scale
        for r, E_r in zip(self.regions, theta):
            if not (np.isfinite(E_r) and E_r > 0):
                raise ValueError(f"design modulus of region {r.name!r} must be positive, got {E_r!r}")
            scale[r.elements] = E_r / robot.youngs_modulus
        return {"modulus_scale": scale}

    def force_jacobian(self, system, x, x_prev, u, history) -> np.ndarray:
        """``d(dE/dx)/dE_r`` (3n, n_regions)."""
        out = np.zeros((system.n_dof, len(self.regions)))
        dmu, dlam = self._dlame
        for j, r in enumerate(self.regions):
            mask = np.zeros(system.robot.mesh.n_tets)
            mask[r.elements] = 1.0
            out[:, j] = system.elastic.lame_gradient(x, dmu * mask, dlam * mask)
        return out
