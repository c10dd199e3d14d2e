"""`trajopt check` and `trajopt mesh`: summaries, exit codes, messages naming the field, and a
picture whose pixels show the robot where its nodes project."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from soft_envs.robot_check import MOTOR_COLOURS, PAYLOAD_COLOUR, check_robot, draw_robot
from soft_envs.sim import load_robot
from soft_envs.sim.robot_file import asset_path
from trajopt.cli import main

QUADRUPED = Path(__file__).resolve().parents[1] / "examples" / "data" / "quadruped.obj"


def _robot_pixel(rgb: np.ndarray) -> np.ndarray:
    """Not background: the sky, the ground tiles and the shadow are light or mid greys."""
    rgb = rgb.astype(int)
    return (rgb.max(axis=-1) - rgb.min(axis=-1) > 20) | (rgb.max(axis=-1) < 60)


def test_check_shipped_robot_prints_summary_and_draws(tmp_path, capsys):
    png = tmp_path / "tripod.png"
    assert main(["check", "tripod", "--picture", str(png)]) == 0
    out = capsys.readouterr().out
    assert "tripod: valid" in out and "153 nodes, 360 tets" in out and "payload 44.0 g" in out
    assert "motor front" in out and "u 0.0 mm .. 20.0 mm" in out and "radius ratio" in out
    from PIL import Image
    assert Image.open(png).size == (1200, 300 + 30 + 16)


def test_check_prints_the_contact_law_in_use_and_its_parameters(tmp_path, capsys):
    """The contact row names the law the robot is simulated with (the file's ``[contact] model``,
    the default when it names none) and that law's parameters, not the paper law's friction
    weight under a Coulomb robot (#41)."""
    assert main(["check", "tripod", "--no-picture"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.lstrip().startswith("contact"))
    assert "coulomb law (the robot file's [contact] model" in row
    assert "friction_coefficient 0.8" in row and "slip_distance 0.0003 m" in row and "1/m" not in row
    folder = tmp_path / "paper"
    shutil.copytree(Path(asset_path("tripod")).parent, folder)
    text = (folder / "robot.toml").read_text()
    (folder / "robot.toml").write_text(text.replace('model = "coulomb"\n', "", 1))
    assert main(["check", str(folder / "robot.toml"), "--no-picture"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.lstrip().startswith("contact"))
    assert "paper law (the default: the robot file names none" in row and "friction 1000 1/m" in row
    assert "friction_coefficient" not in row


@pytest.mark.parametrize("edit, field", [
    (lambda s: s.replace("youngs_modulus = 1e+05", "youngs_modulus = \"soft\""), r"\[material\].youngs_modulus"),
    (lambda s: s.replace("[payload]", "[payload]\ncolour = 1"), r"\[payload\].colour"),
    (lambda s: s.replace("points = [[0.0780", "points = [[0.5", 1), r"tendons\[0\] \('front_a'\).points\[0\]"),
    (lambda s: s.replace('mirror = "', 'mirror = "x'), r"mirror names unknown motor"),
])
def test_check_broken_toml_exits_2_naming_file_and_field(tmp_path, capsys, edit, field):
    src = asset_path("tripod")
    text = src.read_text()
    if "mirror" in field:           # the Puppy has mirrored motors
        src = asset_path("puppy")
        text = src.read_text()
    shutil.copy(src.parent / f"{src.parent.name}.vtu", tmp_path)
    broken = tmp_path / "robot.toml"
    new = edit(text)
    assert new != text
    broken.write_text(new)
    assert main(["check", str(broken), "--no-picture"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"trajopt: error: {broken}") and len(err.splitlines()) == 1
    assert pytest.importorskip("re").search(field, err), err


def test_picture_shows_the_robot_where_its_nodes_project():
    robot = load_robot("puppy")
    pic = draw_robot(robot, size=(320, 240))
    img = pic.image
    assert img.shape == (240 + 30 + 16 * 3, 960, 3)
    robot_px = _robot_pixel(img)
    for v, pix in enumerate(pic.node_pixels):
        c, r = np.round(pix).astype(int).T
        assert (c >= v * 320 + 1).all() and (c < (v + 1) * 320 - 1).all() and (r >= 1).all() and (r < 239).all()
        near = np.zeros(len(c), bool)             # silhouette nodes sit on antialiased edges: 3x3
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                near |= robot_px[r + dr, c + dc]
        assert near.all(), v
        # and nothing drawn away from the robot (view title in the top-left corner excepted)
        panel = robot_px[:240, v * 320:(v + 1) * 320].copy()
        panel[:24, :200] = False
        c0, c1, r0, r1 = c.min() - v * 320 - 3, c.max() - v * 320 + 4, r.min() - 3, r.max() + 4
        panel[max(r0, 0):r1, max(c0, 0):c1] = False
        assert not panel.any(), (v, np.argwhere(panel)[:5])
        assert robot_px[r0 + 3:r1 - 3, v * 320 + c0 + 3:v * 320 + c1 - 3].mean() > 0.5   # the body fills it
    # payload dots (black) at the payload nodes seen from above
    c, r = np.round(pic.node_pixels[2][robot.payload_nodes]).astype(int).T
    assert (np.abs(img[r, c].astype(int) - 255 * np.array(PAYLOAD_COLOUR)).max(axis=1) < 40).mean() > 0.9
    # each tendon in its motor's colour at its segments' midpoints (drawn on top of the body; other
    # tendons may cross it in one view, not in all)
    for ti, mi in enumerate(robot.tendon_motor):
        want = np.array([int(MOTOR_COLOURS[mi][k:k + 2], 16) for k in (1, 3, 5)])
        hits = []
        for views in pic.tendon_pixels:
            c, r = np.round(0.5 * (views[ti][1:] + views[ti][:-1])).astype(int).T
            hits.append((np.abs(img[r, c].astype(int) - want).max(axis=1) < 40).mean())
        assert max(hits) == 1.0 and np.mean(hits) > 0.5, (robot.tendons[ti].name, hits)


def test_check_warns_about_a_robot_without_motors(tmp_path):
    src = asset_path("tripod")
    shutil.copy(src.parent / "tripod.vtu", tmp_path)
    text = src.read_text()
    (tmp_path / "robot.toml").write_text(text[:text.index("[[tendons]]")])
    c = check_robot(tmp_path / "robot.toml")
    assert any("no motors" in w for w in c.warnings)


def test_mesh_command_writes_a_robot_that_checks(tmp_path, capsys):
    pytest.importorskip("gmsh")
    out = tmp_path / "quad"
    assert main(["mesh", str(QUADRUPED), "--scale", "0.001", "--up", "+z", "--out", str(out),
                 "--edge-length", "0.03"]) == 0
    text = capsys.readouterr().out
    assert "dihedral angles" in text and "radius ratio" in text and f"trajopt check {out / 'robot.toml'}" in text
    assert (out / "quadruped.vtu").is_file()
    toml = (out / "robot.toml").read_text()
    assert "numerical" in toml and "# [[tendons]]" in toml and "paper II-A" in toml
    assert main(["check", str(out / "robot.toml")]) == 0
    assert (out / "quadruped.png").is_file()
    before = toml
    assert main(["mesh", str(QUADRUPED), "--scale", "0.001", "--up", "+z", "--out", str(out)]) == 2
    assert "exists already" in capsys.readouterr().err and (out / "robot.toml").read_text() == before


def test_mesh_command_refuses_an_open_surface(tmp_path, capsys):
    bad = tmp_path / "open.obj"
    lines = QUADRUPED.read_text().splitlines()
    bad.write_text("\n".join(line for i, line in enumerate(lines) if i != len(lines) - 1) + "\n")
    assert main(["mesh", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: the surface is not closed" in err and not (tmp_path / "o").exists()
