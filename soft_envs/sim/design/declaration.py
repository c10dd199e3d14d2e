"""The ``[design]`` table of a robot.toml: which design parameters co-design may vary.

.. code-block:: toml

    [design]                        # absent: the robot is fixed
    routing = ["front_a", "back_a"] # tendons whose via points move ("all": every tendon);
                                    # a tendon mirroring a routed one follows it
    fixed_points = [-1]             # indices of each routed tendon's points that stay
                                    # (default: the last, where it leaves the body to its motor)
    hip_height = 0.03               # legs = connected parts below this height above the lowest
                                    # rest node (file units)
    modulus_bounds = [0.3, 3.0]     # regional moduli's bounds, factors of the fitted modulus

    [[design.regions]]              # Young's modulus per region
    name = "middle_leg"
    boxes = [[0.055, 0.0, 0.0, 0.085, 0.03, 0.04]]   # [x0, y0, z0, x1, y1, z1], mesh frame
    # or: cell_tag = 2 with cell_data = "region" (an integer cell-data array of the mesh file)

:func:`load_design` reads it and returns the :class:`~.block.DesignParameters` of the kinds
asked for (``vary``: a subset of ``("routing", "stiffness", "legs")``). Every error is a
ValueError naming the file and the field.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import meshio
import numpy as np

from ..robot_file import robot_document
from .block import DesignParameters
from .morph import LegMorph, legs_below
from .regions import MODULUS_BOUNDS, RegionalModuli, region_from_boxes, region_from_cell_tags
from .routing import TendonRouting

__all__ = ["KINDS", "load_design"]

#: the design kinds, in the order of their columns
KINDS = ("stiffness", "routing", "legs")
_KEYS = ("routing", "fixed_points", "hip_height", "modulus_bounds", "regions")
_REGION_KEYS = ("name", "boxes", "cell_tag", "cell_data")


def load_design(robot, vary: Sequence[str] = KINDS) -> DesignParameters:
    """The design parameters that ``robot``'s file (``robot.source``) declares for the kinds in
    ``vary``. A kind asked for but not declared is a ValueError naming the missing key."""
    src = robot.source
    for k in vary:
        if k not in KINDS:
            raise ValueError(f"unknown design kind {k!r} (known: {', '.join(KINDS)})")
    doc, to_sim = robot_document(src)
    table = doc.get("design")
    if not isinstance(table, dict):
        raise ValueError(f"{src}: no [design] table: the robot declares nothing that co-design may vary")
    for key in table:
        if key not in _KEYS:
            raise ValueError(f"{src}: unknown key [design].{key} (allowed: {', '.join(_KEYS)})")
    kinds = []
    if "stiffness" in vary:
        kinds.append(_moduli(robot, table, doc, to_sim, src))
    if "routing" in vary:
        kinds.append(_routing(robot, table, src))
    if "legs" in vary:
        if "hip_height" not in table:
            raise ValueError(f"{src}: [design].hip_height is missing (needed to vary the legs)")
        hip = _number(table["hip_height"], "[design].hip_height", src)
        scale = float(np.linalg.norm(to_sim(np.array([1.0, 0.0, 0.0]))))
        hip_sim = float((robot.mesh.points @ robot.up_axis).min()) + scale * hip
        _check_hip_height(robot, hip, hip_sim, scale, src)
        kinds.append(LegMorph(robot, legs_below(robot, hip_sim), hip_sim))
    return DesignParameters(robot, kinds)


def _check_hip_height(robot, hip: float, hip_sim: float, scale: float, src: str) -> None:
    """The legs are the parts below the hip and the body the rest: a hip height with no tet
    below it, or none above it (the whole robot would be one leg), is refused naming the field."""
    mesh = robot.mesh
    up = int(np.argmax(np.abs(robot.up_axis)))
    centroids = mesh.points[mesh.tets].mean(axis=1)[:, up]
    height = float(np.ptp(mesh.points @ robot.up_axis)) / scale
    if not hip > 0.0 or not (centroids < hip_sim).any():
        raise ValueError(f"{src}: [design].hip_height = {hip!r} leaves no tet below it: the legs are the parts "
                         f"below the hip, measured from the lowest rest node (the robot is {height:.4g} high, file "
                         "units)")
    if not (centroids >= hip_sim).any():
        raise ValueError(f"{src}: [design].hip_height = {hip!r} lies above the whole robot ({height:.4g} high, file "
                         "units, from its lowest rest node): every tet would be a leg; give the height of the hips")


def _number(v, where: str, src: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"{src}: {where} must be a number, got {v!r}")
    return float(v)


def _moduli(robot, table: dict, doc: dict, to_sim, src: str) -> RegionalModuli:
    raw = table.get("regions")
    if not raw:
        raise ValueError(f"{src}: [[design.regions]] is missing (needed to vary the stiffness)")
    bounds = table.get("modulus_bounds", list(MODULUS_BOUNDS))
    if not (isinstance(bounds, list) and len(bounds) == 2):
        raise ValueError(f"{src}: [design].modulus_bounds must be [low, high], got {bounds!r}")
    bounds = tuple(_number(b, "[design].modulus_bounds", src) for b in bounds)
    if bounds[0] == bounds[1]:
        raise ValueError(f"{src}: [design].modulus_bounds = {list(bounds)} leaves the moduli nothing to vary "
                         "(low = high); give a range around 1, e.g. [0.3, 3.0], or leave stiffness out of --vary")
    regions = []
    for i, r in enumerate(raw):
        where = f"[[design.regions]][{i}]"
        if not isinstance(r, dict) or not isinstance(r.get("name"), str):
            raise ValueError(f"{src}: {where} needs a name")
        for key in r:
            if key not in _REGION_KEYS:
                raise ValueError(f"{src}: unknown key {where}.{key} (allowed: {', '.join(_REGION_KEYS)})")
        if ("boxes" in r) == ("cell_tag" in r):
            raise ValueError(f"{src}: {where} ({r['name']!r}) needs either boxes or cell_tag")
        if "boxes" in r:
            try:
                boxes = np.asarray(r["boxes"], dtype=np.float64).reshape(-1, 6)
            except (TypeError, ValueError):
                raise ValueError(f"{src}: {where}.boxes must be a list of [x0, y0, z0, x1, y1, z1], "
                                 f"got {r['boxes']!r}") from None
            lo, hi = to_sim(boxes[:, :3]), to_sim(boxes[:, 3:])
            sim_boxes = np.hstack([np.minimum(lo, hi), np.maximum(lo, hi)])
            regions.append(region_from_boxes(robot, r["name"], sim_boxes))
        else:
            regions.append(region_from_cell_tags(robot, r["name"], _cell_tags(doc, r, src, where), r["cell_tag"]))
    return RegionalModuli(robot, regions, bounds)


def _cell_tags(doc: dict, region: dict, src: str, where: str) -> np.ndarray:
    name = region.get("cell_data")
    if not isinstance(name, str):
        raise ValueError(f"{src}: {where}.cell_data (the mesh's cell-data array) is missing")
    mesh_file = Path(src).parent / doc["robot"]["mesh"]
    m = meshio.read(mesh_file)
    if name not in m.cell_data:
        raise ValueError(f"{src}: {where}.cell_data: the mesh {str(mesh_file)!r} has no cell data {name!r} "
                         f"(it has: {sorted(m.cell_data)})")
    blocks = [np.asarray(d) for d, c in zip(m.cell_data[name], m.cells) if c.type == "tetra"]
    return np.concatenate(blocks) if blocks else np.zeros(0)


def _routing(robot, table: dict, src: str) -> TendonRouting:
    names = table.get("routing")
    if names is None:
        raise ValueError(f"{src}: [design].routing is missing (needed to vary the routing)")
    if names == "all":
        names = robot.tendon_names
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise ValueError(f"{src}: [design].routing must be a list of tendon names or \"all\", got {names!r}")
    if not names:
        raise ValueError(f"{src}: [design].routing = [] names no tendon: name the tendons whose via points may "
                         f"move (known: {', '.join(robot.tendon_names)}), or \"all\"; or leave routing out of --vary")
    fixed = table.get("fixed_points", [-1])
    if not (isinstance(fixed, list) and all(isinstance(i, int) and not isinstance(i, bool) for i in fixed)):
        raise ValueError(f"{src}: [design].fixed_points must be a list of point indices, got {fixed!r}")
    for n in names:
        if n in robot.tendon_names:
            P = len(robot.tendons[robot.tendon_names.index(n)].points)
            bad = [i for i in fixed if not -P <= i < P]
            if bad:
                raise ValueError(f"{src}: [design].fixed_points: point {bad[0]} does not exist on tendon {n!r}, "
                                 f"which has {P} points (indices 0..{P - 1}, or -{P}..-1 from the end)")
    return TendonRouting(robot, names, fixed)
