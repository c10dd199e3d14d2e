"""The ``trajopt`` command's paths end to end through ``trajopt.cli.main``, on tiny settings,
with exit codes asserted exactly: optimize (fresh, a non-zero heading, the turn task, a warm
start, an interruption and --resume), evaluate, and play on the RoboClaw emulator."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from trajopt import Result
from trajopt.cli import main

TINY = ["--prep-steps", "4", "--cycle-steps", "12", "--keyframes", "4", "--seeds", "1", "--cycles", "1", "--quiet"]
K = 4 + 2 * 12
DT = 0.033
TRIPOD_BL = 0.14


def optimize(tmp, *args: str) -> int:
    return main(["optimize", "tripod", *TINY, "--out", str(tmp), *args])


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """A fresh ``trajopt optimize tripod`` run (one iteration)."""
    out = tmp_path_factory.mktemp("walk")
    assert optimize(out, "--iterations", "1") == 0
    return out / "tripod_walk.npz"


def test_fresh_optimize_writes_a_complete_result(walk, capsys):
    assert walk.is_file() and walk.with_suffix(".json").is_file()
    res = Result.load(walk)
    assert res.robot == "tripod" and res.task == "walk" and res.status in ("max_iter", "ftol", "xtol", "gtol",
                                                                             "stalled")
    assert res.u.shape == (K, 2) and res.u_post.shape == (K, 2) and res.com.shape == (K + 1, 3)
    assert [h["iteration"] for h in res.history] == [1]
    assert res.settings["symmetry"] is True and res.settings["n_cycle"] == 12 and res.settings["n_prep"] == 4
    # the default target: 8 BL/min along +x from the rest COM, i.e. 8 * 0.14 / 60 m/s for K steps
    d = res.target[-1] - res.target[0]
    np.testing.assert_allclose(d, [8.0 * TRIPOD_BL / 60.0 * K * DT, 0.0], rtol=1e-12, atol=1e-15)
    assert res.evaluation["cycles"] == 1 and np.isfinite(res.evaluation["speed_bl_per_min"])


def test_heading_rotates_the_target_and_the_metric(tmp_path):
    """--heading 90: the target runs along +z (the robot's right) at the requested speed, and
    the result is evaluated along that heading."""
    assert optimize(tmp_path, "--iterations", "1", "--heading", "90", "--speed", "6", "--name", "h90") == 0
    res = Result.load(tmp_path / "h90.npz")
    assert res.settings["heading_deg"] == 90.0
    d = res.target[-1] - res.target[0]
    np.testing.assert_allclose(d, [0.0, 6.0 * TRIPOD_BL / 60.0 * K * DT], rtol=1e-12, atol=1e-15)
    com = np.asarray(res.evaluation["com"])
    n0, n1 = 4, 4 + 12                                             # one evaluation cycle after the prep
    along_z = (com[n1, 2] - com[n0, 2]) / (12 * DT) * 60.0 / TRIPOD_BL
    assert res.evaluation["speed_bl_per_min"] == pytest.approx(along_z, rel=1e-9, abs=1e-12)


def test_turn_task_targets_a_quarter_circle(tmp_path):
    """--task turn: symmetry off by default (paper IV-B), the target is a quarter circle to the
    right of radius 2 v T / pi ending at start + (R, R)."""
    assert optimize(tmp_path, "--task", "turn", "--iterations", "1") == 0
    res = Result.load(tmp_path / "tripod_turn.npz")
    assert res.task == "turn" and res.settings["symmetry"] is False and res.settings["turn"] == "right"
    assert res.settings["interpolation"] == "linear"                 # the turn's default
    v, T = 8.0 * TRIPOD_BL / 60.0, K * DT
    R = 2.0 * v * T / math.pi
    np.testing.assert_allclose(res.target[-1] - res.target[0], [R, R], rtol=1e-12)
    assert np.asarray(res.settings["keyframes"]).shape == (2, 4)


def test_warm_start_starts_from_the_given_keyframes(walk, tmp_path):
    """--warm-start with no seeds and no iterations: the turn starts (and so ends) exactly at the
    walk's keyframes, converted from the symmetric to the asymmetric parameterisation (joined as
    the walk joins them, by the spline: the turn's default lines play other controls)."""
    assert optimize(tmp_path, "--task", "turn", "--warm-start", str(walk), "--iterations", "0", "--seeds", "0",
                    "--name", "warm", "--interpolation", "hermite") == 0
    res, src = Result.load(tmp_path / "warm.npz"), Result.load(walk)
    assert res.settings["warm_start"] == str(walk) and res.history == []
    np.testing.assert_allclose(res.settings["keyframes"], src.settings["keyframes"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(res.u, src.u, rtol=0, atol=1e-15)     # same controls, other task


def test_interrupt_then_resume_ends_where_an_uninterrupted_run_ends(tmp_path, monkeypatch, capsys):
    """Ctrl-C after the first iteration: exit 130 and the iterate saved as "interrupted";
    --resume runs the remaining iteration and ends with the same parameters as a run that was
    never interrupted. --resume of a finished run does nothing (exit 0); with other settings it
    is refused (exit 2)."""
    import trajopt.optimize_run as commands
    assert optimize(tmp_path, "--iterations", "2", "--name", "straight") == 0
    straight = Result.load(tmp_path / "straight.npz")
    real = commands.optimize_gait

    def interrupted_after_one(*args, callback, **kw):
        def cb(entry, partial):
            callback(entry, partial)
            raise KeyboardInterrupt
        return real(*args, callback=cb, **kw)
    monkeypatch.setattr(commands, "optimize_gait", interrupted_after_one)
    assert optimize(tmp_path, "--iterations", "2") == 130
    monkeypatch.setattr(commands, "optimize_gait", real)
    assert not (tmp_path / "tripod_walk.npz").exists()              # only finished runs get that name
    part = Result.load(tmp_path / "tripod_walk.partial.npz")
    assert part.status == "interrupted" and [h["iteration"] for h in part.history] == [1]
    assert "--resume" in capsys.readouterr().err
    assert optimize(tmp_path, "--iterations", "2", "--resume") == 0
    assert "resuming" in capsys.readouterr().out
    done = Result.load(tmp_path / "tripod_walk.npz")
    assert not (tmp_path / "tripod_walk.partial.npz").exists()       # the checkpoint is removed
    assert [h["iteration"] for h in done.history] == [h["iteration"] for h in straight.history] == [1, 2]
    np.testing.assert_allclose(done.z, straight.z, rtol=0, atol=1e-10)
    assert optimize(tmp_path, "--iterations", "2", "--resume") == 0
    assert "nothing to resume" in capsys.readouterr().out
    part.status = "interrupted"
    part.save(tmp_path / "again.partial.npz")
    assert optimize(tmp_path, "--iterations", "2", "--resume", "--name", "again", "--heading", "45") == 2
    err = capsys.readouterr().err
    assert "cannot resume: the settings differ" in err and "'heading_deg': (0.0, 45.0)" in err, err


def test_evaluate_exit_codes(walk, tmp_path, monkeypatch, capsys):
    """0: upright (this gait is); 1: the robot fell (the metric says so); 2: bad input."""
    assert main(["evaluate", str(walk), "--cycles", "1"]) == 0
    out = capsys.readouterr().out
    assert "upright" in out and "yes" in out and "BL/min over 1 cycles" in out
    import trajopt.cli.commands as commands
    real = commands.evaluate_result
    monkeypatch.setattr(commands, "evaluate_result",
                        lambda res, n=None, **kw: {**real(res, n, **kw), "upright": False})
    assert main(["evaluate", str(walk), "--cycles", "1"]) == 1
    monkeypatch.undo()
    assert main(["evaluate", str(tmp_path / "missing.npz")]) == 2
    assert "not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:                       # argparse refuses it: exit code 2
        main(["evaluate", str(walk), "--cycles", "0"])
    assert exit_.value.code == 2


def test_play_a_real_result_on_the_emulator(tmp_path, capsys):
    """``trajopt play`` of a real Tripod gait from ``trajopt optimize`` on an emulated RoboClaw:
    exit 0, every step sent, and the commanded encoder counts are
    ``direction * round(u_post / r / 2 pi * counts_per_rev)`` with the TOML's numbers
    (r = 5 mm, 3575.04 counts per output revolution, direction +1). Keyframes 18 steps apart
    and a 24-step prep keep any gait within the example's 5960 counts/s and its acceleration
    setting (optimised gaits obey the robot's 100 rpm, 5958 counts/s, whatever the phases)."""
    pytest.importorskip("serial")
    from trajopt.hardware import EXAMPLE_TRIPOD, RoboClawEmulator
    assert main(["optimize", "tripod", "--prep-steps", "24", "--cycle-steps", "36", "--keyframes", "2",
                 "--seeds", "1", "--cycles", "1", "--iterations", "0", "--quiet", "--out", str(tmp_path),
                 "--name", "play"]) == 0
    res = Result.load(tmp_path / "play.npz")
    n = len(res.u_post)
    assert n == 24 + 2 * 36 and np.ptp(res.u_post) > 1e-3
    log = tmp_path / "play.csv"
    with RoboClawEmulator(addresses=(0x80,)) as emu:
        code = main(["play", str(tmp_path / "play.npz"), "--hardware", str(EXAMPLE_TRIPOD),
                     "--port-override", emu.port, "--log", str(log)])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert f"{n}/{n} steps sent" in out.out
    rows = list(csv.reader(log.open()))
    assert rows[0] == ["time", "step", "front_commanded", "front_measured", "back_commanded", "back_measured"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (n, 6)
    expected = np.rint(res.u_post / 0.005 / (2.0 * math.pi) * 3575.04)
    np.testing.assert_array_equal(data[:, [2, 4]], expected)
    assert np.abs(data[:, [3, 5]]).max() > 0.5 * np.abs(expected).max()      # the motors moved


def test_play_loops_an_optimised_gaits_cycles_not_its_prep(walk, capsys):
    """Issue #40: ``play --loops N`` replayed the prep phase, so every optimised gait was refused
    (the jump from the last cycle back to rest); the prep is played once, the cycles N times."""
    from trajopt.hardware.config import EXAMPLE_TRIPOD
    capsys.readouterr()
    assert main(["play", str(walk), "--hardware", str(EXAMPLE_TRIPOD), "--dry-run", "--loops", "3"]) == 0, \
        capsys.readouterr().err
    text = capsys.readouterr()
    assert f"{4 + 3 * 2 * 12} steps (4 prep samples once, then 24 samples of cycles x 3 loops)" in text.out + text.err


def test_a_result_of_a_relative_robot_path_is_found_from_anywhere(robot_dir, tmp_path, monkeypatch, capsys):
    """Issue #40: a result recorded its robot path as typed (relative): evaluated from another
    folder, "robot file not found". It records the absolute path, and a robot.toml beside the
    result is found when the recorded one is gone (a folder moved with its robot)."""
    import shutil
    folder = tmp_path / "robots"
    folder.mkdir()
    for name in ("robot.toml", "tripod.vtu"):
        shutil.copy(robot_dir / name, folder / name)
    monkeypatch.chdir(tmp_path)
    assert main(["optimize", "robots/robot.toml", *TINY, "--iterations", "0", "--out", "robots", "--name", "r"]) == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["evaluate", str(folder / "r.npz"), "--cycles", "1"]) in (0, 1)
    moved = tmp_path / "moved"
    folder.rename(moved)
    assert main(["evaluate", str(moved / "r.npz"), "--cycles", "1"]) in (0, 1), capsys.readouterr().err
    assert "not found" not in capsys.readouterr().err


def test_evaluate_says_a_gait_was_made_without_the_motor_limit(tmp_path, capsys):
    """Issue #40: evaluate of a --no-motor-limit gait said nothing about the limit it breaks."""
    assert optimize(tmp_path, "--iterations", "0", "--no-motor-limit", "--name", "free") == 0
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "free.npz"), "--cycles", "1"]) in (0, 1)
    out = capsys.readouterr().out
    assert "motor limit" in out and "made without it (--no-motor-limit)" in out and "largest step" in out, out
    assert main(["evaluate", str(tmp_path / "free.npz"), "--cycles", "1", "--json"]) in (0, 1)
    import json
    assert json.loads(capsys.readouterr().out)["within_motor_limit"] is False
    assert optimize(tmp_path, "--iterations", "0", "--name", "limited") == 0
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "limited.npz"), "--cycles", "1"]) in (0, 1)
    assert "made without it" not in capsys.readouterr().out


def test_an_own_robots_result_is_named_after_the_robot(robot_dir, tmp_path):
    """``trajopt optimize results/my_robot/robot.toml --task walk`` writes ``quadruped_walk.npz``
    (the file's ``[robot] name``, as the docs and examples/robot_from_surface.py say), not
    ``robot_walk.npz`` (#41); a file without a usable name falls back to its stem, and shipped
    robots keep theirs."""
    import shutil

    from trajopt.optimize_run import OptimizeRun
    folder = tmp_path / "my_robot"
    folder.mkdir()
    shutil.copy(robot_dir / "tripod.vtu", folder / "tripod.vtu")
    text = (robot_dir / "robot.toml").read_text()
    (folder / "robot.toml").write_text(text.replace('name = "tripod"', 'name = "quadruped"', 1))
    assert OptimizeRun(robot=str(folder / "robot.toml"), task="walk", out=tmp_path).result_file() == \
        tmp_path / "quadruped_walk.npz"
    (folder / "robot.toml").write_text(text.replace('name = "tripod"', 'name = "a/b"', 1))
    assert OptimizeRun(robot=str(folder / "robot.toml"), task="walk", out=tmp_path).result_file().name == \
        "robot_walk.npz"
    assert OptimizeRun(robot="tripod", task="walk", out=tmp_path).result_file() == tmp_path / "tripod_walk.npz"
