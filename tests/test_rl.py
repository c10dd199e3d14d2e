"""RL baseline (trajopt.rl): smoke training of PPO and SAC on both robots, save / reload /
evaluate with trajopt's metric, determinism of the evaluation, export as a trajopt Result
whose controls replay to the evaluated COM displacement, and the ``trajopt rl`` command line.

Fast by construction: tiny networks, one environment (DummyVecEnv), a few hundred steps, and
evaluations over 1 gait cycle (24 + 72 simulation steps) instead of 6.
"""
from __future__ import annotations

import math
import sys

import gymnasium as gym
import numpy as np
import pytest

import soft_envs  # noqa: F401  (registers the ids)
from trajopt.cli import main
from trajopt.results.result import Result

pytestmark = pytest.mark.rl
pytest.importorskip("stable_baselines3")

from trajopt.rl.evaluate import LoadedPolicy  # noqa: E402

ROBOTS = ["tripod", "puppy"]
ALGOS = ["ppo", "sac"]
TINY = {"ppo": {"n_steps": 64, "batch_size": 32, "n_epochs": 2, "policy_kwargs": {"net_arch": [16, 16]}},
        "sac": {"learning_starts": 64, "batch_size": 32, "policy_kwargs": {"net_arch": [16, 16]}}}
STEPS = {"ppo": 192, "sac": 160}
CYCLES = 1


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One tiny training per (robot, algo), shared by the tests of this module."""
    from trajopt.rl import train
    out = tmp_path_factory.mktemp("rl_runs")
    done = {}
    for robot in ROBOTS:
        for algo in ALGOS:
            done[robot, algo] = train(robot, algo, STEPS[algo], seed=0, out=out, n_envs=1, vec_env="dummy",
                                      hyperparams=TINY[algo], checkpoint_every=STEPS[algo] // 2,
                                      progress_bar=False)
    return done


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("algo", ALGOS)
def test_train_save_reload_evaluate(runs, robot, algo):
    from trajopt.rl.evaluate import evaluate_policy_metric, load_policy
    run = runs[robot, algo]
    assert run.status == "done" and run.timesteps >= STEPS[algo] and run.sim_steps == run.timesteps
    for name in ("model.zip", "vecnormalize.pkl", "rl_config.json"):
        assert (run.run_dir / name).is_file()
    assert (run.run_dir / "logs" / "progress.csv").is_file()
    assert list((run.run_dir / "logs").glob("events.out.tfevents.*")), "no TensorBoard log"
    steps = sorted(int(p.stem.split("_")[-2]) for p in run.checkpoints)
    assert steps[0] == 0 and len(steps) >= 2
    assert run.config["hyperparams"]["policy_kwargs"]["net_arch"] == [16, 16]
    policy = load_policy(run.run_dir)
    assert policy.algo == algo and policy.robot == robot and policy.vecnormalize is not None
    ev = evaluate_policy_metric(policy, n_cycles=CYCLES)
    assert ev["sim_steps"] == 24 + 72 * CYCLES and ev["cycles"] == CYCLES
    assert math.isfinite(ev["speed_bl_per_min"]) and isinstance(ev["upright"], bool)
    # a checkpoint loads too (with its own VecNormalize statistics)
    ck = load_policy(run.checkpoints[-1])
    assert ck.vecnormalize is not None


def test_a_policy_plays_closed_loop_at_finer_physics(runs, capsys):
    """The RL side of the fidelity protocol: the policy closed loop at its run's physics (the
    Coulomb law's 4 steps per control step) and at 2x finer steps, through the environment
    (``substeps``); its own row is the plain evaluation, the finer one a real replay on other
    physics (another step count, another trajectory), and ``trajopt rl evaluate --fidelity``
    prints the table."""
    from trajopt.rl.evaluate import evaluate_policy_metric, load_policy, policy_fidelity
    policy = load_policy(runs["tripod", "ppo"].run_dir)
    own = evaluate_policy_metric(policy, n_cycles=1)
    fid = policy_fidelity(policy, (0.5, 2), n_cycles=1)              # 16.5 ms (coarser) and 4.125 ms
    assert own["substeps"] == fid["substeps"] == 4
    assert [(r["factor"], r["substeps"]) for r in fid["rows"]] == [(1, 4), (0.5, 2), (2, 8)]
    assert fid["rows"][1]["speed_bl_per_min"] == evaluate_policy_metric(policy, n_cycles=1, substeps=2)["speed_bl_per_min"]
    assert fid["rows"][0]["speed_bl_per_min"] == own["speed_bl_per_min"]
    finer = evaluate_policy_metric(policy, n_cycles=1, substeps=8)
    assert finer["substeps"] == 8 and fid["rows"][2]["speed_bl_per_min"] == finer["speed_bl_per_min"]
    assert not np.allclose(finer["com"], own["com"], rtol=0, atol=1e-9)
    assert fid["rows"][2]["deviation"] == pytest.approx((finer["speed_bl_per_min"] - own["speed_bl_per_min"])
                                                        / abs(own["speed_bl_per_min"]))
    capsys.readouterr()
    main(["rl", "evaluate", str(runs["tripod", "ppo"].run_dir), "--cycles", "1", "--fidelity"])
    out = capsys.readouterr().out
    assert "finer physics steps" in out and "1.031 ms" in out and "spread" in out


def test_evaluate_is_deterministic(runs):
    from trajopt.rl.evaluate import evaluate_policy_metric, load_policy
    run = runs["tripod", "sac"]
    a = evaluate_policy_metric(load_policy(run.run_dir), n_cycles=CYCLES, seed=3)
    b = evaluate_policy_metric(load_policy(run.model_path), n_cycles=CYCLES, seed=3)
    assert a["speed_bl_per_min"] == b["speed_bl_per_min"] and a["com"] == b["com"]
    # with reset noise, the seed decides the start: same seed -> same number
    c = evaluate_policy_metric(run.run_dir, n_cycles=CYCLES, seed=5, reset_noise_scale=1e-4)
    d = evaluate_policy_metric(run.run_dir, n_cycles=CYCLES, seed=5, reset_noise_scale=1e-4)
    assert c["speed_bl_per_min"] == d["speed_bl_per_min"]


class PhaseGait(LoadedPolicy):
    """A loaded policy made to walk: the action follows the gait-phase observation (the last
    two entries, sin and cos), motors alternating. A freshly trained tiny policy barely moves,
    which would make the replay test below trivially true."""

    def act(self, obs):
        s, c = obs[-2], obs[-1]
        return np.array([s if m % 2 == 0 else c for m in range(self.model.action_space.shape[0])])


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("walker", [False, True], ids=["trained", "phase-gait"])
def test_export_replays_to_the_evaluated_displacement(runs, robot, walker, tmp_path):
    from trajopt.rl.evaluate import evaluate_policy_metric, export_result, load_policy
    run = runs[robot, "ppo"]
    policy = load_policy(run.run_dir)
    if walker:
        policy = PhaseGait(**vars(policy))
    ev = evaluate_policy_metric(policy, n_cycles=CYCLES)
    if walker:
        assert abs(ev["displacement_m"]) > 1e-3        # it moves (millimetres at least)
    res = export_result(policy, tmp_path / "rl_gait", n_cycles=CYCLES)
    loaded = Result.load(tmp_path / "rl_gait.npz")
    assert loaded.task == "rl" and loaded.robot == robot
    s = loaded.settings
    assert (s["n_prep"], s["n_cycle"], s["algo"], s["seed"]) == (24, 72, "ppo", 0)
    assert s["timesteps"] == run.timesteps
    assert loaded.u.shape == (24 + 72 * CYCLES, len(loaded.motor_names))
    np.testing.assert_array_equal(loaded.u, res.u)
    # the controls, replayed open loop from the reset state, reproduce the closed-loop run
    env = gym.make({"tripod": "SoftTripod-v2", "puppy": "SoftPuppy-v2"}[robot], reset_noise_scale=0.0)
    env.reset(seed=0)
    traj = env.unwrapped.rollout(loaded.u)
    disp = float(traj.com[-1, 0] - traj.com[24, 0])          # target direction +x
    assert disp == pytest.approx(ev["displacement_m"], abs=1e-5)     # Newton tolerance level
    np.testing.assert_allclose(traj.com, np.asarray(ev["com"]), atol=1e-5)
    assert loaded.evaluation["speed_bl_per_min"] == pytest.approx(ev["speed_bl_per_min"])
    # and trajopt's own evaluation of the exported file gives the same speed
    from trajopt.rl.evaluate import evaluate_trajopt_result
    again = evaluate_trajopt_result(loaded, n_cycles=CYCLES)
    assert again["speed_bl_per_min"] == pytest.approx(ev["speed_bl_per_min"], abs=1e-3)
    # the applied controls respect the motor bounds
    lo, hi = env.unwrapped.robot.u_bounds.T
    assert np.all(loaded.u >= lo - 1e-12) and np.all(loaded.u <= hi + 1e-12)


def test_applied_controls_as_actions_replay_in_env(runs):
    """control_to_action of the exported u, stepped through the env, is the same run."""
    from trajopt.rl.evaluate import export_result, play_controls_in_env
    res = export_result(runs["tripod", "sac"].run_dir, n_cycles=CYCLES)
    env = gym.make("SoftTripod-v2", reset_noise_scale=0.0, max_episode_steps=len(res.u))
    acts = env.unwrapped.control_to_action(res.u)
    rec = play_controls_in_env(env, lambda obs, k: acts[k], len(res.u), seed=0)
    np.testing.assert_allclose(rec["u"], res.u, atol=1e-12)
    np.testing.assert_allclose(rec["com"], res.com, atol=1e-5)


def test_cli_help_and_commands(runs, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["rl", "--help"])
    assert exc.value.code == 0
    assert "train" in capsys.readouterr().out
    for sub in ("train", "evaluate", "export"):
        with pytest.raises(SystemExit) as exc:
            main(["rl", sub, "--help"])
        assert exc.value.code == 0
    run = runs["tripod", "ppo"]
    code = main(["rl", "evaluate", str(run.run_dir), "--cycles", "1", "--json"])
    out = capsys.readouterr().out
    assert '"speed_bl_per_min"' in out and '"upright": true' in out
    assert code == 0                           # upright (1 would be: the robot fell)
    assert main(["rl", "export", str(run.run_dir), "--cycles", "1", "--out", str(tmp_path / "g.npz")]) == 0
    assert Result.load(tmp_path / "g.npz").task == "rl"


def test_cli_train_small(tmp_path):
    code = main(["rl", "train", "tripod", "--algo", "ppo", "--timesteps", "64", "--n-envs", "1",
                 "--out", str(tmp_path), "--name", "cli", "--no-progress",
                 "--hp", "n_steps=32", "--hp", "batch_size=32", "--hp", "n_epochs=1",
                 "--hp", "policy_kwargs=dict(net_arch=[8])"])
    assert code == 0 and (tmp_path / "cli" / "model.zip").is_file()


def test_cli_train_off_a_terminal_beats_and_ends_with_the_speed(tmp_path, capsys, monkeypatch):
    """Off a terminal (captured), ``rl train`` prints a plain line at least every heartbeat
    period (shortened here from 30 s) while it trains, no carriage return, and ends with the
    trained policy's speed in BL/min (#41)."""
    import trajopt.progress
    monkeypatch.setattr(trajopt.progress, "HEARTBEAT_S", 0.05)
    code = main(["rl", "train", "tripod", "--algo", "ppo", "--timesteps", "64", "--n-envs", "1",
                 "--out", str(tmp_path), "--name", "cli", "--hp", "n_steps=32", "--hp", "batch_size=32",
                 "--hp", "n_epochs=1", "--hp", "policy_kwargs=dict(net_arch=[8])"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err.startswith("rl train: PPO on tripod, 64 environment steps") and "\r" not in err
    assert "steps, still working" in err
    import re
    assert re.search(r"^  speed: +-?\d+\.\d\d BL/min along the target over 6 cycles \((upright|fell over);",
                     out, re.M), out


def test_hyperparameter_overrides_parse():
    from trajopt.rl.hyperparams import default_hyperparams, parse_overrides
    assert parse_overrides(["learning_rate=1e-3", "policy_kwargs=dict(net_arch=[32, 32])", "ent_coef=auto"]) == {
        "learning_rate": 1e-3, "policy_kwargs": {"net_arch": [32, 32]}, "ent_coef": "auto"}
    with pytest.raises(ValueError):
        parse_overrides(["no_equals_sign"])
    assert default_hyperparams("ppo", n_envs=2)["n_steps"] == 512
    assert default_hyperparams("sac", timesteps=500)["learning_starts"] == 100


def test_missing_sb3_says_how_to_install(monkeypatch, tmp_path, capsys):
    from trajopt.rl import MissingRLDependencies, require_sb3
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)     # import now fails
    with pytest.raises(MissingRLDependencies, match=r"pip install soft-envs\[rl\]"):
        require_sb3()
    assert main(["rl", "train", "tripod", "--timesteps", "10", "--out", str(tmp_path)]) == 2
    assert "pip install soft-envs[rl]" in capsys.readouterr().err


@pytest.mark.parametrize("observe_nodes", [False, True])
def test_dropped_entries_are_the_com_x_and_z_the_env_reports(observe_nodes):
    """The wrapper finds the COM's horizontal position through the environment's
    ``observation_structure``, not a copy of its layout."""
    from trajopt.rl.envs import make_env
    env = make_env("tripod", env_kwargs={"observe_nodes": observe_nodes, "reset_noise_scale": 0.0})
    env.reset(seed=0)
    full, _, _, _, info = env.env.step(np.ones(2, np.float32))       # the observation before the wrapper
    assert env.dropped == (0, 2)
    assert np.array_equal(full[[0, 2]], info["displacement"][[0, 2]]) and full[1] == info["com"][1]
    assert np.array_equal(env.observation(full), np.delete(full, env.dropped))
    assert env.observation_space.shape == (len(full) - 2,)


def test_env_ids_have_one_home():
    from trajopt.rl.envs import COULOMB_IDS, ROBOT_IDS, ROBOTS, env_id, robot_name
    assert set(ROBOTS) == set(soft_envs.ENV_IDS_BY_ROBOT)
    assert ROBOT_IDS == {"tripod": "SoftTripod-v0", "puppy": "SoftPuppy-v0"}
    assert COULOMB_IDS == {"tripod": "SoftTripod-v2", "puppy": "SoftPuppy-v2"}
    assert set(soft_envs.ENV_IDS) == {*ROBOT_IDS.values(), *COULOMB_IDS.values(), "SoftTripod-v1", "SoftPuppy-v1",
                                      "SoftHexapod-v2", "SoftInchworm-v2"}     # robots shipped at v2: -v2 only
    speed = {"motor_model": "speed"}          # -v0 and -v1 keep the motors of their making
    paper, coulomb_33ms = {"contact": "paper", "substeps": 1, **speed}, {"contact": "coulomb", "substeps": 1, **speed}
    assert soft_envs.ENV_KWARGS == {"SoftTripod-v0": paper, "SoftPuppy-v0": paper,
                                    "SoftTripod-v1": coulomb_33ms, "SoftPuppy-v1": coulomb_33ms,
                                    "SoftTripod-v2": {"contact": "coulomb"}, "SoftPuppy-v2": {"contact": "coulomb"},
                                    "SoftHexapod-v2": {"contact": "coulomb"}, "SoftInchworm-v2": {"contact": "coulomb"}}
    assert soft_envs.LATEST_ENV_IDS == {**COULOMB_IDS, "hexapod": "SoftHexapod-v2", "inchworm": "SoftInchworm-v2"}
    # the RL baseline makes the latest id under either law (never -v0, "out of date")
    assert env_id("puppy") == "SoftPuppy-v2" and env_id("SoftPuppy-v0") == "SoftPuppy-v2"
    assert robot_name("SoftTripod-v1") == "tripod" and robot_name("SoftTripod-v2") == "tripod"
    with pytest.raises(ValueError, match="SoftTripod-v0"):
        robot_name("cube")


def _out_of_date(caught) -> list[str]:
    """Gymnasium's "SoftTripod-v0 is out of date" (and any DeprecationWarning naming a -v0 id)."""
    return [str(w.message) for w in caught if "out of date" in str(w.message)
            or (issubclass(w.category, DeprecationWarning) and "-v0" in str(w.message))]


@pytest.mark.parametrize("contact", [None, "paper"])
def test_rl_commands_use_the_latest_id_under_either_law_without_a_deprecation_warning(tmp_path, contact):
    """``trajopt rl train`` / ``rl evaluate``: the default is the Coulomb law on -v2;
    ``--contact paper`` is the paper's law on -v2 too (``contact="paper"``), never -v0, which
    Gymnasium reports "out of date". The run records its law and its physics steps (the law's:
    4 for Coulomb, 1 for the paper's), and evaluates with them."""
    import json
    import warnings
    law = ["--contact", contact] if contact else []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["rl", "train", "tripod", "--algo", "ppo", "--timesteps", "32", "--n-envs", "1", "--vec-env",
                     "dummy", "--out", str(tmp_path), "--name", "run", "--no-progress", "--hp", "n_steps=32",
                     "--hp", "batch_size=32", "--hp", "n_epochs=1", "--hp", "policy_kwargs=dict(net_arch=[8])",
                     *law]) == 0
        main(["rl", "evaluate", str(tmp_path / "run"), "--cycles", "1", "--json"])
        assert main(["rl", "export", str(tmp_path / "run"), "--cycles", "1", "--out", str(tmp_path / "g.npz")]) == 0
    assert not _out_of_date(caught), _out_of_date(caught)
    config = json.loads((tmp_path / "run" / "rl_config.json").read_text())
    assert config["env_id"] == "SoftTripod-v2"
    assert config["env"]["env_kwargs"]["contact"] == (contact or "coulomb")
    assert config["env"]["env_kwargs"]["substeps"] == (1 if contact == "paper" else 4)
    exported = Result.load(tmp_path / "g.npz").settings                                    # evaluated with them
    assert exported["contact"] == (contact or "coulomb") and exported["substeps"] == (1 if contact == "paper" else 4)


def test_runs_made_before_the_law_was_recorded_evaluate_with_their_ids_law():
    """rl_config.json of older runs holds no ``contact``: -v0 runs were the paper's law, -v1 runs
    Coulomb's; a recorded law wins."""
    from trajopt.rl.envs import run_contact
    assert run_contact({"env_id": "SoftPuppy-v0", "env": {"env_kwargs": {"task": "walk"}}}) == "paper"
    assert run_contact({"env_id": "SoftPuppy-v1", "env": {"env_kwargs": {}}}) == "coulomb"
    assert run_contact({"env_id": "SoftPuppy-v1", "env": {"env_kwargs": {"contact": "paper"}}}) == "paper"
    assert run_contact({}) == "paper"


def test_runs_made_before_substeps_evaluate_with_their_ids_physics():
    """rl_config.json of runs made before sub-steps holds no ``substeps``: -v0 and -v1 runs (and
    runs without an id) had one physics step per control step; -v2 runs record theirs."""
    from trajopt.rl.envs import run_substeps
    assert run_substeps({"env_id": "SoftPuppy-v1", "env": {"env_kwargs": {}}}) == 1
    assert run_substeps({"env_id": "SoftPuppy-v0", "env": {"env_kwargs": {}}}) == 1
    assert run_substeps({}) == 1
    assert run_substeps({"env_id": "SoftPuppy-v2", "env": {"env_kwargs": {"substeps": 4}}}) == 4
    assert run_substeps({"env_id": "SoftPuppy-v2", "env": {"env_kwargs": {}}}) is None     # the law's default


def test_a_task_id_trains_on_its_registered_episodes_and_a_robot_on_trajopt_s_horizon(monkeypatch, tmp_path):
    """``trajopt rl train ID`` without --episode-steps: a task id's 300 steps (its score is defined
    over them), a robot's 168 (trajopt's horizon); --episode-steps wins over both. The command
    passes None on to ``train``, whose default decides (the Python API and the command agree)."""
    import soft_envs
    import trajopt.rl.training
    from trajopt.rl.envs import TRAIN_HORIZON
    from trajopt.rl.options import train_with_options
    from trajopt.rl.training import episode_steps_for
    seen = []
    monkeypatch.setattr(trajopt.rl.training, "train", lambda *a, **k: seen.append(k["max_episode_steps"]))
    cases = (("SoftTripodClimbStep-v0", None), ("tripod", None), ("SoftTripodClimbStep-v0", 50))
    for target, steps in cases:
        train_with_options(target, out=tmp_path, no_progress=True, episode_steps=steps)
    assert seen == [None, None, 50]
    assert [episode_steps_for(t, s) for t, s in cases] == [soft_envs.MAX_EPISODE_STEPS, TRAIN_HORIZON, 50]
