"""``trajopt calibrate`` checks its data and its fit before it writes a robot.toml (issue #26
items 3 and 6): tracks in millimetres, times 10x too large or in milliseconds, a constant offset,
a fit stopped at its evaluation limit, standard errors larger than the values, parameters at
their bounds; refused (exit 2, nothing written) unless ``--force``. The tracks file: rows in any
order, ``inf`` refused, a non-UTF-8 file named with the byte offset.

The bad tracks are the good synthetic ones (Tripod, E hidden 25 % off, 8 markers, 40 steps,
0.5 mm noise, 30 Hz) made wrong the way users make them wrong."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from soft_envs.envs import load_robot, with_parameters
from trajopt.calibration.calibrate import CalibrationFit, synthetic_tracks
from trajopt.calibration.checks import check_fit
from trajopt.cli import main
from trajopt.calibration.tracks import read_tracks, write_tracks

from .test_calibrate import DT, make_result, spread_markers, wave


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """The robot, its markers, the gait file and the good tracks ``(times, positions)``."""
    root = tmp_path_factory.mktemp("checks")
    robot = load_robot("tripod")
    markers = spread_markers(robot)
    u = wave(robot, 40)
    times, pos, _ = synthetic_tracks(with_parameters(robot, {"youngs_modulus": 1.25e5}), markers, u, DT,
                                     rate_hz=30.0, noise_m=5e-4, rng=np.random.default_rng(0))
    points = root / "markers.csv"
    points.write_text("marker,x,y,z\n" + "".join(f"{n},{p[0]:.17g},{p[1]:.17g},{p[2]:.17g}\n"
                                                  for n, p in zip(markers.names, markers.points)))
    return {"markers": markers, "times": times, "pos": pos, "points": points, "gait": make_result(root, robot, u)}


def calibrate(setup, tmp_path, times, pos, *extra):
    """Run ``trajopt calibrate`` on tracks ``(times, pos)``; ``(exit code, out folder)``."""
    tracks = write_tracks(tmp_path / "tracks.csv", times, setup["markers"].names, pos)
    out = tmp_path / "calib"
    code = main(["calibrate", "tripod", "--markers", str(tracks), "--controls", str(setup["gait"]),
                 "--fit", "youngs_modulus", "--marker-points", str(setup["points"]), "--out", str(out), *extra])
    return code, out


def refused(out: Path) -> bool:
    return not (out / "robot.toml").exists() and not (out / "calibration.json").exists()


def test_tracks_in_millimetres_refused_with_a_unit_hint_and_forced(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, setup["times"], 1000.0 * setup["pos"])
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "tracks look like millimetres" in err and "divide x, y, z by 1000" in err and "--force" in err
    # --force: written, with every failed check as a warning (the fit of mm tracks: E +- far more than E)
    code, out = calibrate(setup, tmp_path, setup["times"], 1000.0 * setup["pos"], "--force")
    text = capsys.readouterr().out
    assert code == 0 and (out / "robot.toml").exists() and (out / "calibration.json").exists()
    assert "warning: check failed (written anyway, --force): plausible-tracks" in text
    assert "standard-errors" in text and "youngs_modulus" in text and "rms-vs-noise" in text


def test_tracks_far_from_the_robot_refused_with_a_frame_hint(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, setup["times"], setup["pos"] + [10.0, 0.0, 0.0])
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "plausible-tracks: a marker stays" in err and "need --frame camera" in err and "millimetres" not in err


def test_times_ten_times_too_large_refused(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, 10.0 * setup["times"], setup["pos"])
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    n_all = setup["pos"].shape[0] * setup["pos"].shape[1]
    assert f"of {n_all} samples fall within the controls' 1.32 s" in err and "time-span" in err
    assert "10x longer than the controls" in err


def test_times_in_milliseconds_refused_naming_the_samples_used(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, 1000.0 * setup["times"], setup["pos"])
    err = capsys.readouterr().err
    n_all = setup["pos"].shape[0] * setup["pos"].shape[1]
    assert code == 2 and refused(out), err
    assert f"only 8 of {n_all} samples" in err and "times look like milliseconds: divide t by 1000" in err


def test_constant_offset_refused_by_the_rms_against_the_noise(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, setup["times"], setup["pos"] + 0.05)
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "rms-vs-noise" in err and "--noise 0.001 m" in err and "--frame camera" in err


def test_fit_stopped_at_its_evaluation_limit_refused(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, setup["times"], setup["pos"], "--max-evaluations", "2")
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "evaluation-limit" in err and "--max-evaluations" in err


def test_good_tracks_pass_every_check(setup, tmp_path, capsys):
    code, out = calibrate(setup, tmp_path, setup["times"], setup["pos"])
    text = capsys.readouterr()
    assert code == 0 and (out / "robot.toml").exists(), text.err
    assert "check failed" not in text.out + text.err


def _fit(values, std, rms=0.8, names=("youngs_modulus", "poisson_ratio"), stopped=False):
    n = len(names)
    return CalibrationFit(tuple(names), np.ones(n), np.asarray(values, float), np.asarray(std, float), np.eye(n),
                          10.0, rms, {}, 100, 5, "ok", stopped_at_limit=stopped)


def test_fit_checks_each_name_what_failed():
    assert check_fit(_fit([1e5, 0.3], [1e3, 0.01]), noise_m=1e-3) == []
    at_bound = check_fit(_fit([1e5, 0.49], [1e3, 0.01]), noise_m=1e-3)
    assert len(at_bound) == 1 and at_bound[0].startswith("at-bounds: poisson_ratio = 0.49")
    assert check_fit(_fit([1e5, -0.99], [1e3, 0.01]), noise_m=1e-3)[0].startswith("at-bounds")
    big = check_fit(_fit([1e5, 0.3], [2e5, 0.01]), noise_m=1e-3)
    assert len(big) == 1 and big[0].startswith("standard-errors: youngs_modulus = 100000 +- 2e+05")
    assert check_fit(_fit([1e5, 0.3], [1e3, 0.01], rms=6.0), noise_m=1e-3)[0].startswith("rms-vs-noise")
    assert check_fit(_fit([1e5, 0.3], [1e3, 0.01], rms=6.0), noise_m=2e-3) == []
    assert check_fit(_fit([1e5, 0.3], [1e3, 0.01], stopped=True), noise_m=1e-3)[0].startswith("evaluation-limit")


# ---------------------------------------------------------------------- the tracks file
def test_rows_in_any_order_read_as_sorted(setup, tmp_path):
    names = setup["markers"].names
    good = read_tracks(write_tracks(tmp_path / "sorted.csv", setup["times"], names, setup["pos"]), names)
    lines = (tmp_path / "sorted.csv").read_text().splitlines()
    body = lines[1:]
    np.random.default_rng(3).shuffle(body)
    shuffled = tmp_path / "shuffled.csv"
    shuffled.write_text("\n".join([lines[0], *body]) + "\n")
    tr = read_tracks(shuffled, names)
    assert tr.markers == good.markers and tr.n_samples == good.n_samples
    for n in names:
        assert np.array_equal(tr.samples[n][0], good.samples[n][0])
        assert np.array_equal(tr.samples[n][1], good.samples[n][1])


@pytest.mark.parametrize("text,match", [
    ("t,marker,x,y,z\n0,a,1,2,3\n0.1,a,inf,2,3\n", r"t\.csv:3: x is inf: positions must be finite"),
    ("t,marker,x,y,z\n0,a,1,2,3\n0.1,a,1,2,-Infinity\n", r"t\.csv:3: z is -inf"),
    ("t,marker,x,y,z\ninf,a,1,2,3\n", r"t\.csv:2: t is inf"),
    ("t,marker,x,y,z\n0.2,a,1,2,3\n0.1,a,1,2,3\n0.2,a,1,2,3\n",
     r"t\.csv:4: marker 'a' has a second sample at t = 0.2 s \(the first on line 2\)"),
])
def test_inf_and_duplicate_times_refused_naming_the_line(tmp_path, text, match):
    f = tmp_path / "t.csv"
    f.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_tracks(f, ["a"])


def test_non_utf8_tracks_name_the_file_and_byte_offset(setup, tmp_path, capsys):
    f = tmp_path / "t.csv"
    f.write_bytes(b"t,marker,x,y,z\n0,a,1,2,3\n0.1,a,1,\xe92,3\n")
    with pytest.raises(ValueError, match=r"t\.csv: not UTF-8 text: byte 0xe9 at offset 33 \(line 3\)"):
        read_tracks(f, ["a"])
    code = main(["calibrate", "tripod", "--markers", str(f), "--controls", str(setup["gait"]),
                 "--fit", "youngs_modulus", "--marker-points", str(setup["points"]), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "t.csv: not UTF-8 text: byte 0xe9 at offset 33" in err
    bad_points = tmp_path / "points.csv"
    bad_points.write_bytes(setup["points"].read_bytes().replace(b"m1,", b"m\xff1,"))
    code = main(["calibrate", "tripod", "--markers", str(f), "--controls", str(setup["gait"]),
                 "--fit", "youngs_modulus", "--marker-points", str(bad_points), "--out", str(tmp_path / "o")])
    assert code == 2 and "points.csv: not UTF-8 text: byte 0xff at offset" in capsys.readouterr().err


# ---------------------------------------------------------------------- issue #40
def test_tracks_in_centimetres_get_a_centimetre_hint(setup, tmp_path, capsys):
    """Tracks in centimetres were told "millimetres: divide by 1000"."""
    code, out = calibrate(setup, tmp_path, setup["times"], 100.0 * setup["pos"])
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "tracks look like centimetres: divide x, y, z by 100" in err and "1000" not in err, err


def test_an_offset_hidden_by_a_large_noise_is_caught_as_a_model_misfit(setup, tmp_path, capsys):
    """``--noise 0.05`` with a 5 cm offset passed every check and wrote a far wrong E: the
    residual is mostly a constant offset per marker, which no physical parameter explains."""
    code, out = calibrate(setup, tmp_path, setup["times"], setup["pos"] + 0.05, "--noise", "0.05")
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "model-misfit" in err and "constant offset" in err and "--noise 0.05" in err, err


def test_a_second_calibration_into_the_same_folder_needs_overwrite(setup, tmp_path, capsys):
    """Defect 5: a second calibrate into the same --out replaced the first's files."""
    code, out = calibrate(setup, tmp_path, setup["times"], setup["pos"])
    assert code == 0
    first = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"robot.toml", "calibration.json", "tracks.png"} <= set(first)
    code, _ = calibrate(setup, tmp_path, setup["times"], setup["pos"])
    err = capsys.readouterr().err
    assert code == 2 and "--overwrite" in err and "holds a calibration" in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == first
    code, _ = calibrate(setup, tmp_path, setup["times"], setup["pos"], "--overwrite")
    assert code == 0 and (out / "calibration.json").read_bytes() != first["calibration.json"]


def test_a_calibration_folder_is_reserved_while_a_run_lives(setup, tmp_path, capsys):
    import json
    import os
    import platform
    import time
    out = tmp_path / "calib"
    out.mkdir()
    (out / "calibrate.lock").write_text(json.dumps({"pid": os.getppid(), "host": platform.node(),
                                                    "started": time.time(), "command": "trajopt calibrate"}))
    code, _ = calibrate(setup, tmp_path, setup["times"], setup["pos"])
    err = capsys.readouterr().err
    assert code == 2 and "calibrate.lock" in err and f"pid {os.getppid()} " in err, err
    assert sorted(p.name for p in out.iterdir()) == ["calibrate.lock"]


def test_the_shipped_tracks_with_an_offset_and_a_large_noise_are_refused(tmp_path, capsys):
    """The red team's case: the shipped example tracks 5 cm off, --noise 0.05: every check
    passed and a wrong E was written. The model-misfit check refuses it."""
    root = Path(__file__).resolve().parents[1] / "examples" / "data"
    lines = (root / "tripod_tracks.csv").read_text().splitlines()
    moved = [lines[0]] + [",".join(r.split(",")[:2] + [f"{float(v) + 0.05!r}" for v in r.split(",")[2:5]])
                          for r in lines[1:] if r.strip()]
    tracks = tmp_path / "offset.csv"
    tracks.write_text("\n".join(moved) + "\n")
    out = tmp_path / "calib"
    code = main(["calibrate", "tripod", "--markers", str(tracks), "--controls", str(root / "tripod_gait.npz"),
                 "--marker-points", str(root / "tripod_markers.csv"), "--fit", "youngs_modulus", "--contact", "paper",
                 "--noise", "0.05", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and refused(out), err
    assert "model-misfit" in err and "constant offset" in err, err
