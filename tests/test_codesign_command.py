"""``trajopt codesign`` end to end in quick mode (issue #29 item 3): the files it writes, the
written robot loads and simulates and its constraints hold (checked from the files), a result made
on the written robot refuses the shipped one, resume after an interruption, and the refusals."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from soft_envs.envs import load_robot
from trajopt import Result
from trajopt.cli import main
from trajopt.codesign.run import CodesignRun, run_codesign
from trajopt.codesign.checks import check_designed_robot
from trajopt.evaluation import evaluate_result


CHECKPOINTS: list[dict] = []       # every state ``done``'s run checkpointed (each screening round, each iteration)


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    import trajopt.codesign.run as run_module
    out = tmp_path_factory.mktemp("codesign") / "tripod"
    original = run_module._write_json

    def keep(path, data):
        if path.name == "codesign.partial.json":
            CHECKPOINTS.append(json.loads(json.dumps(data["state"], default=float)))
        original(path, data)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_module, "_write_json", keep)
        assert main(["codesign", "tripod", "--quick", "--quiet", "--out", str(out)]) == 0
    return out


def test_every_stage_keeps_the_design_within_its_bounds_and_over_the_mass_floor(done):
    """Every design a stage moved to or stood at (the screening's rounds, each joint Gauss-Newton
    iterate and its linearisation points, the written robot) lies within the [design] table's
    bounds, and its total mass is at least 98 % of the shipped robot's (the floor is pinned)."""
    from soft_envs.envs.design import MAX_MASS_LOSS, load_design
    from trajopt.codesign import CodesignProblem
    assert MAX_MASS_LOSS == 0.02
    shipped = load_design(load_robot("tripod"))
    lo, hi = shipped.bounds[:, 0], shipped.bounds[:, 1]
    floor = 0.98 * shipped.total_mass()
    n = len(shipped)
    assert CHECKPOINTS and any(s["screened"] for s in CHECKPOINTS) and any(s["history"] for s in CHECKPOINTS)

    def check(thetas, where):
        block, anchor = shipped, shipped.values.copy()
        for theta in thetas:
            theta = np.asarray(theta, dtype=np.float64)
            assert theta.shape == (n,), where
            assert np.all(theta >= lo - 1e-12) and np.all(theta <= hi + 1e-12), (where, theta)
            block, anchor = CodesignProblem.moved(block, anchor, theta)       # as the run moves
            assert block.total_mass() >= floor * (1 - 1e-12), (where, block.total_mass(), floor)

    stages = set()
    for k, state in enumerate(CHECKPOINTS):
        progress = state.get("screen_progress") or {}
        check(progress.get("path", []), f"checkpoint {k}: the screening's path")
        if progress:
            stages.add("screen")
            check(progress.get("path", []) + [progress["theta"]], f"checkpoint {k}: the screening's design")
        check(state["path"], f"checkpoint {k}: the joint stage's designs")
        check(state["path"] + [state["w"][-n:]], f"checkpoint {k}: the joint iterate")
        if state["history"]:
            stages.add("joint")
    assert stages == {"screen", "joint"}
    written = load_design(load_robot(done / "robot.toml"))
    assert np.all(written.values >= lo - 1e-9) and np.all(written.values <= hi + 1e-9)
    assert written.total_mass() >= floor * (1 - 1e-12)


def test_writes_a_robot_folder_its_gait_and_a_report(done):
    for name in ("robot.toml", "tripod_walk.npz", "tripod_walk_reoptimised.npz", "baseline_walk.npz",
                 "codesign.md", "codesign.png", "codesign.json"):
        assert (done / name).is_file() and (done / name).stat().st_size > 0, name
    assert not (done / "codesign.partial.json").exists()
    summary = json.loads((done / "codesign.json").read_text())
    assert summary["checks_passed"] and summary["after_upright"]
    rank = lambda g: (summary[f"{g}_holds"], summary[f"{g}_slowest_bl_per_min"])     # noqa: E731
    assert rank("after") >= rank("before")            # the screening and the stages keep the best, credibly
    assert summary["credible_ratio"] == summary["after_slowest_bl_per_min"] / summary["before_slowest_bl_per_min"]
    text = (done / "codesign.md").read_text()
    assert "Design changes" in text and "codesign.png" in text and "Credible speed ratio, co-designed" in text


def test_written_robot_loads_simulates_and_holds_its_constraints(done):
    robot = load_robot(done / "robot.toml")
    assert robot.motor_names == load_robot("tripod").motor_names
    assert all(c.passed for c in check_designed_robot("tripod", done / "robot.toml"))
    res = Result.load(done / "tripod_walk.npz")
    ev = evaluate_result(res, 2)
    assert np.isclose(ev["speed_bl_per_min"], json.loads((done / "codesign.json").read_text())["after_bl_per_min"])


def test_a_result_made_on_the_written_robot_refuses_the_shipped_one(done):
    res = Result.load(done / "tripod_walk.npz")
    res.robot = "tripod"
    with pytest.raises(ValueError, match="robot"):
        evaluate_result(res, 1)


def test_refuses_to_replace_a_finished_run_and_unknown_kinds(done, capsys):
    assert main(["codesign", "tripod", "--quick", "--quiet", "--out", str(done)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["codesign", "tripod", "--vary", "wings", "--out", str(done)])
    assert exc.value.code == 2


@pytest.mark.parametrize("stage", ["screen_progress", "history"])
def test_resume_continues_an_interrupted_run(tmp_path, done, stage):
    """Interrupted at its first checkpoint after a screening round, or at its first joint
    checkpoint, resumed (in this process; ``done`` scored its candidates in one worker process
    per core): the same design and speed as a run that was never interrupted."""
    import trajopt.codesign.run as run_module
    out = tmp_path / "again"
    shutil.copytree(done, out)
    for name in ("robot.toml", "codesign.json", "codesign.md", "tripod_walk.npz"):
        (out / name).unlink()
    original = run_module._write_json
    calls = []

    def interrupt(path, data):
        original(path, data)
        calls.append(path.name)
        if path.name == "codesign.partial.json" and data["state"][stage]:
            raise KeyboardInterrupt

    run_module._write_json = interrupt
    try:
        with pytest.raises(KeyboardInterrupt):
            run_codesign(CodesignRun.quick("tripod", out, quiet=True, reoptimise=False, overwrite=True,
                                           baseline=done / "baseline_walk.npz"))
    finally:
        run_module._write_json = original
    assert (out / "codesign.partial.json").is_file()
    outcome = run_codesign(CodesignRun.quick("tripod", out, quiet=True, reoptimise=False, resume=True,
                                             baseline=done / "baseline_walk.npz"))
    reference = json.loads((done / "codesign.json").read_text())
    assert outcome.summary["after_bl_per_min"] == pytest.approx(reference["after_bl_per_min"], rel=1e-9)
    body = lambda p: [line for line in p.read_text().splitlines() if not line.startswith("# Designed")]  # noqa: E731
    assert body(out / "robot.toml") == body(done / "robot.toml")          # the header has the date


def test_scratch_scored_screening_runs(tmp_path, done):
    """--screen scratch: each candidate's gait found as --speed max finds it (quick search; the
    legs only: 7 candidates a round, where the default design's 11 take about twice the time)."""
    out = tmp_path / "scratch"
    assert main(["codesign", "tripod", "--quick", "--quiet", "--screen", "scratch", "--no-reoptimise", "--vary", "legs",
                 "--baseline", str(done / "baseline_walk.npz"), "--out", str(out)]) == 0
    summary = json.loads((out / "codesign.json").read_text())
    assert summary["checks_passed"] and summary["after_bl_per_min"] > 0


def _contents(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_resume_of_a_finished_codesign_has_nothing_to_do(done, capsys):
    """Issue #40 defect 2: --resume on a finished folder ran again and replaced it."""
    before = _contents(done)
    assert main(["codesign", "tripod", "--quick", "--quiet", "--resume", "--out", str(done)]) == 0
    assert "nothing to resume" in capsys.readouterr().out
    assert _contents(done) == before


def test_resume_of_a_finished_codesign_with_another_vary_is_refused(done, capsys):
    before = _contents(done)
    assert main(["codesign", "tripod", "--quick", "--quiet", "--resume", "--vary", "legs", "--out", str(done)]) == 2
    err = capsys.readouterr().err
    assert "varied stiffness,routing,legs, not --vary legs" in err and "--overwrite" in err, err
    assert _contents(done) == before


def test_a_codesign_folder_moved_elsewhere_still_works(done, tmp_path, monkeypatch):
    """Issue #40: the written robot pointed to the shipped mesh by a relative path and its
    results to the robot by the path typed: a copied or moved folder broke. The folder holds
    its mesh, and its results find the robot beside them."""
    from soft_envs.sim.robot_file import read_robot_toml
    assert read_robot_toml(done / "robot.toml")["robot"]["mesh"] == "mesh.vtu"
    moved = tmp_path / "far" / "away"
    moved.parent.mkdir()
    done.rename(moved)
    try:
        monkeypatch.chdir(tmp_path)
        for name in ("tripod_walk.npz", "tripod_walk_reoptimised.npz"):
            ev = evaluate_result(Result.load(moved / name), 1)
            assert ev["cycles"] == 1
    finally:
        moved.rename(done)
