"""Writing a designed robot as a robot folder that every command loads unchanged.

:func:`write_designed_robot` copies the source robot.toml (comments and layout kept, through
tomlkit) into a new folder and sets what the design changed, in the file's own frame and
units:

* routing: every ``[[tendons]]`` table's ``points`` (and an explicit ``rest_length``);
* moduli: ``[[material.regions]]`` tables (``name``, ``youngs_modulus``, ``tets``), read back by
  :func:`~soft_envs.sim.robot_file.load_robot` into ``Robot.modulus_scale``;
* leg lengths: a new mesh file ``mesh.vtu`` (``[robot].mesh`` points at it) and the markers'
  points; otherwise the source's mesh is copied in as ``mesh.vtu`` (the folder is self-contained:
  a copy of it, anywhere, is the same robot). The ``[design]`` table
  is kept (the written robot can be co-designed again) with, when the mesh moved, its
  ``hip_height`` measured from the new lowest node at the absolute hip height the source's
  declares, and its ``[[design.regions]]`` as cell tags of the mesh (cell data
  ``design_region``): ``load_design`` on the written folder finds the same legs and regions.

The written folder is loaded back and compared with ``design.robot_at(theta)`` (node positions,
tendon points, element moduli, masses): a mismatch is a RuntimeError. A different robot file
means a different :func:`~soft_envs.sim.fingerprint.robot_fingerprint`, so results made on one
robot refuse the other.
"""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import meshio
import numpy as np

from ..robot_file import load_robot, robot_document
from .block import DesignParameters
from .declaration import load_design

__all__ = ["write_designed_robot", "HEADER"]

HEADER = "# Designed by soft_envs.sim.design"


def write_designed_robot(design: DesignParameters, theta, out_dir: str | Path) -> Path:
    """Write the robot of design ``theta`` into ``out_dir`` (created); returns its robot.toml."""
    import tomlkit

    source = Path(design.robot.source)
    if not source.is_file():
        raise ValueError(f"the design's robot was not loaded from a robot.toml ({design.robot.source!r}): "
                         "there is no file to start the new one from")
    out = Path(out_dir)
    target = out / "robot.toml"
    if target.resolve() == source.resolve():
        raise ValueError(f"{target} is the source robot file: a design never overwrites it")
    out.mkdir(parents=True, exist_ok=True)
    robot = design.robot_at(theta)
    _, to_sim = robot_document(source)
    M = to_sim(np.eye(3))                       # rows: the simulation-frame images of the file axes
    to_file = lambda p: np.asarray(p, dtype=np.float64) @ np.linalg.inv(M)   # noqa: E731
    doc = tomlkit.parse(source.read_text(encoding="utf-8"))

    for table, tendon in zip(doc.get("tendons", []), robot.tendons):
        table["points"] = [[float(v) for v in p] for p in to_file(tendon.points)]
        if tendon.rest_length is not None:
            table["rest_length"] = float(tendon.rest_length)
    for table, marker in zip(doc.get("markers", []), robot.markers):
        table["point"] = [float(v) for v in to_file(marker.point)]

    regions = [k for k in design.kinds if k.kind == "stiffness"]
    if regions:
        mat = doc["material"]
        array = tomlkit.aot()
        for region in regions[0].regions:
            t = tomlkit.table()
            t["name"] = region.name
            t["youngs_modulus"] = float(robot.youngs_modulus * robot.element_modulus_scale[region.elements[0]])
            t["tets"] = [int(e) for e in region.elements]
            array.append(t)
        mat["regions"] = array

    mesh = (source.parent / str(doc["robot"]["mesh"])).resolve()
    shipped = load_robot(source)
    if np.array_equal(robot.mesh.points, shipped.mesh.points):       # the source's mesh, copied in
        _replace(out / MESH, lambda tmp: shutil.copyfile(mesh, tmp) if mesh.suffix == ".vtu"
                 else meshio.write(tmp, meshio.read(mesh), file_format="vtu"))
    else:
        tags = _design_regions_as_tags(design.robot.mesh.n_tets, doc, source)
        moved = _moved_mesh(mesh, robot.mesh, to_file(robot.mesh.points), tags)
        _replace(out / MESH, lambda tmp: meshio.write(tmp, moved, file_format="vtu"))
        _move_hip_height(doc, shipped, robot, float(np.linalg.norm(M[0])))
    doc["robot"]["mesh"] = MESH

    changed = ", ".join(f"{n} = {float(v):.6g}" for n, v, v0 in zip(design.names, theta, design.values) if v != v0)
    text = f"{HEADER} from {source} on {time.strftime('%Y-%m-%d %H:%M')}: {changed or 'no change'}\n"
    _replace(target, lambda tmp: Path(tmp).write_text(text + tomlkit.dumps(doc), encoding="utf-8"))
    _check_written(target, robot)
    return target


#: the mesh file of a written robot folder
MESH = "mesh.vtu"


def _replace(path: Path, write) -> None:
    """``write(temporary)`` beside ``path``, then renamed over it (atomic: a reader sees the old
    file or the new one, never half of one)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


#: the written mesh's cell-data array of the ``[[design.regions]]`` (when the mesh moved)
REGION_CELL_DATA = "design_region"


def _design_regions_as_tags(n_tets: int, doc, source: Path) -> np.ndarray | None:
    """When the source declares ``[[design.regions]]``: one tag per tet (region i: i + 1, else 0),
    and the regions rewritten as ``cell_tag`` of :data:`REGION_CELL_DATA` (boxes would pick other
    tets of a morphed mesh)."""
    table = doc.get("design")
    if not isinstance(table, dict) or not table.get("regions"):
        return None
    regions = load_design(load_robot(source), ["stiffness"]).kinds[0].regions     # the tets never change
    tags = np.zeros(n_tets, dtype=np.int64)
    for i, (region, entry) in enumerate(zip(regions, table["regions"])):
        tags[region.elements] = i + 1
        for key in ("boxes", "cell_tag", "cell_data"):
            entry.pop(key, None)
        entry["cell_tag"] = i + 1
        entry["cell_data"] = REGION_CELL_DATA
    return tags


def _move_hip_height(doc, shipped, robot, scale: float) -> None:
    """``[design].hip_height`` (file units, above the lowest node) of the moved mesh at the
    absolute height the source's declares (above the ``shipped`` robot's lowest node), so that
    ``load_design`` finds the same legs."""
    table = doc.get("design")
    hip = table.get("hip_height") if isinstance(table, dict) else None
    if isinstance(hip, (int, float)) and not isinstance(hip, bool):
        up = robot.up_axis
        absolute = float((shipped.mesh.points @ up).min()) + scale * float(hip)
        table["hip_height"] = (absolute - float((robot.mesh.points @ up).min())) / scale


def _moved_mesh(source_file: Path, mesh, points: np.ndarray, tags: np.ndarray | None = None) -> meshio.Mesh:
    """The source mesh file's content (cells, cell data such as region tags) with new
    ``points``, when its tets are the robot's; otherwise the bare tets. ``tags``: one integer
    per tet, written as the cell data :data:`REGION_CELL_DATA`."""
    original = meshio.read(source_file)
    tetra = [c.data for c in original.cells if c.type == "tetra"]
    if original.points.shape[0] == len(points) and tetra and np.array_equal(np.concatenate(tetra), mesh.tets):
        cells, cell_data = original.cells, dict(original.cell_data)
    else:
        cells, cell_data = [meshio.CellBlock("tetra", np.array(mesh.tets))], {}
    if tags is not None:
        blocks, start = [], 0
        for c in cells:
            n = len(c.data)
            blocks.append(tags[start:start + n] if c.type == "tetra" else np.zeros(n, dtype=np.int64))
            start += n if c.type == "tetra" else 0
        cell_data[REGION_CELL_DATA] = blocks
    return meshio.Mesh(points, cells, cell_data=cell_data)


def _check_written(target: Path, robot) -> None:
    back = load_robot(target)
    checks = {"node positions": (back.mesh.points, robot.mesh.points),
              "element moduli": (back.element_lame()[0], robot.element_lame()[0]),
              "node masses": (back.node_masses, robot.node_masses),
              "payload nodes": (back.payload_nodes, robot.payload_nodes),
              "fixed nodes": (back.fixed_nodes, robot.fixed_nodes)}
    for a, b in zip(back.tendons, robot.tendons):
        checks[f"tendon {a.name!r} points"] = (np.asarray(a.points), np.asarray(b.points))
    for what, (a, b) in checks.items():
        if np.shape(a) != np.shape(b) or not np.allclose(a, b, rtol=1e-12, atol=1e-12):
            raise RuntimeError(f"{target}: the written robot's {what} differ from the design's")
