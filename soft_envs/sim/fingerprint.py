"""The fingerprint of a robot description: what ties a result to the robot it was made for.

:func:`robot_fingerprint` hashes a ``robot.toml`` as parsed and normalised (comments, layout, key
order, ``1`` vs ``1.0`` and the ``[design]`` table do not count) and its mesh as read (positions rounded to 1e-9 of the
mesh's size, and tets; the file format does not count). ``trajopt.results.robot_match`` compares two
fingerprints and names the fields that changed.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from .mesh import load_mesh
from .robot import MOTOR_DEFAULTS, Robot
from .robot_file import read_robot_toml, robot_file_path

__all__ = ["robot_fingerprint"]


def _normalised(v: Any) -> Any:
    """Numbers as floats (``1`` and ``1.0`` are one value), everything else as parsed."""
    if isinstance(v, dict):
        return {k: _normalised(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_normalised(x) for x in v]
    if isinstance(v, int) and not isinstance(v, bool):
        return float(v)
    return v


def robot_fingerprint(source: str | Path | Robot) -> dict[str, Any] | None:
    """What identifies a robot description, to tie a result to the robot it was made for.

    ``source``: a shipped name, a ``robot.toml`` path, or a :class:`Robot` (its ``source``
    file; None for a robot built in Python). Returns ``{"name", "source", "sha256",
    "toml_sha256", "mesh_sha256", "toml"}``: the ``[robot].name``, the file, and SHA-256 hashes
    of the whole, of the ``robot.toml`` as parsed (comments, layout, key order, ``1`` vs ``1.0``,
    ``[robot].mesh`` and ``description`` do not count, nor the ``[design]`` table (what co-design
    may vary does not change the robot), nor a motor's ``max_speed_rpm``, ``stall_torque`` or
    ``max_torque`` written out at its default (:data:`~.robot.MOTOR_DEFAULTS`: the same motor as a
    file without the key; another value is part of it); ``toml`` is that normalised document, so a
    mismatch can name the fields that changed) and of the mesh as read (node positions rounded to
    1e-9 of the mesh's size, and tets; the file format does not count)."""
    if isinstance(source, Robot):
        if not Path(source.source).is_file():
            return None
        path = Path(source.source)
    else:
        path = robot_file_path(source)
    doc = read_robot_toml(path)
    robot_tbl = doc.get("robot", {}) if isinstance(doc.get("robot"), dict) else {}
    mesh_name = robot_tbl.get("mesh")
    if not isinstance(mesh_name, str):
        raise ValueError(f"{path}: [robot].mesh is missing")
    mesh = load_mesh(path.parent / mesh_name)
    norm = _normalised(doc)
    norm.get("robot", {}).pop("mesh", None)
    norm.get("robot", {}).pop("description", None)
    norm.pop("design", None)     # what co-design may vary is no part of the robot (docs/codesign.md)
    for motor in norm.get("motors", []) if isinstance(norm.get("motors"), list) else []:
        for key, default in MOTOR_DEFAULTS.items():    # the default written out is the same robot (older files)
            if isinstance(motor, dict) and motor.get(key) == default:
                del motor[key]
    toml_text = json.dumps(norm, sort_keys=True, separators=(",", ":"), default=str)
    size = float(np.ptp(mesh.points, axis=0).max()) or 1.0
    h = hashlib.sha256()
    h.update(np.round(mesh.points / size * 1e9).astype(np.int64).tobytes())
    h.update(mesh.tets.astype(np.int64).tobytes())
    mesh_hash = h.hexdigest()
    toml_hash = hashlib.sha256(toml_text.encode()).hexdigest()
    return {"name": str(robot_tbl.get("name", "")), "source": str(path),
            "sha256": hashlib.sha256(f"{toml_hash}:{mesh_hash}".encode()).hexdigest(),
            "toml_sha256": toml_hash, "mesh_sha256": mesh_hash, "toml": json.loads(toml_text)}
