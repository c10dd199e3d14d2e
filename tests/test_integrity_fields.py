"""Integrity checks tried with every kind of edit (issue #30, class "integrity checks tried with
one edited field"): a result's hash covers its metadata as well as its arrays, and a robot's
fingerprint covers the mesh's node positions as well as its connectivity and the robot.toml."""
from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

from soft_envs.envs import robot_fingerprint
from soft_envs.sim.mesh import load_mesh
from trajopt.results.result import Result
from trajopt.results.robot_match import describe_difference


def _result() -> Result:
    u = np.full((20, 2), 2e-3)
    return Result(robot="tripod", task="walk", motor_names=["front", "back"], dt=0.033, z=np.zeros(3), u=u,
                  u_post=u.copy(), target=np.zeros((21, 2)), com=np.zeros((21, 3)), status="done",
                  settings={"n_prep": 0, "n_cycle": 20, "speed_bl_per_min": 8.0})


def _edit_npz(path, edit) -> None:
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    edit(arrays)
    np.savez(path, **arrays)


@pytest.mark.parametrize("what", ["a setting", "the status", "the time step"])
def test_a_result_with_edited_metadata_is_refused(tmp_path, what):
    path = _result().save(tmp_path / "r")
    key, value = {"a setting": ("settings", {"n_prep": 0, "n_cycle": 20, "speed_bl_per_min": 80.0}),
                  "the status": ("status", "edited"), "the time step": ("dt", 0.05)}[what]

    def edit(arrays):
        meta = json.loads(str(arrays["meta"]))
        assert key in meta
        meta[key] = value
        arrays["meta"] = np.array(json.dumps(meta))
    _edit_npz(path, edit)
    with pytest.raises(ValueError, match=r"r\.npz: its content does not match its content_sha256"):
        Result.load(path)


def test_an_unedited_result_loads(tmp_path):
    path = _result().save(tmp_path / "r")
    _edit_npz(path, lambda arrays: None)               # rewritten, nothing changed
    assert Result.load(path).settings["speed_bl_per_min"] == 8.0


def _move_nodes(robot_dir, shift: float) -> None:
    mesh = load_mesh(robot_dir / "tripod.vtu")
    pts = np.array(mesh.points)
    top = pts[:, 1] > np.median(pts[:, 1])
    pts[top, 1] += shift                                # same tets, some nodes higher
    meshio.write(robot_dir / "tripod.vtu", meshio.Mesh(pts, [("tetra", np.array(mesh.tets))]))


def test_moving_mesh_nodes_with_the_same_connectivity_changes_the_fingerprint(robot_dir):
    before = robot_fingerprint(robot_dir / "robot.toml")
    _move_nodes(robot_dir, 1e-4)                       # 0.1 mm: far above the hash's 1e-9 rounding
    after = robot_fingerprint(robot_dir / "robot.toml")
    assert after["toml_sha256"] == before["toml_sha256"]
    assert after["mesh_sha256"] != before["mesh_sha256"] and after["sha256"] != before["sha256"]
    assert describe_difference(before, after) == "the mesh changed"


def test_rewriting_the_same_mesh_keeps_the_fingerprint(robot_dir):
    before = robot_fingerprint(robot_dir / "robot.toml")
    _move_nodes(robot_dir, 0.0)
    assert robot_fingerprint(robot_dir / "robot.toml")["sha256"] == before["sha256"]
