"""``trajopt optimize ROBOT --speed max`` (issue #28 item 3): the fastest upright walk within
the motors' speed limit, searched over cycle length and keyframes (:mod:`trajopt.fastest`), and
the straight-line keyframe interpolation it uses (``GaitSpec(interpolation="linear")``)."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from soft_envs.sim import load_robot
from trajopt import GaitSpec
from trajopt.argtypes import speed
from trajopt.cli import main
from trajopt.fastest import SearchSettings, keyframes_at, search_table_paths
from trajopt.search.hold import FASTEST_HELD, FASTEST_UPRIGHT, SLOWEST_BEST, choose_gait, hold_steps
from trajopt.optim.motor_limit import speed_limit_constraints
from trajopt.optim.parameterization import (
    GaitParameterization,
    hermite_cycle_basis,
    linear_cycle_basis,
)
from trajopt.results.result import Result

from .test_motor_limit import STEP, _obeys_over_ten_cycles


def test_straight_lines_between_keyframes_have_a_constant_slope():
    B = linear_cycle_basis(12, 4)
    kf = np.array([0.0, 3.0, 3.0, -3.0])
    u = B @ kf
    assert np.allclose(u[::3], kf) and np.allclose(np.diff(np.append(u, u[0])), [1, 1, 1, 0, 0, 0, -2, -2, -2, 1, 1, 1])
    assert np.allclose(B.sum(axis=1), 1.0) and np.allclose(hermite_cycle_basis(12, 4)[::3], np.eye(4))


@pytest.mark.parametrize("robot", ["tripod", "puppy"])
def test_straight_lines_can_use_the_whole_limit_where_the_papers_spline_cannot(robot):
    """Keyframes alternating between the ends of a range that the motor crosses in exactly one
    keyframe interval at full speed: the straight lines obey the limit, the zero-tangent spline
    (peak slope 1.5 times its mean) breaks it."""
    r = load_robot(robot)
    gait = GaitSpec(n_prep=24, n_cycle=24, n_keyframes=4)
    lo, hi = r.u_bounds[:, 0], r.u_bounds[:, 0] + 6 * r.max_contraction_step(0.033)      # 6 steps per keyframe
    kf = np.column_stack([lo, hi, lo, hi])
    for interpolation, obeys in (("linear", True), ("hermite", False)):
        param = GaitParameterization.for_robot(r, gait.replace(interpolation=interpolation))
        c = speed_limit_constraints(param, r.max_contraction_step(0.033))
        assert (c.violation(param.z_from_keyframes(kf)) <= 1e-12) == obeys, interpolation


def test_the_papers_gait_is_the_default_and_older_results_read_as_it():
    assert GaitSpec().interpolation == "hermite"
    assert GaitSpec.from_settings({"n_cycle": 72}).interpolation == "hermite"
    with pytest.raises(ValueError, match="GaitSpec.interpolation must be one of .*got 'cubic'"):
        GaitSpec(interpolation="cubic")


def test_keyframes_at_other_phases_keep_the_cycle():
    kf = np.array([[0.0, 2.0, 4.0, 2.0]])
    assert np.allclose(keyframes_at(kf, 8), [[0, 1, 2, 3, 4, 3, 2, 1]])
    assert np.allclose(keyframes_at(kf, 4), kf) and keyframes_at(kf, 2).shape == (1, 2)


def test_the_speed_option_takes_a_number_or_max():
    import argparse
    assert speed("max") == "max" and speed("12.5") == 12.5
    with pytest.raises(argparse.ArgumentTypeError, match="must be a finite number > 0 \\[BL/min\\] or 'max', got 'fast'"):
        speed("fast")


def test_the_search_order_and_the_pinned_cycle():
    s = SearchSettings()
    assert s.candidates()[:4] == [(8, 4), (12, 4), (16, 4), (16, 8)]
    assert s.candidates(24) == [(24, 4), (24, 8)]
    assert s.gait(8, 4).n_cycles * 8 >= s.min_horizon_steps and s.gait(72, 4).n_cycles == 2
    with pytest.raises(ValueError, match="no \\(cycle, keyframes\\) candidate"):
        s.candidates(6)


@pytest.fixture(scope="module")
def speed_max(tmp_path_factory):
    """``trajopt optimize tripod --speed max`` in quick mode (SOFT_ENVS_QUICK=1)."""
    out = tmp_path_factory.mktemp("max")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SOFT_ENVS_QUICK", "1")
        assert main(["optimize", "tripod", "--speed", "max", "--contact", "coulomb", "--quiet", "--out", str(out)]) == 0
    return out / "tripod_walk.npz"


def test_speed_max_writes_the_gait_its_rule_chooses_from_its_table(speed_max):
    """The refined gait is replayed at 2, 8 and 16 physics steps per control step; the result is
    the fastest gait that holds, by its slowest speed, else the fastest upright one; the table's
    steps add up to the search's."""
    res = Result.load(speed_max)
    csv_path, md_path = search_table_paths(speed_max)
    assert md_path.is_file()
    rows = list(csv.DictReader(csv_path.open()))
    chosen = [r for r in rows if r["chosen"] == "True"]
    assert len(rows) >= 2 and len(chosen) == 1
    best = chosen[0]
    assert best["motor_model"] == res.settings["motor_model"] == "torque-speed" and best["stage"] == "fine"
    upright = [r for r in rows if r["upright"] == "True" and r["motor_model"] == best["motor_model"]]
    assert {r["motor_model"] for r in rows if r["stage"] != "fine"} == {"speed"}     # explored under the speed limit
    assert {r["holds"] for r in rows if r["stage"] == "fine"} <= {"True", "False"}   # every refined gait checked
    assert {r["holds"] for r in rows if r["stage"] != "fine"} == {""}
    held = [r for r in upright if r["holds"] == "True"]
    if held:
        assert float(best["slowest_bl_per_min"]) == max(float(r["slowest_bl_per_min"]) for r in held)
    elif any(r["holds"] == "False" and float(r["slowest_bl_per_min"]) > 0 for r in upright):
        assert float(best["slowest_bl_per_min"]) == max(float(r["slowest_bl_per_min"]) for r in upright
                                                        if r["holds"] == "False")
    else:
        assert float(best["speed_bl_per_min"]) == max(float(r["speed_bl_per_min"]) for r in upright)
    hold = res.evaluation["hold"]
    assert hold["substeps"] == [2, 4, 8, 16] and hold["speeds"][1] == res.evaluation["speed_bl_per_min"]
    assert hold["slowest"] == pytest.approx(float(best["slowest_bl_per_min"]), rel=1e-12)
    assert (int(best["n_cycle"]), int(best["n_keyframes"])) == (res.settings["n_cycle"], res.settings["n_keyframes"])
    assert res.evaluation["speed_bl_per_min"] == pytest.approx(float(best["speed_bl_per_min"]), rel=1e-12)
    assert res.evaluation["upright"] and res.settings["interpolation"] == "linear"
    assert res.evaluation["search_sim_steps"] == int(rows[-1]["total_sim_steps"]) + sum(
        int(r["hold_sim_steps"]) for r in rows) == sum(int(r["optimization_sim_steps"]) + int(r["evaluation_sim_steps"])
                                                        + int(r["hold_sim_steps"]) for r in rows)
    assert res.settings["search"]["chosen_by"].startswith((FASTEST_HELD,) if held else (SLOWEST_BEST, FASTEST_UPRIGHT))


def _run(speed, credible=None, holds="", slowest=float("nan")):
    row = {"speed_bl_per_min": speed, "credible_bl_per_min": speed if credible is None else credible,
           "holds": holds, "slowest_bl_per_min": slowest}
    return row, f"gait {speed}"


def test_the_search_returns_the_fastest_gait_that_holds_by_its_slowest_speed():
    """The gait that holds with the highest slowest speed; else the highest slowest speed; else the fastest."""
    fragile = _run(20.5, holds=False, slowest=18.1)
    steady = _run(16.5, holds=True, slowest=16.2)
    steadier_but_slower = _run(16.9, holds=True, slowest=15.0)
    never_checked = _run(25.0)
    assert choose_gait([fragile, steady, steadier_but_slower, never_checked])[1:] == ("gait 16.5", FASTEST_HELD)
    # none holds: the highest slowest speed among the gaits replayed at every step (a budget-cut
    # search's 8-step gait, 16.9 BL/min spreading 29 % to 14.9, loses to a 15.3 one at 15.0)
    spreading = _run(16.9, holds=False, slowest=14.9)
    row, res, rule = choose_gait([spreading, never_checked, _run(15.3, holds=False, slowest=15.0),
                                  _run(30.0, holds=False, slowest=float("nan"))])          # fell at some step
    assert res == "gait 15.3" and rule == (SLOWEST_BEST + ": none of the 3 gait(s) checked holds its speed "
                                           "within 5 % at other physics steps")
    # none replayed upright and forwards at every step: the fastest, saying how many were checked
    fell, backwards = _run(30.0, holds=False, slowest=float("nan")), _run(31.0, holds=False, slowest=-2.0)
    row, res, rule = choose_gait([never_checked, fell, backwards])
    assert res == "gait 31.0" and rule == (FASTEST_UPRIGHT + ": none of the 2 gait(s) checked holds its speed "
                                           "within 5 % at other physics steps")
    assert choose_gait([_run(9.0, credible=7.0), _run(8.5)])[1:] == ("gait 8.5", FASTEST_UPRIGHT)   # an ensemble's
    with pytest.raises(ValueError, match="no upright gait"):
        choose_gait([])


def test_the_replays_of_the_hold_check():
    assert hold_steps(4) == [2, 8, 16] and hold_steps(1) == [2, 4] and hold_steps(3, (0.5, 2.0)) == [6]
    assert hold_steps(4, ()) == []


def test_speed_max_obeys_the_limit_over_ten_cycles(speed_max):
    res = Result.load(speed_max)
    assert res.settings["motor_limit"]["max_step_m"] == pytest.approx([STEP, STEP], rel=1e-12)
    assert _obeys_over_ten_cycles(res, np.zeros(2)) <= 1e-9
    assert max(res.evaluation["motor_load"]["worst_line_excess"]) <= 0.01          # and the torque-speed line


def test_play_dry_run_accepts_the_speed_max_result(speed_max, capsys):
    from trajopt.hardware import EXAMPLE_TRIPOD
    capsys.readouterr()
    code = main(["play", str(speed_max), "--hardware", str(EXAMPLE_TRIPOD), "--dry-run"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "warning" not in err


def test_speed_max_pins_the_cycle(tmp_path, monkeypatch):
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")
    assert main(["optimize", "tripod", "--speed", "max", "--cycle-steps", "12", "--contact", "coulomb", "--quiet",
                 "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(search_table_paths(tmp_path / "tripod_walk.npz")[0].open()))
    assert {r["n_cycle"] for r in rows} == {"12"} and Result.load(tmp_path / "tripod_walk.npz").settings["n_cycle"] == 12


@pytest.mark.parametrize("args, message", [
    (["--task", "turn"], "--speed max finds the fastest walk: it needs --task walk, got --task turn"),
    (["--task", "incline"], "--speed max finds the fastest walk: it needs --task walk, got --task incline"),
    (["--no-motor-limit"], "--speed max cannot be combined with --no-motor-limit"),
])
def test_speed_max_refuses_what_it_cannot_do(tmp_path, capsys, args, message):
    assert main(["optimize", "tripod", "--speed", "max", *args, "--quiet", "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_the_search_keeps_within_its_budget():
    """A budget of simulation steps is never passed: runs that would not fit are skipped
    (listed), a run stops early rather than risk it."""
    import dataclasses

    from trajopt.fastest import fastest_gait
    settings = dataclasses.replace(SearchSettings.quick(), coarse_iterations=3, max_sim_steps=600)
    res, rows = fastest_gait("tripod", contact="coulomb", settings=settings, quiet=True)
    assert rows[-1]["total_sim_steps"] + sum(r["hold_sim_steps"] for r in rows) == res.evaluation["search_sim_steps"] <= 600
    assert any(r["status"] == "skipped: budget" for r in rows) or any(r["status"] == "callback" for r in rows)


def test_the_command_takes_the_search_budget(tmp_path, monkeypatch):
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")
    assert main(["optimize", "tripod", "--speed", "max", "--max-sim-steps", "500", "--contact", "coulomb", "--quiet",
                 "--out", str(tmp_path)]) == 0
    res = Result.load(tmp_path / "tripod_walk.npz")
    assert res.evaluation["search_sim_steps"] <= 500 and res.settings["search"]["settings"]["max_sim_steps"] == 500


def test_a_budget_that_fits_no_candidate_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")
    assert main(["optimize", "tripod", "--speed", "max", "--max-sim-steps", "50", "--quiet", "--out", str(tmp_path)]) == 2
    assert "--speed max: a budget of 50 simulation steps fits none of the 2 candidates" in capsys.readouterr().err
    assert not (tmp_path / "tripod_walk.npz").exists()


def test_revisit_runs_the_shorter_cycles_from_the_fastest_coarse_gait():
    """The revisit stage: every candidate with a shorter cycle than the fastest upright coarse
    gait, warm-started from its keyframes at the same phases (no seeds); nothing when the
    fastest is the shortest cycle or nothing stood."""
    from types import SimpleNamespace

    from trajopt.fastest import _revisit
    settings = SearchSettings()
    kf16 = np.array([[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], [7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0]])

    def run_of(n_cycle, n_kf, speed, upright=True, keyframes=None):
        kf = keyframes if keyframes is not None else np.zeros((2, n_kf))
        return ({"n_cycle": n_cycle, "n_keyframes": n_kf, "speed_bl_per_min": speed,
                 "credible_bl_per_min": speed, "upright": upright},
                SimpleNamespace(settings={"keyframes": kf.tolist()}))

    class Search:
        def __init__(self, runs):
            self.runs, self.calls, self.rows, self.bar = runs, [], [], None

        def run(self, stage, gait, start, iterations, share, *, warm=None, z0=None, n_seeds=0):
            self.calls.append((stage, gait.n_cycle, gait.n_keyframes, start, np.asarray(warm.settings["keyframes"]),
                               iterations, share, n_seeds))

    search = Search([run_of(8, 4, 4.9), run_of(12, 4, 18.8), run_of(16, 8, 21.8, keyframes=kf16),
                     run_of(24, 4, 30.0, upright=False)])
    candidates = settings.candidates()
    _revisit(search, settings, candidates)
    assert [(c[1], c[2]) for c in search.calls] == [(8, 4), (12, 4)]
    for stage, _, n_kf, start, warm, iterations, share, n_seeds in search.calls:
        assert stage == "revisit" and start == "cycle 16, 8 keyframes" and n_seeds == 0
        assert (iterations, share) == (settings.coarse_iterations, settings.coarse_share)
        np.testing.assert_array_equal(warm, keyframes_at(kf16, n_kf))
    shortest_best = Search([run_of(8, 4, 26.6), run_of(12, 4, 22.1)])
    _revisit(shortest_best, settings, candidates)
    assert shortest_best.calls == []
    none_upright = Search([run_of(8, 4, 26.6, upright=False)])
    _revisit(none_upright, settings, candidates)
    assert none_upright.calls == []


@pytest.mark.parametrize("budget", [None, 100_000])
def test_no_candidate_that_can_be_simulated_is_said_so(tmp_path, capsys, monkeypatch, budget):
    """Issue #40 defect 6: every candidate failing to simulate ended in a TypeError traceback
    (a budget of None formatted), or with --max-sim-steps blamed the budget."""
    import trajopt.fastest as fastest
    from soft_envs.envs import SimulationError

    def fails(*args, **kw):
        raise SimulationError("Newton did not converge")

    monkeypatch.setattr(fastest, "optimize_gait", fails)
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")
    extra = [] if budget is None else ["--max-sim-steps", str(budget)]
    assert main(["optimize", "tripod", "--speed", "max", *extra, "--quiet", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "no candidate could be simulated" in err and "Newton did not converge" in err and "budget" not in err, err
    assert not (tmp_path / "tripod_walk.npz").exists()


def test_max_sim_steps_without_speed_max_is_refused(tmp_path, capsys):
    """Issue #40: --max-sim-steps was silently ignored without --speed max."""
    assert main(["optimize", "tripod", "--max-sim-steps", "500", "--quiet", "--out", str(tmp_path)]) == 2
    assert "--max-sim-steps 500 is the budget of the --speed max search" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_a_plain_overwrite_removes_an_earlier_searchs_table(speed_max, tmp_path):
    """Issue #40: a plain --overwrite left the old --speed max result's NAME.search.csv/.md
    beside a result that no search made."""
    import shutil
    for p in (speed_max, speed_max.with_suffix(".json"), *search_table_paths(speed_max)):
        shutil.copy(p, tmp_path / p.name)
    assert main(["optimize", "tripod", "--iterations", "0", "--prep-steps", "4", "--cycle-steps", "12", "--seeds",
                 "1", "--cycles", "1", "--quiet", "--overwrite", "--out", str(tmp_path)]) == 0
    assert "search" not in Result.load(tmp_path / "tripod_walk.npz").settings
    assert not any(p.exists() for p in search_table_paths(tmp_path / "tripod_walk.npz"))


def test_a_search_checkpoint_of_another_search_or_damaged_is_refused(tmp_path):
    """--speed max --resume checks its checkpoint: another search's (settings, robot, law) is
    refused naming what differs; a damaged state.json names the file."""
    import json

    from trajopt.fastest import SearchCheckpoint
    identity = {"settings": {"seeds": 1, "keyframes": [4]}, "contact": "coulomb"}
    store = SearchCheckpoint(tmp_path / "m.search.partial", identity)
    store.start([])
    assert store.load() == ([], "running")
    other = SearchCheckpoint(store.folder, {"settings": {"seeds": 2, "keyframes": [4]}, "contact": "coulomb"})
    with pytest.raises(ValueError, match=r"cannot resume: .*settings\.seeds: 1 -> 2.*--overwrite"):
        other.load()
    store.state_file.write_text(json.dumps({"identity": identity, "rows": [{"stage": "coarse"}]}))
    with pytest.raises(ValueError, match=r"state\.json: field 'rows'"):
        store.load()
    store.state_file.write_text('{"identity": {')
    with pytest.raises(ValueError, match=r"state\.json: not JSON"):
        store.load()


def test_speed_max_returns_the_fastest_upright_gait_never_one_that_fell(monkeypatch):
    """Which gait ``fastest_gait`` returns, with the optimiser replaced by a table of outcomes:
    in every stage the fastest gait falls (as an optimiser pushed past what the robot can hold
    does). The fine stage continues only from upright coarse gaits (the fastest of them first),
    and the result is the fastest upright run of the search's own motor model, marked chosen in
    its table; with nothing upright the search raises instead of returning a fallen gait."""
    from types import SimpleNamespace

    import trajopt.fastest as fastest
    from soft_envs.envs import SimulationError

    settings = SearchSettings(cycle_steps=(8, 12, 16), keyframes=(4,), seeds=0, coarse_iterations=1,
                              fine_iterations=1, n_fine=2, min_horizon_steps=16, n_prep=4, eval_cycles=2,
                              revisit=False)
    coarse = {8: (30.0, False), 12: (14.0, True), 16: (18.0, True)}       # n_cycle -> (speed, upright)
    fine = {16: (21.0, True), 12: (40.0, False)}                          # the fine run from cycle 12 falls
    calls = []

    def fake_optimize(env, task, *, gait, z0=None, motor_model=None, **kw):
        stage = "coarse" if z0 is None else "fine"
        speed, upright = (coarse if stage == "coarse" else fine)[gait.n_cycle]
        calls.append((stage, gait.n_cycle, motor_model))
        settings_ = {"n_prep": gait.n_prep, "n_cycle": gait.n_cycle, "n_cycles": gait.n_cycles,
                     "n_keyframes": gait.n_keyframes, "eval_cycles": 2, "symmetry": gait.symmetry,
                     "interpolation": gait.interpolation, "keyframes": np.zeros((2, gait.n_keyframes)).tolist()}
        return SimpleNamespace(settings=settings_, history=[{}], status="max_iter", z=np.full(4, gait.n_cycle),
                               evaluation={"speed_bl_per_min": speed, "upright": upright, "max_tilt_deg": 5.0,
                                           "optimization_sim_steps": 10})

    monkeypatch.setattr(fastest, "optimize_gait", fake_optimize)
    res, rows = fastest.fastest_gait("tripod", settings=settings, quiet=True, motor_model="speed")
    assert [(s, n) for s, n, _ in calls] == [("coarse", 8), ("coarse", 12), ("coarse", 16), ("fine", 16), ("fine", 12)]
    assert res.evaluation["speed_bl_per_min"] == 21.0 and res.evaluation["upright"]
    chosen = [r for r in rows if r["chosen"]]
    assert len(chosen) == 1 and (chosen[0]["stage"], chosen[0]["n_cycle"]) == ("fine", 16)
    assert max(r["speed_bl_per_min"] for r in rows) == 40.0          # faster gaits were there, and fell

    coarse.update({12: (14.0, False), 16: (18.0, False)})
    calls.clear()
    with pytest.raises(SimulationError, match="none of the 3 gaits tried stayed upright"):
        fastest.fastest_gait("tripod", settings=settings, quiet=True, motor_model="speed")
    assert all(stage == "coarse" for stage, _, _ in calls)            # nothing fell into the fine stage


def test_speed_max_off_a_terminal_prints_plain_lines_and_a_heartbeat(monkeypatch, capsys):
    """Off a terminal, ``--speed max`` prints a plain line per optimisation (no tqdm carriage
    returns in a log) and a heartbeat when one takes longer than the heartbeat period (30 s,
    shortened here) (#41)."""
    import time
    from types import SimpleNamespace

    import trajopt.fastest as fastest
    import trajopt.progress

    monkeypatch.setattr(trajopt.progress, "HEARTBEAT_S", 0.05)
    settings = SearchSettings(cycle_steps=(8, 12), keyframes=(4,), seeds=0, coarse_iterations=1, fine_iterations=1,
                              n_fine=1, min_horizon_steps=16, n_prep=4, eval_cycles=2, revisit=False)

    def fake_optimize(env, task, *, gait, z0=None, motor_model=None, **kw):
        time.sleep(0.3)                                   # a slow optimisation
        settings_ = {"n_prep": gait.n_prep, "n_cycle": gait.n_cycle, "n_cycles": gait.n_cycles,
                     "n_keyframes": gait.n_keyframes, "eval_cycles": 2, "symmetry": gait.symmetry,
                     "interpolation": gait.interpolation, "keyframes": np.zeros((2, gait.n_keyframes)).tolist()}
        return SimpleNamespace(settings=settings_, history=[{}], status="max_iter", z=np.full(4, gait.n_cycle),
                               evaluation={"speed_bl_per_min": float(gait.n_cycle), "upright": True,
                                           "max_tilt_deg": 5.0, "optimization_sim_steps": 10})

    monkeypatch.setattr(fastest, "optimize_gait", fake_optimize)
    fastest.fastest_gait("tripod", settings=settings, quiet=False, motor_model="speed")
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert [line.split(",")[0] for line in lines if "still working" not in line] == [
        "--speed max: 1/3 runs", "--speed max: 2/3 runs", "--speed max: 3/3 runs"]
    assert "--speed max: 0/3 runs, still working" in err and "best 12.00 BL/min" in err


def test_the_search_table_says_its_target_is_tracked_not_enforced(tmp_path):
    """The Markdown search table explains its target column (#41): the speed of the COM path an
    optimisation tracked, not a speed it enforced."""
    from trajopt.search.table import TABLE_COLUMNS, write_search_table
    row = {c: 1 for c in TABLE_COLUMNS}
    csv_path, md_path = write_search_table([row], tmp_path / "g.npz")
    text = md_path.read_text()
    assert "target_bl_per_min: the speed of the target COM path" in text and "does not enforce its speed" in text
    assert csv_path.read_text().splitlines()[0] == ",".join(TABLE_COLUMNS)       # the CSV stays a table


def test_a_hold_check_says_where_a_gait_fell():
    from trajopt.search.hold import describe_hold
    fell = {"speeds": [float("nan"), 25.56, 26.23, 33.81], "substeps": [2, 4, 8, 16], "spread": float("inf"),
            "holds": False}
    assert describe_hold(fell) == ("fell, 25.56, 26.23, 33.81 BL/min at 2, 4, 8, 16 physics steps per control step, "
                                   "fell at 2 physics steps per control step: does not hold")
    held = {"speeds": [16.72, 16.51, 16.23, 16.47], "substeps": [2, 4, 8, 16], "spread": 0.0304, "holds": True}
    assert describe_hold(held).endswith("spread 3.0 %: holds")


def test_the_hold_verdict():
    from trajopt.search.hold import hold_verdict
    assert hold_verdict([16.72, 16.51, 16.23, 16.47]) == {"slowest": 16.23, "spread": pytest.approx(0.0302, abs=1e-4),
                                                           "holds": True}
    assert not hold_verdict([18.14, 20.51, 20.25, 21.61])["holds"]                    # 19 %
    assert not hold_verdict([-5.0, -5.1, -5.05, -5.02])["holds"]                      # steadily backwards
    fell = hold_verdict([float("nan"), 25.56, 26.23, 33.81])
    assert fell["holds"] is False and fell["slowest"] != fell["slowest"] and fell["spread"] == float("inf")
