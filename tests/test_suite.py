"""The task suite (issue #39 items 4-6): every benchmark task is a trajopt objective on the task's
own ground, RL trains on the task ids, both are scored with the task's own score, one sweep file
holds the runs, the quick mode of benchmarks/bench_suite.py renders its report with every row, and
the rl_zoo3 files are trajopt/rl/hyperparams.py's values."""
from __future__ import annotations

import importlib.util
import re
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import soft_envs
from soft_envs import TASK_ENV_IDS, TASK_IDS_BY_TASK
from soft_envs import TASKS as ALL_TASKS
from trajopt.rl.hyperparams import ALGOS, SUITE_N_ENVS, SUITE_TIMESTEPS, vecnormalize_kwargs
from trajopt.tasks import ENV_TASKS, get_task
from trajopt.tasks.scores import SCORES, _episode_score

TASKS = tuple(SCORES)            # the suite's tasks (benchmarks/bench_suite.py)
SUITE_IDS = [TASK_IDS_BY_TASK[t][r] for t in TASKS for r in ("tripod", "puppy")]

ROOT = Path(__file__).resolve().parents[1]


def test_every_benchmark_task_is_a_trajopt_task_on_the_task_s_own_ground():
    assert set(ENV_TASKS) == set(TASKS) == set(SCORES)
    assert set(TASKS) == set(ALL_TASKS)
    xs, zs = np.meshgrid(np.linspace(-0.1, 0.5, 31), np.linspace(-0.2, 0.2, 5))
    for task, name in ENV_TASKS.items():
        where = get_task(name).environment("tripod", "hard")
        env = gym.make(TASK_IDS_BY_TASK[task]["tripod"], difficulty="hard")
        base = env.unwrapped
        assert where.get("incline_deg", 0.0) == base.incline_deg, task
        ground = base.robot.ground
        if "ground" in where:        # the same field as the environment's (the rough terrain's of seed 0)
            if task == "rough_terrain":
                env.close()
                ground = gym.make(TASK_IDS_BY_TASK[task]["tripod"], difficulty="hard", terrain_seed=0).unwrapped.robot.ground
            np.testing.assert_array_equal(where["ground"].height(xs, zs), ground.height(xs, zs), err_msg=task)
        elif "box" in where:         # the task's box, as the environment adds it
            assert where["box"] == base.box and (ground is None or ground.is_flat), task
        else:
            assert ground is None or ground.is_flat, task
        env.close()
    with pytest.raises(ValueError, match="difficulty must be one of 'easy', 'medium', 'hard', got 'extreme'"):
        get_task("climb_step").environment("tripod", "extreme")


def test_each_task_s_score_is_what_its_documentation_says():
    L, dt, K = 0.14, 0.033, 300
    base = SimpleNamespace(robot=SimpleNamespace(body_length=L), dt=dt,
                           locomotion_task=SimpleNamespace(heading=np.array([1.0, 0.0, 0.0]), turn_direction="left"))
    com = np.zeros((K + 1, 3))
    com[-1, 0] = L                                   # one body length along +x over 10 s
    rec = {"com": com, "yaw": np.linspace(0.0, -3 * np.pi / 4, K + 1) % (2 * np.pi) - np.pi,   # wraps around
           "goal_distance": np.linspace(1.0, 0.5, K + 1) * L, "box_x": np.linspace(0.01, 0.01 + 0.25 * L, K + 1)}
    assert _episode_score("walk", base, rec, K) == pytest.approx(60.0 / (K * dt))            # BL/min
    assert _episode_score("rough_terrain", base, rec, K) == pytest.approx(60.0 / (K * dt))
    assert _episode_score("climb_step", base, rec, K) == pytest.approx(1.0)                  # BL
    assert _episode_score("reach_goal", base, rec, K) == pytest.approx(0.5)                  # BL gained
    assert _episode_score("turn", base, rec, K) == pytest.approx(135.0)                      # deg, to the left
    assert _episode_score("carry", base, rec, K) == pytest.approx(60.0 / (K * dt))           # BL/min, as walk
    assert _episode_score("push_box", base, rec, K) == pytest.approx(0.25)                   # the box's BL
    assert {s.unit for s in SCORES.values()} == {"BL/min", "deg", "BL"}


def test_rl_takes_a_task_id_and_refuses_what_does_not_fit(tmp_path):
    from trajopt.rl.envs import env_id, make_env, rl_target, robot_name, task_of
    assert robot_name("SoftPuppyCrossTrench-v0") == "puppy" and task_of("SoftPuppyCrossTrench-v0") == "cross_trench"
    assert env_id("SoftPuppyCrossTrench-v0") == "SoftPuppyCrossTrench-v0" and env_id("puppy") == "SoftPuppy-v2"
    env = make_env("SoftTripodReachGoal-v0", max_episode_steps=300, env_kwargs={"difficulty": "easy"})
    assert env.unwrapped.difficulty == "easy" and "goal_offset" in env.unwrapped.observation_structure
    env.close()
    import argparse
    with pytest.raises(argparse.ArgumentTypeError, match=rf"or a task id {sorted(TASK_ENV_IDS)[0]} \.\.\.\), got 'SoftTripodWalk-v9'"):
        rl_target("SoftTripodWalk-v9")
    from trajopt.rl.options import train_with_options
    with pytest.raises(ValueError, match="--difficulty applies to a task id .*, not to 'tripod'"):
        train_with_options("tripod", difficulty="easy", out=tmp_path)
    from trajopt.sweep import load_spec
    spec = tmp_path / "s.toml"
    spec.write_text('[[runs]]\nkind = "evaluate"\nname = "e"\ntask_score = true\n[runs.args]\nresult = "x.npz"\n')
    with pytest.raises(ValueError, match=r"s.toml: runs\[0\].task_score must be true or false and applies to kinds "
                                         "'rl-train' and 'optimize' only"):
        load_spec(spec)
    spec.write_text('[[runs]]\nkind = "rl-train"\nname = "r"\n[runs.args]\nrobot = "SoftTripodWalk-v0"\n'
                    'difficulty = "extreme"\n')
    with pytest.raises(ValueError, match="argument difficulty: difficulty must be one of"):
        load_spec(spec)


def test_difficulty_is_refused_for_a_task_that_is_no_benchmark_task(tmp_path):
    from trajopt.optimize_run import OptimizeRun, run_optimization
    with pytest.raises(ValueError, match="--difficulty applies to the benchmark's tasks .*, not to --task incline"):
        run_optimization(OptimizeRun("tripod", task="incline", difficulty="easy", out=tmp_path, quiet=True))


def test_heading_is_refused_where_the_task_s_ground_and_score_lie_along_x(tmp_path):
    from trajopt.optimize_run import OptimizeRun, run_optimization
    for task in ("slope_up", "rough_terrain", "climb_step"):
        with pytest.raises(ValueError, match=rf"--heading applies to the walk, the turn and reach_goal, not to "
                                             rf"--task {task}: its slope, step, trench or terrain lies along \+x"):
            run_optimization(OptimizeRun("tripod", task=task, heading=30.0, out=tmp_path, quiet=True))
    assert not any(tmp_path.iterdir())                                    # refused before anything is written



    doc = tomllib.loads((ROOT / "examples" / "suite.toml").read_text())
    rl = [b for b in doc["runs"] if b["kind"] == "rl-train"]
    assert sorted(b["args"]["algo"] for b in rl) == sorted(ALGOS)
    for b in rl:
        assert b["args"]["timesteps"] == SUITE_TIMESTEPS and b["args"]["n_envs"] == SUITE_N_ENVS
        assert sorted(b["grid"]["robot"]) == sorted(SUITE_IDS) and b["grid"]["seed"] == [0, 1, 2]
    opt = [b for b in doc["runs"] if b["kind"] == "optimize"]
    medium = [b for b in opt if b.get("args", {}).get("difficulty") == "medium"]
    assert len(medium) == 1 and set(medium[0]["grid"]["task"]) == set(ENV_TASKS.values())
    levels = [b for b in opt if "difficulty" in b["grid"]]         # every task at its other levels
    assert len(levels) == 1 and set(levels[0]["grid"]["task"]) == set(ENV_TASKS.values())
    assert levels[0]["grid"]["difficulty"] == ["easy", "hard"] and "{difficulty}" in levels[0]["name"]
    fastest = [b for b in opt if "speed" in b.get("args", {})]     # RL's like-for-like baseline on the walk
    assert len(fastest) == 1 and fastest[0]["args"] == {"task": "walk", "speed": "max"}
    assert fastest[0]["grid"]["robot"] == ["tripod", "puppy"]
    assert all(b.get("task_score") for b in doc["runs"])


def test_the_renderer_draws_a_relief_and_a_goal():
    from soft_envs.render import Renderer
    from soft_envs.sim import HeightField, load_robot
    robot = load_robot("tripod")
    r = Renderer(robot.mesh.surface, width=160, height=120, body_length=robot.body_length, legend=False,
                 scale_bar=False)
    x = robot.mesh.points
    flat = r.render(x)
    step = r.render(x, ground=HeightField.step(height=0.02, position=0.15, width=0.01))
    goal = r.render(x, goal=[0.1, 0.0, 0.05])
    assert (flat != step).any() and (flat != goal).any()


def test_the_docs_get_each_task_s_rows_of_the_main_table_not_of_the_levels(tmp_path):
    """bench_suite.update_docs copies each task's rows of the task x robot x method table into its
    block of docs/tasks.md; the Levels table's rows (same first cells, fewer columns) stay out."""
    spec = importlib.util.spec_from_file_location("bench_suite", ROOT / "benchmarks" / "bench_suite.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    docs = tmp_path / "tasks.md"
    docs.write_text("".join(f"# {t}\n<!-- baselines {t} -->\nstale row\n<!-- /baselines {t} -->\n" for t in TASKS))
    main_row = "| walk | Tripod | PPO | +17.00 ± 0.30 BL/min | +16.80 (3/3) | – | 3/3 | 30,720 | 300 s |"
    level_row = "| walk | Tripod | +7.58 ± 0.01 BL/min | +7.55 ± 0.04 BL/min | +7.49 ± 0.02 BL/min |"
    bench.update_docs("\n".join([main_row, level_row]), docs)
    text = docs.read_text()
    assert main_row in text and level_row not in text and "stale row" not in text
    assert text.count(bench.TABLE_HEAD[0]) == len(TASKS)


@pytest.mark.rl
def test_the_quick_suite_trains_every_id_and_its_report_has_every_row(tmp_path):
    """benchmarks/bench_suite.py --quick: PPO a few hundred steps on each of the 20 ids, SAC on two,
    trajopt on the step, each scored on its id; the report lists task x robot x method, the runs not
    made as "not run", each id's steps per second and a picture of each task."""
    pytest.importorskip("stable_baselines3")
    spec = importlib.util.spec_from_file_location("bench_suite", ROOT / "benchmarks" / "bench_suite.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    text = bench.main(["--quick", "--serial", "--sweep-dir", str(tmp_path)])
    rows = [line.split(" | ") for line in text.splitlines() if line.startswith("| ") and " | Tripod | " in line
            or line.startswith("| ") and " | Puppy | " in line]
    levels = [r for r in rows if len(r) == 5]                      # task, robot, easy, medium, hard
    rows = [r for r in rows if len(r) == 9]                        # the table of task x robot x method
    assert len(levels) == len(TASKS) * 2 and all(r[2] == "not run" and r[4] == "not run |" for r in levels)
    step = next(r for r in levels if r[0] == "| climb_step" and r[1] == "Tripod")
    assert step[3].endswith("%)") and "BL" in step[3]                # the medium run, with its success rate
    assert len(rows) == len(TASKS) * 2 * 3 + 2                             # and the walk's --speed max rows
    assert [r[2] for r in rows if r[0] == "| walk"] == ["trajopt (open loop)", "trajopt `--speed max` (open loop)",
                                                        "PPO", "SAC"] * 2
    for task in TASKS:
        for robot in ("Tripod", "Puppy"):
            ppo = next(r for r in rows if r[0] == f"| {task}" and r[1] == robot and r[2] == "PPO")
            assert ppo[3].endswith(SCORES[task].unit) and "±" in ppo[3] and ppo[6] == "1/3", ppo
            assert ppo[4] == "–", ppo                                    # not replayed in the quick mode
    replayed = [r for r in rows if r[4] != "–"]                       # bench.QUICK_HOLDS: the SAC walk, the trajopt step
    assert [(r[0], r[1], r[2]) for r in replayed] == [("| walk", "Tripod", "SAC"),
                                                      ("| climb_step", "Tripod", "trajopt (open loop)")], replayed
    assert all(r[4].endswith("/1)") for r in replayed), replayed
    summary = text.split("## Which scores hold")[1].split("\n## ")[0]
    assert "| trajopt (open loop) | 1 | " in summary and "| SAC | 1 | " in summary and "| PPO |" not in summary
    import json
    hold = json.loads((tmp_path / "SoftTripodWalk-v0_sac_seed0" / bench.HOLD_NAME).read_text())
    assert hold["substeps"] == [2, 4, 8, 16] and hold["own_substeps"] == 4 and len(hold["scores"]) == 4
    step = next(r for r in rows if r[0] == "| climb_step" and r[1] == "Tripod" and r[2].startswith("trajopt"))
    assert step[3].endswith("BL") and "±" in step[3]
    assert sum(r[3] == "not run" for r in rows) == len(TASKS) * 2 * 3 + 2 - len(SUITE_IDS) - 2 - 1
    assert all(f"`{i}`" in text for i in SUITE_IDS)                    # steps per second of every id
    assert all((tmp_path / "images" / f"{t}.png").is_file() for t in TASKS)
    assert "--only 'SoftPuppyWalk-v0_sac_seed*'" in text
    from trajopt.replay import env_for_result
    from trajopt.results.result import Result
    res = Result.load(tmp_path / "tripod_climb_step_trajopt" / "tripod_climb_step_trajopt.npz")
    assert res.settings["env_task"] == "climb_step" and env_for_result(res).robot.ground is not None


def test_a_task_score_s_hold_is_the_headline_s_protocol():
    """trajopt.tasks.play.task_hold: the evaluation at half, twice and four times the physics steps,
    the lowest score the credible one, NaN where a simulation failed, and holds within 5 %."""
    from trajopt.tasks.play import task_hold

    def ev(score, end="truncated", substeps=4, level="medium"):
        return {"score": score, "score_name": "speed", "score_unit": "BL/min", "control_dt_s": 0.033,
                "substeps": substeps, "env_id": "SoftTripodWalk-v0", "difficulty": level,
                "episodes": [{"score": score, "end": "truncated"}, {"score": score, "end": end}]}

    asked = []

    def evaluate(n, scores={2: 19.8, 8: 20.3, 16: 20.5}):
        asked.append(n)
        return ev(scores[n], substeps=n)

    out = task_hold(evaluate, ev(20.0))
    assert asked == [2, 8, 16] and out["substeps"] == [2, 4, 8, 16] and out["own_substeps"] == 4
    assert out["physics_dt_ms"] == pytest.approx([16.5, 8.25, 4.125, 2.0625])
    assert out["scores"] == [19.8, 20.0, 20.3, 20.5] and out["slowest"] == 19.8
    assert out["spread"] == pytest.approx(0.7 / 19.8) and out["holds"] and out["episodes"] == 2
    assert not task_hold(lambda n: ev(25.0), ev(20.0))["holds"]                    # 25 % apart
    assert not task_hold(lambda n: ev(-1.0), ev(-1.0))["holds"]                    # backwards: spread 0
    failed = task_hold(lambda n: ev(20.0, end="sim_failure") if n == 16 else ev(20.0), ev(20.0))
    assert np.isnan(failed["scores"][-1]) and np.isnan(failed["slowest"]) and not failed["holds"]
    failed = task_hold(lambda n: ev(20.0), ev(21.0, end="sim_failure"))
    assert np.isnan(failed["scores"][1]) and failed["own_score"] == 21.0     # what the run's own score was
    assert task_hold(evaluate, ev(20.0, substeps=1), factors=(0.5, 2.0))["substeps"] == [1, 2]   # no half step of one
    with pytest.raises(ValueError, match=r"factors \(0.5,\) of 1 physics steps per control step give no other whole"):
        task_hold(evaluate, ev(20.0, substeps=1), factors=(0.5,))
    with pytest.raises(ValueError, match="the replay with 2 physics steps is on difficulty 'hard', the evaluation it "
                                         "is compared with on 'medium'"):
        task_hold(lambda n: ev(20.0, level="hard"), ev(20.0))


@pytest.mark.parametrize("substeps", [0, 2.5, True, "4", float("nan"), float("inf"), np.int64(-2)])
def test_a_task_score_at_other_physics_steps_refuses_what_is_no_step_count(substeps):
    from trajopt.tasks.play import gait_on_task, policy_on_task
    for play in (gait_on_task, policy_on_task):
        with pytest.raises(ValueError, match=re.escape(f"substeps must be a whole number >= 1, got {substeps!r}")):
            play("no such run", substeps=substeps)


def test_a_numpy_step_count_is_a_step_count():
    from trajopt.tasks.play import _check_substeps
    for ok in (None, 1, 8, 4.0, np.int64(4)):
        _check_substeps(ok)


@pytest.mark.rl
def test_rl_evaluate_task_scores_a_task_run_and_replays_it(tmp_path, monkeypatch, capsys):
    """``trajopt rl evaluate RUN --task [--fidelity]``: a run trained on a task id gets its task's
    score on the id (as the suite scores it), with --fidelity at 16.5, 4.125 and 2.06 ms; a run
    trained on a robot is refused with what to do instead."""
    pytest.importorskip("stable_baselines3")
    import json
    from trajopt.cli import main
    from trajopt.rl import train
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")                 # one evaluation episode
    hp = dict(n_steps=32, batch_size=32, n_epochs=1)
    run = train("SoftTripodPushBox-v0", "ppo", 32, seed=0, out=tmp_path, n_envs=1, vec_env="dummy", hyperparams=hp,
                max_episode_steps=300, progress_bar=False)
    assert main(["rl", "evaluate", str(run.run_dir), "--task", "--fidelity", "--json"]) == 0
    ev = json.loads(capsys.readouterr().out)
    assert ev["task"] == "push_box" and ev["score_unit"] == "BL" and len(ev["episodes"]) == 1
    hold = ev["hold"]
    assert ev["substeps"] == 4 and ev["control_dt_s"] == pytest.approx(0.033)
    assert hold["substeps"] == [2, 4, 8, 16] and hold["physics_dt_ms"] == pytest.approx([16.5, 8.25, 4.125, 2.0625])
    assert np.isfinite(hold["scores"]).all() and hold["slowest"] == min(hold["scores"])
    from trajopt.tasks.play import policy_on_task
    assert policy_on_task(run.run_dir, substeps=2)["substeps"] == 2            # the replays' physics is theirs
    assert main(["rl", "evaluate", str(run.run_dir), "--task"]) == 0
    text = capsys.readouterr().out
    assert f"pushed       {ev['score']:+.3f} BL (the task's score, mean of 1 episodes)" in text   # deterministic
    from trajopt.cli.commands import task_hold_text
    text = task_hold_text({**hold, "scores": [0.5, 0.51, float("nan"), 0.52], "slowest": float("nan"),
                           "holds": False}, 33.0)
    lines = text.splitlines()
    assert lines[2].split() == ["16.500", "ms", "+0.500", "BL"] and lines[3].split() == ["8.250", "ms", "(its", "own)", "+0.510", "BL"]
    assert lines[4].split() == ["4.125", "ms", "failed"] and lines[-1] == "  a simulation failed: does not hold"
    assert main(["rl", "evaluate", str(run.run_dir), "--task", "--seed", "3"]) == 2
    assert "--task scores the task's own episodes: --seed does not apply" in capsys.readouterr().err
    walk = train("tripod", "ppo", 32, seed=0, out=tmp_path, n_envs=1, vec_env="dummy", hyperparams=hp,
                 progress_bar=False)
    assert main(["rl", "evaluate", str(walk.run_dir), "--task"]) == 2
    assert "was trained on 'SoftTripod-v2', not on a task id" in capsys.readouterr().err


def test_the_rl_zoo_files_are_the_baseline_s_hyperparameters(tmp_path):
    from trajopt.rl.zoo import ZOO_DIR, write_zoo_files, zoo_ids, zoo_text
    for algo in ALGOS:
        assert (ZOO_DIR / f"{algo}.yml").read_text() == zoo_text(algo), "python -m trajopt.rl.zoo"
    assert len(zoo_ids()) == len(TASK_ENV_IDS) + len(soft_envs.LATEST_ENV_IDS)
    assert [p.read_text() for p in write_zoo_files(tmp_path)] == [zoo_text(a) for a in ALGOS]


@pytest.mark.parametrize("algo", ALGOS)
def test_rl_zoo3_loads_every_id_with_its_own_loader(algo, tmp_path):
    pytest.importorskip("rl_zoo3", reason="rl_zoo3 is the optional 'zoo' extra (pip install -e .[zoo])")
    import argparse
    from rl_zoo3.exp_manager import ExperimentManager
    from trajopt.rl.envs import DropHorizontalPosition
    from trajopt.rl.zoo import ZOO_DIR, zoo_ids
    from trajopt.rl.training import sb3_keywords
    from trajopt.rl.tuning.tuned import task_hyperparams
    for env_id in zoo_ids():
        # what trajopt rl train uses on the id: the robot's tuned values on a task id, where adopted
        want = sb3_keywords(task_hyperparams(algo, env_id, n_envs=SUITE_N_ENVS, timesteps=SUITE_TIMESTEPS)[0])
        em = ExperimentManager(argparse.Namespace(), algo, env_id, str(tmp_path), config=str(ZOO_DIR / f"{algo}.yml"),
                               verbose=0)
        hp, _ = em.read_hyperparameters()
        hp, wrapper, _, _ = em._preprocess_hyperparams(hp)
        assert em.n_envs == SUITE_N_ENVS and em.n_timesteps == SUITE_TIMESTEPS, env_id
        assert em.normalize and em.normalize_kwargs == vecnormalize_kwargs(algo, want["gamma"]), env_id
        assert wrapper(gym.make("SoftTripod-v2")).__class__ is DropHorizontalPosition
        assert hp.pop("policy_kwargs") == want["policy_kwargs"] and hp.pop("policy") == "MlpPolicy"
        lr = hp.pop("learning_rate")
        assert lr(1.0) == want["learning_rate"], env_id               # rl_zoo3 makes it a schedule
        if "clip_range" in hp:
            assert hp.pop("clip_range")(1.0) == want["clip_range"]
        assert hp == {k: v for k, v in want.items() if k not in ("policy_kwargs", "learning_rate", "clip_range")}
        assert (em.env_kwargs == {}) == (env_id in TASK_ENV_IDS), env_id


def test_docs_show_each_task_s_picture_and_its_rows_of_the_report():
    """docs/tasks.md's rows under each task are benchmarks/results/suite.md's (bench_suite.py
    writes both), and the pictures it links exist."""
    spec = importlib.util.spec_from_file_location("bench_suite", ROOT / "benchmarks" / "bench_suite.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    width = bench.TABLE_HEAD[0].count("|")
    report = (ROOT / "benchmarks" / "results" / "suite.md").read_text().splitlines()
    docs = (ROOT / "docs" / "tasks.md").read_text()
    for task in TASKS:
        block = docs.split(f"<!-- baselines {task} -->")[1].split(f"<!-- /baselines {task} -->")[0]
        rows = [line for line in block.splitlines() if line.startswith(f"| {task} | ")]
        main = [line for line in report if line.startswith(f"| {task} | ") and line.count("|") == width]   # not the Levels'
        assert rows and rows == main, task
        assert f"](../benchmarks/results/suite/{task}.png)" in docs
        assert (ROOT / "benchmarks" / "results" / "suite" / f"{task}.png").is_file()


def _bench():
    spec = importlib.util.spec_from_file_location("bench_suite", ROOT / "benchmarks" / "bench_suite.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def _fake_run(folder, run, score, *, episodes=(1.0, 2.0, 3.0), hold=None, finished=1.0e9, params=None):
    """A run's folder as the sweep leaves it (status.json, task_score.json, task_hold.json)."""
    import json
    folder.mkdir(parents=True)
    task = {"task": "walk", "score": score, "score_unit": "BL/min", "score_name": "speed", "success_rate": 0.0}
    (folder / "status.json").write_text(json.dumps({
        "status": "done", "kind": run.kind, "params": run.params if params is None else params,
        "metrics": {"task": task, "sim_steps": 6000}, "wall_time_s": 40.0, "finished": finished}))
    (folder / "task_score.json").write_text(json.dumps({**task, "episodes": [{"score": e} for e in episodes]}))
    if hold is not None:
        (folder / "task_hold.json").write_text(json.dumps({**hold, "own_score": score}))


def test_the_suite_ledger_keeps_each_run_and_a_run_made_here_replaces_its_record(tmp_path):
    """benchmarks/suite_ledger.py: the report is made from the ledger's records where the sweep
    folder has no run (a new machine), a run in the folder replaces its record unless the record is
    of a run finished later (and the aggregate of its row once all the row's runs are made again:
    until then the row keeps it), a record or a folder of other arguments is not used, and the
    ledger written reads back."""
    bench = _bench()
    ledger_mod = bench.suite_ledger
    from trajopt.sweep import load_spec
    spec = load_spec(bench.SPEC, tmp_path)
    name = "tripod_walk_trajopt"
    run = next(r for r in spec.runs if r.name == name)
    group = bench.group_of(run)
    assert group == ("walk", "tripod", "trajopt")
    hold = {"slowest": 7.4, "spread": 0.02, "holds": True, "scores": [7.4, 7.5, 7.5, 7.5], "substeps": [2, 4, 8, 16],
            "own_substeps": 4}
    _fake_run(tmp_path / "made_elsewhere" / name, run, 7.5, hold=hold)
    groups, local = bench.collect(spec, tmp_path / "made_elsewhere")
    rec = local[name]
    assert rec["score"] == 7.5 and rec["episode_std"] == 1.0 and rec["hold"] == {"slowest": 7.4, "spread": 0.02,
                                                                                  "holds": True}
    assert rec["finished"] == 1.0e9 and rec["made"] == time.strftime("%Y-%m-%d", time.localtime(1.0e9))
    ledger, said = ledger_mod.update(ledger_mod.empty(), local)
    assert said == []
    path = tmp_path / "suite_runs.json"
    with ledger_mod.locked(path):
        ledger_mod.save(path, ledger)
    ledger = ledger_mod.load(path)
    # a new machine: no run in its folder, the row from the ledger; the sweep would not make it again
    groups, local = bench.collect(spec, tmp_path / "empty", ledger)
    c = bench.cell(groups[group])
    assert not local and c["mean"] == 7.5 and c["std"] == 1.0 and c["credible"] == 7.4 and c["hold"] == 1
    assert c["n"] == 1 and c["spreads"] == [0.02] and c["aggregate"] is None
    assert bench.kept_runs(spec, tmp_path / "empty", ledger) == {name}
    # the run made again here replaces the record
    _fake_run(tmp_path / "here" / name, run, 8.0, episodes=(8.0, 8.0, 8.0), finished=2.0e9)
    groups, local = bench.collect(spec, tmp_path / "here", ledger)
    c = bench.cell(groups[group])
    assert c["mean"] == 8.0 and c["std"] == 0.0 and c["replayed"] == 0 and set(local) == {name}
    assert bench.kept_runs(spec, tmp_path / "here", ledger) == set()         # the folder's run is the sweep's
    newer, said = ledger_mod.update(ledger, local)
    assert newer["runs"][name]["score"] == 8.0 and said == [f"{name}: its record replaced by the run in the sweep "
                                                            "folder (+7.5 -> +8 BL/min)"]
    # ... but an older run in a folder does not replace a record made again elsewhere since
    _fake_run(tmp_path / "old" / name, run, 6.0, finished=1.0)
    groups, local = bench.collect(spec, tmp_path / "old", ledger)
    assert bench.cell(groups[group])["mean"] == 7.5
    kept, said = ledger_mod.update(ledger, local)
    assert kept["runs"][name]["score"] == 7.5 and "is newer than the run in the sweep folder" in said[0]
    # a folder made with other arguments is not the run's
    _fake_run(tmp_path / "other" / name, run, 1.0, params={**run.params, "iterations": 1})
    groups, local = bench.collect(spec, tmp_path / "other", ledger)
    assert not local and bench.cell(groups[group])["mean"] == 7.5 and "made with other arguments" in \
        groups[group]["failed"][0]
    # a record made with other arguments than the sweep file's is not the run's
    ledger["runs"][name]["params"] = {**ledger["runs"][name]["params"], "iterations": 99}
    groups, _ = bench.collect(spec, tmp_path / "empty", ledger)
    assert bench.cell(groups[group]) is None and bench.kept_runs(spec, tmp_path / "empty", ledger) == set()
    # an aggregate stands for its row until every run of the row has a record
    ppo = [r for r in spec.runs if bench.group_of(r) == ("walk", "puppy", "ppo")]
    agg = {"task": "walk", "robot": "puppy", "method": "ppo", "n": 3, "mean": 18.0, "std": 4.0, "credible": 17.0,
           "replayed": 3, "hold": 1, "success": 0.0, "sim_steps": 30720.0, "wall": 245.0, "score_unit": "BL/min",
           "score_name": "speed", "rl": None, "runs": {r.name: ledger_mod.jsonable(r.params) for r in ppo},
           "from": "an older report"}
    ledger["aggregates"]["walk/puppy/ppo"] = agg
    groups, _ = bench.collect(spec, tmp_path / "empty", ledger)
    c = bench.cell(groups[("walk", "puppy", "ppo")])
    assert (c["mean"], c["n"], c["credible"], c["hold"], c["aggregate"]) == (18.0, 3, 17.0, 1, "an older report")
    assert c["no_spread"] == 3 and {r.name for r in ppo} <= bench.kept_runs(spec, tmp_path / "empty", ledger)
    records = {r.name: {**ledger["runs"][name], "robot": "puppy", "method": "ppo", "kind": r.kind,
                        "params": ledger_mod.jsonable(r.params), "score": 20.0 + i} for i, r in enumerate(ppo)}
    first = {ppo[0].name: records[ppo[0].name]}
    after, _ = ledger_mod.update(ledger, first)           # one of three made again: the row keeps its aggregate
    assert after["aggregates"]["walk/puppy/ppo"] == agg and after["runs"][ppo[0].name]["score"] == 20.0
    groups, _ = bench.collect(spec, tmp_path / "empty", after)
    g = groups[("walk", "puppy", "ppo")]
    assert bench.cell(g)["mean"] == 18.0 and bench.cell(g)["aggregate"] and g["again"] == [ppo[0].name]
    # a record of one of its runs made with other arguments does not count
    odd = {r.name: {**records[r.name], "params": {**records[r.name]["params"], "seed": 99}} for r in ppo[1:]}
    assert ledger_mod.update(after, odd)[0]["aggregates"]["walk/puppy/ppo"] == agg
    after, _ = ledger_mod.update(after, {r.name: records[r.name] for r in ppo[1:]})       # the last ones
    assert "walk/puppy/ppo" not in after["aggregates"] and "walk/puppy/ppo" in ledger["aggregates"]  # a new ledger
    groups, _ = bench.collect(spec, tmp_path / "empty", after)
    c = bench.cell(groups[("walk", "puppy", "ppo")])
    assert c["n"] == 3 and c["mean"] == 21.0 and not c["aggregate"] and groups[("walk", "puppy", "ppo")]["again"] == []


@pytest.mark.parametrize("text, match", [
    ("{", "not a readable JSON file"),
    ('{"version": 0, "runs": {}, "aggregates": {}}', "not a suite ledger of version 1"),
    ('{"version": 1, "runs": [], "aggregates": {}}', "'runs' must be a table of records"),
    ('{"version": 1, "runs": {"r": {"task": "walk"}}, "aggregates": {}}', r"runs\['r'\] lacks the field\(s\) robot"),
])
def test_a_bad_suite_ledger_is_an_error_naming_the_file_and_the_record(tmp_path, text, match):
    bench = _bench()
    path = tmp_path / "suite_runs.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"{re.escape(str(path))}: .*{match}"):
        bench.suite_ledger.load(path)


@pytest.mark.parametrize("section, field, value, match", [
    ("runs", "score", "fast", r"runs\['r'\].score must be a number, got 'fast'"),
    ("runs", "score", None, r"runs\['r'\].score must be a number, got None"),
    ("runs", "sim_steps", "many", r"runs\['r'\].sim_steps must be a number or null, got 'many'"),
    ("runs", "hold", {"slowest": "x", "spread": None, "holds": True}, r"runs\['r'\].hold must be null or a table"),
    ("runs", "rl", {"algo": "ppo", "n_envs": None}, r"runs\['r'\].rl.n_envs must be a int, got None"),
    ("runs", "params", [], r"runs\['r'\]: kind must be a text and params a table"),
    ("aggregates", "n", "3", r"aggregates\['r'\].n must be a whole number >= 0, got '3'"),
    ("aggregates", "replayed", 4, r"aggregates\['r'\]: hold <= replayed <= n"),
    ("aggregates", "runs", ["a"], r"aggregates\['r'\].runs must be a table of run names to their params"),
])
def test_a_ledger_record_s_fields_are_checked(tmp_path, section, field, value, match):
    """A ledger's record whose field is of the wrong kind is refused on load (naming the file, the
    record and the field) and is never written."""
    import json
    bench = _bench()
    lm = bench.suite_ledger
    good = {"runs": {"task": "walk", "robot": "tripod", "method": "ppo", "kind": "rl-train", "params": {},
                     "score": 1.0, "episode_std": 0.0, "success_rate": 0.0, "score_unit": "BL/min",
                     "score_name": "speed", "sim_steps": None, "wall_time_s": None, "hold": None, "rl": None,
                     "finished": None, "made": None, "machine": "m"},
            "aggregates": {"task": "walk", "robot": "tripod", "method": "ppo", "n": 3, "mean": 1.0, "std": 0.0,
                           "credible": None, "replayed": 0, "hold": 0, "success": 0.0, "sim_steps": None,
                           "wall": None, "score_unit": "BL/min", "score_name": "speed", "rl": None, "runs": {},
                           "from": "x"}}
    ledger = lm.empty()
    ledger[section]["r"] = good[section]
    path = tmp_path / "suite_runs.json"
    lm.save(path, ledger)
    assert lm.load(path) == ledger                                           # the good record reads back
    ledger[section]["r"] = {**good[section], field: value}
    path.write_text(json.dumps(ledger))
    with pytest.raises(ValueError, match=f"{re.escape(str(path))}: {match}"):
        lm.load(path)
    with pytest.raises(ValueError, match=match):
        lm.save(tmp_path / "other.json", ledger)
    assert not (tmp_path / "other.json").exists()


def test_the_shipped_ledger_makes_the_shipped_report_s_rows():
    """benchmarks/results/suite_runs.json (the ledger) and benchmarks/results/suite.md were written
    together: the report's main rows are the ledger's, made again without any run folder."""
    bench = _bench()
    from trajopt.sweep import load_spec
    spec = load_spec(bench.SPEC, ROOT / "no such folder")
    groups, _ = bench.collect(spec, ROOT / "no such folder", bench.suite_ledger.load(bench.LEDGER))
    report = (ROOT / "benchmarks" / "results" / "suite.md").read_text()
    for (task, robot, method), g in groups.items():
        if method not in bench.METHODS:
            continue
        c = bench.cell(g)
        row = next(line for line in report.splitlines()
                   if line.startswith(f"| {task} | {robot.capitalize()} | {bench.METHODS[method]}"))
        cells = row.split(" | ")
        assert cells[3] == (f"{bench._fmt(c)} {SCORES[task].unit}" if c else "not run"), row
        assert cells[4] == bench._fmt_credible(c), row
