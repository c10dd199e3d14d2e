"""A result is tied to the robot it was made for (issue #16 item 6): its fingerprint (robot.toml
and mesh, normalised) is stored, and replay, render, evaluate, export, plot and play refuse
another or an edited robot with a message naming both, unless --ignore-robot-mismatch."""
from __future__ import annotations

import shutil
from pathlib import Path

import meshio
import numpy as np
import pytest

from soft_envs.envs import robot_fingerprint
from soft_envs.sim.robot_file import asset_path
from trajopt.cli import main
from trajopt.results.result import Result

STEPS = 12


def run(argv, capsys) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def copy_robot(name: str, directory: Path) -> Path:
    src = asset_path(name).parent
    directory.mkdir(parents=True, exist_ok=True)
    for p in src.glob("*"):
        if p.name in ("robot.toml", f"{name}.vtu"):
            shutil.copy(p, directory / p.name)
    return directory / "robot.toml"


def gait_for(toml: Path | str, n_motors: int = 2, fingerprint: bool = True) -> Result:
    """A gentle open-loop gait (no optimisation needed) made for the robot of ``toml``."""
    s = np.linspace(0, 1, STEPS)[:, None]
    u = 0.004 * np.sin(np.pi * s) ** 2 * np.ones((1, n_motors))
    names = ["front", "back"] if n_motors == 2 else [f"m{i}" for i in range(n_motors)]
    return Result(robot=str(toml), task="walk", motor_names=names, dt=0.033, z=np.zeros(0), u=u, u_post=u,
                  target=np.zeros((0, 2)), com=np.zeros((0, 3)), settings={"n_prep": 0, "n_cycle": STEPS},
                  robot_fingerprint=robot_fingerprint(toml) if fingerprint else {})


def test_the_fingerprint_ignores_layout_and_file_format_but_not_content(tmp_path):
    toml = copy_robot("tripod", tmp_path / "a")
    base = robot_fingerprint(toml)
    assert base["name"] == "tripod" and len(base["sha256"]) == 64
    assert robot_fingerprint("tripod")["sha256"] == base["sha256"]
    text = toml.read_text()
    # comments, blank lines, the order of keys, 1 vs 1.0 and the mesh's file format do not count
    mesh = meshio.read(tmp_path / "a" / "tripod.vtu")
    meshio.write(tmp_path / "a" / "tripod.msh", mesh, file_format="gmsh22")
    toml.write_text("# a comment\n\n" + text.replace("youngs_modulus = 1e+05", "youngs_modulus = 100000")
                    .replace('name = "tripod"\nmesh = "tripod.vtu"', 'mesh = "tripod.msh"\nname = "tripod"'))
    assert robot_fingerprint(toml)["sha256"] == base["sha256"]
    toml.write_text(text.replace("u_max = 0.02", "u_max = 0.015", 1))
    edited = robot_fingerprint(toml)
    assert edited["sha256"] != base["sha256"] and edited["mesh_sha256"] == base["mesh_sha256"]


def test_results_of_trajopt_record_their_robot(tmp_path):
    from soft_envs.envs import make_gradient_env
    from trajopt import GaitSpec, GaussNewtonOptions, optimize_gait
    toml = copy_robot("tripod", tmp_path / "r")
    res = optimize_gait(make_gradient_env(toml), gait=GaitSpec(n_prep=2, n_cycle=8, n_keyframes=2), n_seeds=0,
                        eval_cycles=1, options=GaussNewtonOptions(max_iter=1), robot_spec=str(toml))
    assert res.robot_fingerprint["sha256"] == robot_fingerprint(toml)["sha256"]
    back = Result.load(res.save(tmp_path / "walk"))
    assert back.robot_fingerprint == res.robot_fingerprint


@pytest.fixture
def edited(tmp_path):
    """A result made for a Tripod whose robot.toml was then edited (narrower motor range)."""
    toml = copy_robot("tripod", tmp_path / "robot")
    path = gait_for(toml).save(tmp_path / "gait")
    toml.write_text(toml.read_text().replace("u_max = 0.02", "u_max = 0.015"))
    return path, toml


COMMANDS = {
    "evaluate": lambda p, t: ["evaluate", p],
    "render": lambda p, t: ["render", p, "--gif", t / "g.gif", "--every", "6", "--size", "64x48"],
    "export": lambda p, t: ["export", p, "--vtu", t / "vtu"],
    "plot": lambda p, t: ["plot", p, "--out", t / "plots"],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_an_edited_robot_is_refused_naming_both_and_the_field(edited, tmp_path, capsys, command):
    path, toml = edited
    out_dir = tmp_path / "out"
    code, _, err = run(COMMANDS[command](path, out_dir), capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{path} was made for robot 'tripod'" in err and f"'{toml}' is now robot 'tripod'" in err
    assert "motors[0].u_max: 0.02 -> 0.015" in err and "--ignore-robot-mismatch" in err
    assert not out_dir.exists()
    code, _, err = run([*COMMANDS[command](path, out_dir), "--ignore-robot-mismatch"], capsys)
    assert code in (0, 1) and "warning" in err and "used anyway" in err, err


def test_another_robot_is_refused_even_with_the_override(tmp_path, capsys):
    toml = copy_robot("tripod", tmp_path / "robot")
    path = gait_for(toml).save(tmp_path / "gait")
    shutil.rmtree(tmp_path / "robot")
    copy_robot("puppy", tmp_path / "robot")                    # the path now holds another robot
    for extra in ([], ["--ignore-robot-mismatch"]):
        code, _, err = run(["evaluate", path, *extra], capsys)
        assert code == 2 and "made for 2 motors (front, back)" in err and "a robot with 8" in err
        assert "another robot ('puppy' instead of 'tripod')" in err and "cannot be applied" in err


def test_a_result_without_fingerprint_is_checked_by_its_motors(tmp_path, capsys):
    toml = copy_robot("puppy", tmp_path / "robot")
    path = gait_for(toml, n_motors=3, fingerprint=False).save(tmp_path / "old")
    code, _, err = run(["evaluate", path], capsys)
    assert code == 2 and "made for 3 motors (m0, m1, m2)" in err and "a robot with 8" in err


def test_resume_refuses_a_changed_robot():
    from trajopt.optim.optimize import check_resume
    res = gait_for(asset_path("tripod"))
    res.settings.update(source="ckpt.partial.npz")
    other = dict(res.robot_fingerprint, sha256="0" * 64, toml_sha256="1" * 64,
                 toml={**res.robot_fingerprint["toml"], "material": {"density": 1.0}})
    settings = {k: res.settings.get(k) for k in ("n_prep", "n_cycle")}
    with pytest.raises(ValueError, match=r"ckpt\.partial\.npz: cannot resume: the robot is not the interrupted "
                                         r"run's \(robot\.toml changed \(\[material\]\.density"):
        check_resume(res, "walk", {**res.settings, **settings, "n_cycles": 2, "n_keyframes": 4, "symmetry": True,
                                   "speed_bl_per_min": None, "heading_deg": None, "turn": None,
                                   "incline_deg": None}, other)


def hardware_file(tmp_path: Path, robot_line: str) -> Path:
    from trajopt.hardware import EXAMPLE_TRIPOD
    text = EXAMPLE_TRIPOD.read_text().replace('robot = "tripod"', robot_line)
    assert robot_line in text
    path = tmp_path / "hw.toml"
    path.write_text(text)
    return path


def test_play_checks_the_hardware_files_robot(tmp_path, capsys):
    toml = copy_robot("tripod", tmp_path / "robot")
    path = gait_for("tripod").save(tmp_path / "gait")
    play = ["play", path, "--dry-run", "--hardware"]
    assert run([*play, hardware_file(tmp_path, 'robot = "tripod"')], capsys)[0] == 0
    code, _, err = run([*play, hardware_file(tmp_path, 'robot = "puppy"')], capsys)
    assert code == 2 and "hw.toml describes robot 'puppy', but" in err and "made for robot 'tripod'" in err
    code, _, err = run([*play, hardware_file(tmp_path, 'robot = "puppy"'), "--ignore-robot-mismatch"], capsys)
    assert code == 0 and "played anyway" in err
    hw = hardware_file(tmp_path, 'robot = "robot/robot.toml"')     # a robot file, relative to hw.toml
    assert run([*play, hw], capsys)[0] == 0
    toml.write_text(toml.read_text().replace("u_max = 0.02", "u_max = 0.015"))
    code, _, err = run([*play, hw], capsys)
    assert code == 2 and "robot.toml changed (motors[0].u_max: 0.02 -> 0.015" in err


def test_play_refuses_a_result_whose_robot_file_was_edited(edited, capsys):
    path, _ = edited
    from trajopt.hardware import EXAMPLE_TRIPOD
    code, _, err = run(["play", path, "--dry-run", "--hardware", EXAMPLE_TRIPOD], capsys)
    assert code == 2 and "motors[0].u_max: 0.02 -> 0.015" in err


def test_moved_mesh_nodes_with_the_same_connectivity_change_the_fingerprint(tmp_path, capsys):
    """The robot.toml unchanged, the mesh's tets the same, one node moved by 1 mm: another robot
    body. Its fingerprint changes (the mesh part only), and the result made for the robot as it
    was refuses to replay and to play on it."""
    toml = copy_robot("tripod", tmp_path / "robot")
    path = gait_for(toml).save(tmp_path / "gait")
    before = robot_fingerprint(toml)
    vtu = tmp_path / "robot" / "tripod.vtu"
    mesh = meshio.read(vtu)
    cells = [c.data.copy() for c in mesh.cells]
    mesh.points[5] += [0.001, 0.0, 0.0]
    meshio.write(vtu, mesh)
    assert all(np.array_equal(a, c.data) for a, c in zip(cells, meshio.read(vtu).cells))   # same connectivity
    after = robot_fingerprint(toml)
    assert after["toml_sha256"] == before["toml_sha256"]
    assert after["mesh_sha256"] != before["mesh_sha256"] and after["sha256"] != before["sha256"]
    code, _, err = run(["evaluate", path], capsys)
    assert code == 2 and f"{path} was made for robot 'tripod'" in err and "the mesh changed" in err, err
    from trajopt.hardware import EXAMPLE_TRIPOD
    code, _, err = run(["play", path, "--dry-run", "--hardware", EXAMPLE_TRIPOD], capsys)
    assert code == 2 and "the mesh changed" in err, err


def test_a_result_from_before_the_coulomb_default_is_still_the_same_robot(tmp_path, capsys):
    """The shipped robot files changed `[contact] model` from "paper" to "coulomb" (issue #31);
    a result records its own law and replays with it, so a result made for the file that said
    "paper" is a result of the same robot. Any other change is still refused."""
    from trajopt.results.robot_match import describe_difference
    toml = copy_robot("tripod", tmp_path / "a")
    now = robot_fingerprint(toml)
    text = toml.read_text()
    assert 'model = "coulomb"' in text
    toml.write_text(text.replace('model = "coulomb"', 'model = "paper"', 1))
    before = robot_fingerprint(toml)
    assert before["sha256"] != now["sha256"]
    assert describe_difference(before, now) is None
    toml.write_text(text.replace('model = "coulomb"', 'model = "paper"', 1).replace("u_max = 0.02", "u_max = 0.015", 1))
    edited = robot_fingerprint(toml)
    assert "motors[0].u_max: 0.015 -> 0.02" in describe_difference(edited, now)
    assert "[contact].model" not in describe_difference(edited, now)
    toml.write_text(text)
    res = gait_for(toml)
    res.robot_fingerprint = before
    res.settings["contact"] = "paper"
    res.save(tmp_path / "old.npz")
    code, out, err = run(["evaluate", tmp_path / "old.npz", "--cycles", "1"], capsys)
    assert code == 0 and "was made for" not in err, err


def test_a_hardware_file_naming_a_shipped_robot_refuses_another_robot_of_that_name(tmp_path, capsys):
    """Issue #40: the hardware file compared robots by name, so the shipped Tripod's accepted a
    gait of a co-designed Tripod (its robot.toml keeps the name). The shipped robot's fingerprint
    is compared; the robot files of the result itself are as they were made."""
    toml = copy_robot("tripod", tmp_path / "designed")
    toml.write_text(toml.read_text().replace("u_max = 0.02", "u_max = 0.015"))      # another Tripod
    path = gait_for(toml).save(tmp_path / "gait")
    from trajopt.hardware import EXAMPLE_TRIPOD
    code, _, err = run(["play", path, "--dry-run", "--hardware", EXAMPLE_TRIPOD], capsys)
    assert code == 2 and "example_tripod.toml describes robot 'tripod'" in err, err
    assert "motors[0].u_max: 0.015 -> 0.02" in err and "--ignore-robot-mismatch" in err
    code, _, err = run(["play", path, "--dry-run", "--hardware", EXAMPLE_TRIPOD, "--ignore-robot-mismatch"], capsys)
    assert code == 0 and "played anyway" in err
