"""``trajopt robustness`` (issue #19) on a tiny gait: seeded perturbations, the actuation model,
slopes in any direction, the report and its files, resuming, the in-process fallback of
``--workers`` and picklable samples; damaged run files give one line naming the file and line,
and a line cut by a crash is repaired (issue #26 item 4)."""
from __future__ import annotations

import importlib.util
import json
import math
import pickle

import numpy as np
import pytest

from soft_envs.envs import load_robot, make_gradient_env
from trajopt import GaitParameterization, GaitSpec
from trajopt.cli import main
from trajopt.evaluation import zero_slack_controls
from trajopt.results.result import Result
from trajopt.robustness.study import (PERTURBATIONS, applied_controls, draw_perturbation, map_samples, perturbed_slope,
                                run_sample)
from trajopt.robustness.report import robustness_jobs

GAIT = GaitSpec(n_prep=4, n_cycle=12, n_cycles=1, n_keyframes=2, symmetry=False)


def tiny_result(tmp_path, contact: str | None = None):
    robot = load_robot("tripod")
    param = GaitParameterization.for_robot(robot, GAIT)
    z = param.initial_z(0.5, np.random.default_rng(0), noise=0.4)
    u = param.controls(z)
    K = len(u)
    env = make_gradient_env("tripod", contact=contact or "paper")
    settings = {**GAIT.to_settings(), "keyframes": param.keyframes(z).tolist(), "heading_deg": 0.0,
                "incline_deg": 0.0, **({"contact": contact, "substeps": env.substeps} if contact else {})}
    u_post = zero_slack_controls(u, env.rollout(u).cable_deformation, robot.tendon_motor, robot.u_bounds)
    res = Result(robot="tripod", task="walk", motor_names=robot.motor_names, dt=0.033, z=z, u=u, u_post=u_post,
                 target=np.zeros((K + 1, 2)), com=np.zeros((K + 1, 3)), settings=settings)
    return res.save(tmp_path / f"tiny{'_' + contact if contact else ''}.npz")


def test_perturbations_are_seeded_per_sample_and_within_their_ranges():
    a = [draw_perturbation(7, i) for i in range(50)]
    assert draw_perturbation(7, 3) == a[3] and draw_perturbation(8, 3) != a[3]
    for name, (kind, lo, hi) in PERTURBATIONS.items():
        x = np.array([p[name] for p in a])
        assert lo <= x.min() and x.max() <= hi and np.ptp(x) > 0.3 * (hi - lo) * (0.5 if kind == "log" else 1)


V_100RPM = 100 * 2 * math.pi / 60 * 0.005       # [m/s] a 100 rpm motor on a 5 mm spool


def test_applied_controls_model_lag_speed_limit_and_jitter():
    u = np.zeros((20, 2))
    u[5:] = [0.01, 0.0]                         # a step of 10 mm
    bounds = np.array([[0.0, 0.02], [0.0, 0.02]])
    none = {"timing_jitter_s": 0.0, "motor_lag_s": 0.0, "motor_speed": 1e9}
    rng = np.random.default_rng(0)
    assert np.array_equal(applied_controls(u, 0.033, np.zeros(2), bounds, [V_100RPM] * 2, none, rng), u)
    slow = applied_controls(u, 0.033, np.zeros(2), bounds, [V_100RPM] * 2, {**none, "motor_speed": 0.6}, rng)
    per_step = 60.0 * 2 * math.pi / 60 * 0.005 * 0.033          # 1.04 mm per step
    assert np.isclose(slow[5, 0], per_step) and np.isclose(slow[-1, 0], 0.01)
    lag = applied_controls(u, 0.033, np.zeros(2), bounds, [V_100RPM] * 2, {**none, "motor_lag_s": 0.1}, rng)
    assert np.isclose(lag[5, 0], 0.01 * (1 - math.exp(-0.33)))
    ramp = np.stack([np.linspace(0.0, 0.0095, 20), np.zeros(20)], axis=1)      # 0.5 mm per step
    jit = applied_controls(ramp, 0.033, np.zeros(2), bounds, [V_100RPM] * 2, {**none, "timing_jitter_s": 0.01}, rng)
    err = np.abs(jit - ramp)[1:-1, 0] / (0.0005 * 0.01 / 0.033)                  # in units of the largest shift
    assert 0.05 < err.max() <= 1.0 + 1e-9 and len(np.unique(np.round(err, 6))) > 10


@pytest.mark.parametrize("incline,uphill,slope,direction", [(0, 0, 10, 135), (10, 0, 0, 0), (10, 90, 10, 90),
                                                            (20, 0, 10, 180)])
def test_perturbed_slope_composes_tilts(incline, uphill, slope, direction):
    a, h = perturbed_slope(incline, uphill, slope, direction)
    if incline == 0:
        assert np.isclose(a, slope) and np.isclose(h % 360, direction)
    elif slope == 0:
        assert np.isclose(a, incline) and np.isclose(h, uphill)
    elif direction == uphill:
        assert np.isclose(a, incline + slope) and np.isclose(h, uphill)
    else:
        assert np.isclose(a, incline - slope) and np.isclose(h, uphill)


def test_robustness_command_report_resume_and_fallback(tmp_path, capsys, monkeypatch):
    """Without Ray, ``--workers 2`` runs in-process and says so."""
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name, *a))
    result = tiny_result(tmp_path)
    out = tmp_path / "rob"
    args = ["robustness", str(result), "--samples", "3", "--cycles", "1", "--out", str(out), "--seed", "5",
            "--workers", "2"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "running in-process (--workers 2 needs" in text and "nominal speed" in text
    report = json.loads((out / "report.json").read_text())
    assert report["samples"] == 3 and 0.0 <= report["upright_fraction"] <= 1.0
    q = report["speed_bl_per_min"]
    assert q["p5"] <= q["median"] <= q["p95"] and np.isfinite(report["nominal"]["speed_bl_per_min"])
    assert len(report["worst"]) == 3 and set(PERTURBATIONS) <= set(report["worst"][0])
    assert (out / "robustness.png").stat().st_size > 10_000
    assert len((out / "samples.csv").read_text().splitlines()) == 4
    lines = (out / "samples.jsonl").read_text().splitlines()
    assert len(lines) == 3
    # a rerun with one more sample runs only that one and reuses the others exactly
    assert main(args[:3] + ["4"] + args[4:]) == 0
    assert "(3 done before)" in capsys.readouterr().out
    assert (out / "samples.jsonl").read_text().splitlines()[:3] == lines
    again = json.loads((out / "report.json").read_text())
    assert again["samples"] == 4
    # other settings in the same directory are refused
    assert main(args[:-4] + ["--seed", "6"]) == 2
    assert "holds a robustness run with other settings" in capsys.readouterr().err


def test_samples_are_independent_picklable_calls(tmp_path):
    res = Result.load(tiny_result(tmp_path))
    nominal, jobs = robustness_jobs(res, 1, 2, seed=1)
    job = pickle.loads(pickle.dumps(jobs[1]))
    a = run_sample(job)
    results, where = map_samples([jobs[1]], workers=1)
    b = next(results)
    assert where == "in-process"
    for k in ("speed_bl_per_min", "heading_drift_deg_per_cycle", "max_tilt_deg"):
        assert a[k] == b[k]
    n = run_sample(nominal)
    assert n["index"] == -1 and "friction" not in n


def test_replays_use_the_gaits_contact_law(tmp_path):
    """A gait made under the Coulomb law is replayed under it: the nominal replay is the
    evaluation of the result (``trajopt evaluate``), and differs from the paper's law."""
    from trajopt.evaluation import evaluate_result
    speeds = {}
    for law in ("paper", "coulomb"):
        res = Result.load(tiny_result(tmp_path, law))
        nominal, jobs = robustness_jobs(res, 2, 1, seed=1)
        assert nominal.contact == law and jobs[0].contact == law
        speeds[law] = run_sample(nominal)["speed_bl_per_min"]
        assert speeds[law] == pytest.approx(evaluate_result(res, 2)["speed_bl_per_min"], rel=1e-12, abs=1e-12)
    assert speeds["paper"] != speeds["coulomb"]


def test_samples_on_ray_equal_the_in_process_ones(tmp_path):
    """With Ray and ``trajopt sweep`` installed, ``--workers`` maps the same calls on Ray."""
    ray = pytest.importorskip("ray")
    if importlib.util.find_spec("trajopt.sweep") is None:
        pytest.skip("trajopt sweep (the Ray runner) is not installed")
    res = Result.load(tiny_result(tmp_path))
    _, jobs = robustness_jobs(res, 1, 2, seed=3)
    try:
        results, where = map_samples(jobs, workers=2)
        on_ray = sorted(results, key=lambda s: s["index"])
    finally:
        ray.shutdown()
    assert where == "on Ray with 2 workers"
    for a, b in zip(on_ray, (run_sample(j) for j in jobs)):
        assert a["speed_bl_per_min"] == b["speed_bl_per_min"] and a["upright"] == b["upright"]


def robustness_run(tmp_path, samples: int = 2):
    """A finished run of ``samples`` samples in tmp_path/rob, and its command line."""
    out = tmp_path / "rob"
    args = ["robustness", str(tiny_result(tmp_path)), "--samples", str(samples), "--cycles", "1", "--out", str(out),
            "--seed", "5"]
    assert main(args) == 0
    return out, args


def run_cli(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


GOOD = {"index": 1, "speed_bl_per_min": 1.0, "upright": True, "heading_drift_deg_per_cycle": 0.0,
        "max_tilt_deg": 1.0, **{k: 1.0 for k in PERTURBATIONS}}
BAD_LINES = {
    "a list": ("[1, 2]", "a sample must be a JSON object, got list"),
    "no sample fields": ('{"foo": 1}', "field 'index' must be a sample number >= 0, got None"),
    "no speed": (json.dumps({k: v for k, v in GOOD.items() if k != "speed_bl_per_min"}),
                 "field 'speed_bl_per_min' must be a number, got nothing (missing)"),
    "index abc": (json.dumps({**GOOD, "index": "abc"}), "field 'index' must be a sample number >= 0, got 'abc'"),
    "upright text": (json.dumps({**GOOD, "upright": "yes"}), "field 'upright' must be true or false"),
    "not json": ('{"index": 1, "speed', "line 2: not valid JSON"),
}


@pytest.mark.parametrize("case", sorted(BAD_LINES))
def test_a_damaged_samples_line_is_one_error_naming_file_and_line(tmp_path, capsys, case):
    out, args = robustness_run(tmp_path, samples=1)
    capsys.readouterr()
    lines = out / "samples.jsonl"
    line, message = BAD_LINES[case]
    lines.write_text(lines.read_text() + line + "\n")             # a whole line (with its newline), damaged
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    code, _, err = run_cli(args, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{lines} line 2: " in err and message in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.name in before} == before     # left as it was


@pytest.mark.parametrize("text,message", [("[]", "the run's settings must be a JSON object, got list"),
                                          (None, "the run's settings is not valid JSON")])
def test_a_damaged_settings_file_is_one_error_naming_it(tmp_path, capsys, text, message):
    out, args = robustness_run(tmp_path, samples=1)
    capsys.readouterr()
    sfile = out / "settings.json"
    sfile.write_text(text if text is not None else sfile.read_text()[:40])        # [] or truncated
    code, _, err = run_cli(args, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{sfile}: {message}" in err and "--overwrite" in err


def test_a_line_cut_by_a_crash_is_repaired_and_its_sample_runs_again(tmp_path, capsys):
    out, args = robustness_run(tmp_path, samples=3)
    lines = out / "samples.jsonl"
    whole = lines.read_text().splitlines()
    lines.write_text("\n".join(whole[:2]) + "\n" + whole[2][:25])     # killed while appending sample 3
    capsys.readouterr()
    code, text, err = run_cli(args, capsys)
    assert code == 0, err
    assert f"warning: {lines} line 3 was cut" in err and "(2 done before)" in text
    again = lines.read_text().splitlines()
    assert len(again) == 3 and again[:2] == whole[:2]
    redone, first = json.loads(again[2]), json.loads(whole[2])
    assert redone["index"] == first["index"] and redone["speed_bl_per_min"] == first["speed_bl_per_min"]
    assert lines.read_text().endswith("\n")


def test_robustness_off_a_terminal_beats_while_it_replays(tmp_path, capsys, monkeypatch):
    """Off a terminal, no tqdm bar (no carriage return) but a plain line after any silence of
    the heartbeat period (30 s, shortened here) while the replays run (#41)."""
    import time

    import trajopt.progress
    import trajopt.robustness.report as report_module
    monkeypatch.setattr(trajopt.progress, "HEARTBEAT_S", 0.05)
    real = report_module.run_sample

    def slow(job):
        time.sleep(0.3)
        return real(job)

    monkeypatch.setattr(report_module, "run_sample", slow)
    result = tiny_result(tmp_path)
    assert main(["robustness", str(result), "--samples", "1", "--cycles", "1", "--out", str(tmp_path / "rob"),
                 "--workers", "1"]) == 0
    err = capsys.readouterr().err
    assert "robustness: 0/1 replays, still working" in err and "\r" not in err


def test_the_robustness_plot_names_the_gait_it_studies(tmp_path, png_titles):
    """robustness.png's title names the gait (its result file) and the replays (#41)."""
    import trajopt.robustness.report as report_module
    titles = png_titles(report_module)
    result = tiny_result(tmp_path)
    assert main(["robustness", str(result), "--samples", "2", "--cycles", "1", "--out", str(tmp_path / "rob"),
                 "--workers", "1"]) == 0
    assert titles == [f"robustness of the gait {result.name}: its speed over 2 perturbed replays of 1 cycle"]
