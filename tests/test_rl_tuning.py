"""The RL baseline's hyper-parameter study (trajopt.rl.tuning, ``trajopt rl tune``): its search
space gives keywords Stable-Baselines3 takes, its first trial is the documented defaults, a study
goes on where it stopped (a trial cut short is tried again with its parameters), and bad input
is refused before anything is written."""
from __future__ import annotations

import json
import time
import warnings

import gymnasium as gym
import numpy as np
import pytest

pytestmark = [pytest.mark.rl, pytest.mark.filterwarnings(r"ignore:timesteps \d+ is below ppo's largest rollout")]
pytest.importorskip("stable_baselines3")
optuna = pytest.importorskip("optuna")

from trajopt.cli import main  # noqa: E402
from trajopt.rl.tuning import study as tuning_study  # noqa: E402
from trajopt.rl.hyperparams import default_hyperparams, parse_overrides  # noqa: E402
from trajopt.rl.training import sb3_keywords, train  # noqa: E402
from trajopt.rl.tuning import (DEFAULT_PARAMS, EVAL_FIRST_SEED, SPACES, TUNING_SEED, hp_overrides,  # noqa: E402
                               hyperparams_of, sample_hyperparams, tune)

ID = "SoftTripodWalk-v0"
TINY = dict(timesteps=256, episodes=1)           # a trial of a few seconds: one PPO update of 256 steps, one episode


def test_the_defaults_point_is_the_documented_defaults():
    for algo in ("ppo", "sac"):
        for name, (how, *range_) in SPACES[algo].items():       # a point of the space
            value = DEFAULT_PARAMS[algo][name]
            assert value in range_[0] if how == "choice" else range_[0] <= value <= range_[1], (algo, name)
        hp = hyperparams_of(DEFAULT_PARAMS[algo], algo)
        base = default_hyperparams(algo, n_envs=2, timesteps=30_000)
        if algo == "ppo":       # ent_coef 0 is the log range's floor; tanh is SB3's own default for PPO
            assert hp.pop("ent_coef") == 1e-8 and base.pop("ent_coef") == 0.0
            assert hp["policy_kwargs"].pop("activation_fn") == "tanh"
        assert hp == base, algo


def test_a_ppo_rollout_never_exceeds_a_smaller_budget():
    """PPO's rollout (n_steps x n_envs transitions) is the budget's when the budget is smaller,
    so that Stable-Baselines3, which collects whole rollouts, keeps it; larger budgets unchanged."""
    for n_envs, timesteps, n_steps in ((2, 30_000, 512), (2, None, 512), (3, 30_000, 341), (1, 1024, 1024),
                                       (2, 256, 128), (3, 256, 86), (1, 100, 100), (4, 40, 16)):
        hp = default_hyperparams("ppo", n_envs=n_envs, timesteps=timesteps)
        assert hp["n_steps"] == n_steps and hp["batch_size"] == min(64, n_steps * n_envs), (n_envs, timesteps)
    point = {**DEFAULT_PARAMS["ppo"], "n_steps_total": 2048, "batch_size": 256}
    assert hyperparams_of(point, "ppo", n_envs=2, timesteps=30_000)["n_steps"] == 1024
    hp = hyperparams_of(point, "ppo", n_envs=2, timesteps=200)
    assert (hp["n_steps"], hp["batch_size"]) == (100, 200)


def test_every_point_of_the_space_makes_a_model():
    """Random points of each space (and its corners) are accepted by Stable-Baselines3 (on a
    small stand-in environment: the keywords are what is checked)."""
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import DummyVecEnv
    venv = DummyVecEnv([lambda: gym.make("Pendulum-v1")] * 2)
    for algo, cls in (("ppo", PPO), ("sac", SAC)):
        study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=3))
        for _ in range(12):
            trial = study.ask()
            hp = hyperparams_of(sample_hyperparams(trial, algo), algo)
            if algo == "ppo":
                assert hp["batch_size"] <= hp["n_steps"] * 2 and hp["n_steps"] * 2 in (256, 512, 1024, 2048)
                assert 0.95 <= hp["gamma"] <= 0.999 and 0.8 <= hp["gae_lambda"] <= 0.99
            else:
                assert hp["gradient_steps"] == hp["train_freq"] and hp["buffer_size"] == 30_000
            model = cls("MlpPolicy", venv, device="cpu", **sb3_keywords(hp))
            assert model.gamma == pytest.approx(hp["gamma"])
            study.tell(trial, 0.0)
    venv.close()


def test_points_outside_the_space_are_refused():
    with pytest.raises(ValueError, match="missing.*tau"):
        hyperparams_of({k: v for k, v in DEFAULT_PARAMS["sac"].items() if k != "tau"}, "sac")
    with pytest.raises(ValueError, match="unknown.*n_epochs"):
        hyperparams_of({**DEFAULT_PARAMS["sac"], "n_epochs": 3}, "sac")
    with pytest.raises(ValueError, match="algo must be one of"):
        hyperparams_of(DEFAULT_PARAMS["ppo"], "td3")
    with pytest.raises(ValueError, match=r"net_arch must be one of \['small', 'medium'\], got 'big'"):
        hyperparams_of({**DEFAULT_PARAMS["ppo"], "net_arch": "big"}, "ppo")
    with pytest.raises(ValueError, match=r"learning_rate must be in \[0.0001, 0.003\], got 0.1"):
        hyperparams_of({**DEFAULT_PARAMS["sac"], "learning_rate": 0.1}, "sac")


def test_the_overrides_are_of_what_train_starts_from_on_the_id(tmp_path, monkeypatch):
    """With tuned values adopted for the robot, the ``--hp`` line of the defaults' point lists what
    differs from the tuned values, and trains with the defaults."""
    from trajopt.rl.tuning import tuned
    path = tmp_path / "tuned.toml"
    path.write_text(tuned.tuned_text({("ppo", "tripod"): _table()}))
    monkeypatch.setattr(tuned, "TUNED_FILE", path)
    base, _ = tuned.task_hyperparams("ppo", ID, n_envs=2, timesteps=30_000)
    want = hyperparams_of(DEFAULT_PARAMS["ppo"], "ppo")
    lines = hp_overrides(want, "ppo", base=base)
    assert "learning_rate=0.0003" in lines and not any(x.startswith("n_steps=") for x in lines)
    assert {**base, **parse_overrides(lines)} == want


def test_the_overrides_train_with_the_point():
    """``--hp`` of :func:`hp_overrides`, parsed as ``trajopt rl train`` does, gives the point back."""
    for algo in ("ppo", "sac"):
        study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=5))
        hp = hyperparams_of(sample_hyperparams(study.ask(), algo), algo)
        back = default_hyperparams(algo, n_envs=2, timesteps=30_000)
        back.update(parse_overrides(hp_overrides(hp, algo)))
        assert back == hp


def test_an_unknown_activation_is_refused_before_the_run_exists(tmp_path):
    with pytest.raises(ValueError, match="activation_fn must be one of"):
        train(ID, "ppo", timesteps=64, out=tmp_path, name="r", n_envs=1, progress_bar=False,
              hyperparams={"policy_kwargs": {"activation_fn": "sigmoid"}})
    assert not (tmp_path / "r").exists()


def test_a_study_scores_the_defaults_first_and_goes_on(tmp_path):
    out = tmp_path / "study"
    with pytest.warns(UserWarning, match="timesteps 256 is below ppo's largest rollout .2048 transitions"):
        s = tune(ID, "ppo", trials=2, out=out, **TINY)        # (the tests' budget: n_steps_total draws in vain)
    assert s["n_finished"] == 2 and [t["number"] for t in s["trials"]] == [0, 1]
    assert s["defaults"]["number"] == 0 and s["defaults"]["params"] == DEFAULT_PARAMS["ppo"]
    assert s["trials"][1]["params"] != DEFAULT_PARAMS["ppo"]
    assert s["best"]["score"] == max(t["score"] for t in s["trials"])
    assert s["seed"] == TUNING_SEED and s["eval_first_seed"] == EVAL_FIRST_SEED and s["score_unit"] == "BL/min"
    assert json.loads((out / "tuning.json").read_text()) == json.loads(json.dumps(s))
    # each trial is a run of the RL baseline, trained with the trial's keywords and the tuning seed
    cfg = json.loads((out / "trials" / "trial_0001" / "rl_config.json").read_text())
    assert cfg["seed"] == TUNING_SEED and cfg["timesteps_done"] == 256        # one rollout of the budget
    assert cfg["hyperparams"] == s["trials"][1]["hyperparams"] and "hyperparams_now" not in s["trials"][1]
    # its score is the task's on the held-out episodes
    from trajopt.tasks.play import policy_on_task
    ev = policy_on_task(out / "trials" / "trial_0001", episodes=1, first_seed=EVAL_FIRST_SEED)
    assert ev["episodes"][0]["seed"] == EVAL_FIRST_SEED and ev["score"] == pytest.approx(s["trials"][1]["score"])

    # the same study again: the two kept, one more made, not a draw made before
    s3 = tune(ID, "ppo", trials=3, out=out, **TINY)
    assert s3["n_finished"] == 3 and s3["trials"][:2] == s["trials"]
    assert s3["trials"][2]["params"] not in [t["params"] for t in s["trials"]]
    # another algorithm's study in the same folder: refused
    with pytest.raises(ValueError, match=f"holds the study {ID}_ppo, not {ID}_sac"):
        tune(ID, "sac", trials=1, out=out, **TINY)
    # other settings in the same folder: refused, nothing changed
    before = (out / "tuning.json").read_bytes()
    with pytest.raises(ValueError, match="a study made with"):
        tune(ID, "ppo", trials=4, out=out, timesteps=512, episodes=1)
    assert (out / "tuning.json").read_bytes() == before


@pytest.mark.filterwarnings("ignore:Heartbeat of storage is supposed to be used with Study.optimize")
def test_a_trial_cut_short_is_tried_again_with_its_parameters(tmp_path, monkeypatch):
    """A trial whose process died (its heartbeat stopped) is marked failed when the study goes on,
    and a copy of it, with the same parameters, is run and scored. (First: a trial reports the
    keywords it trained with, and apart those its parameters give under later code, as PPO's
    rollout changed for budgets below one.)"""
    monkeypatch.setattr(tuning_study, "_HEARTBEAT_S", 1)
    monkeypatch.setattr(tuning_study, "_GRACE_S", 1)
    out = tmp_path / "study"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = tune(ID, "sac", trials=1, out=out, **TINY)
    assert not [w for w in caught if "largest rollout" in str(w.message)]     # SAC has no rollout to warn of
    trained = json.loads((out / "trials" / "trial_0000" / "rl_config.json").read_text())["hyperparams"]
    assert s["trials"][0]["hyperparams"] == trained and "hyperparams_now" not in s["trials"][0]
    study = optuna.load_study(study_name=f"{ID}_sac", storage=tuning_study._storage(out))
    real = tuning_study.hyperparams_of
    with monkeypatch.context() as m:
        m.setattr(tuning_study, "hyperparams_of", lambda *a, **k: {**real(*a, **k), "learning_rate": 1e-3})
        row = tuning_study.tuning_summary(study, ID, "sac", 256, 2)["trials"][0]
    assert row["hyperparams"] == trained and trained["learning_rate"] == 3e-4
    assert row["hyperparams_now"] == {**trained, "learning_rate": 1e-3}

    dead = study.ask()                                # a trial that starts, beats once and dies
    params = sample_hyperparams(dead, "sac")
    study._storage.record_heartbeat(dead._trial_id)
    time.sleep(2.5)
    s = tune(ID, "sac", trials=2, out=out, **TINY)
    states = {t["number"]: t["state"] for t in s["trials"]}
    assert states[dead.number] == "FAIL" and "error" not in s["trials"][dead.number]
    retried = [t for t in s["trials"] if t["number"] > dead.number]
    assert len(retried) == 1 and retried[0]["state"] == "COMPLETE" and retried[0]["params"] == params
    assert s["n_finished"] == 2


def test_bad_input_is_refused_before_anything_is_written(tmp_path):
    for kwargs, match in ((dict(env="SoftTripod-v2"), "must be a task id"), (dict(algo="a2c"), "algo must be"),
                          (dict(trials=0), "trials must be"), (dict(workers=1.5), "workers must be"),
                          (dict(episodes=0), "episodes must be")):
        args = {"env": ID, "algo": "ppo", "trials": 1, "out": tmp_path / "s", **kwargs}
        with pytest.raises(ValueError, match=match):
            tune(args.pop("env"), args.pop("algo"), **args)
    assert not (tmp_path / "s").exists()


def test_the_command(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["rl", "tune", ID, "--trials", "1", "--timesteps", "256", "--episodes", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "trial   0:" in text and "(the defaults)" in text and f"trajopt rl train {ID} --algo ppo" in text
    assert main(["rl", "tune", ID, "--trials", "1", "--timesteps", "256", "--episodes", "1", "--out", str(out),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_finished"] == 1
    assert main(["rl", "tune", "SoftTripod-v2", "--out", str(tmp_path / "t")]) == 2
    assert "must be a task id" in capsys.readouterr().err
    assert main(["rl", "tune", ID, "--out", str(out), "--adopt"]) == 2
    assert "--adopt needs --check N" in capsys.readouterr().err


def test_a_study_of_two_workers(tmp_path):
    """Two processes share one study: three trials finished, none twice."""
    s = tune(ID, "ppo", trials=3, out=tmp_path / "s", workers=2, **TINY)
    numbers = [t["number"] for t in s["trials"] if t["state"] == "COMPLETE"]
    assert 3 <= len(numbers) <= 4 and len(set(numbers)) == len(numbers)
    params = [json.dumps(t["params"], sort_keys=True) for t in s["trials"]]
    assert len(set(params)) == len(params) and sum(t["defaults"] for t in s["trials"]) == 1
    assert np.isfinite([t["score"] for t in s["trials"] if t["score"] is not None]).all()


def test_a_trial_stopped_by_ctrl_c_is_queued_again(tmp_path, monkeypatch):
    """Ctrl-C during trial 0 (the defaults) stops the study; going on runs the defaults again."""
    import trajopt.rl.training as training
    real = training.train

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(training, "train", interrupted)
    out = tmp_path / "s"
    with pytest.raises(KeyboardInterrupt):
        tune(ID, "ppo", trials=1, out=out, **TINY)
    monkeypatch.setattr(training, "train", real)
    s = tune(ID, "ppo", trials=1, out=out, **TINY)
    assert [t["state"] for t in s["trials"]] == ["FAIL", "COMPLETE"] and "error" not in s["trials"][0]
    assert s["defaults"]["number"] == 1 and s["trials"][1]["params"] == DEFAULT_PARAMS["ppo"]


def test_a_diverging_trial_counts_and_other_errors_stop_the_study(tmp_path, monkeypatch, capsys):
    import trajopt.rl.training as training

    def diverges(*args, **kwargs):
        raise ValueError("Expected parameter loc (Tensor of shape (2, 2)) of distribution Normal(...) to satisfy "
                         "the constraint Real(), but found invalid values: tensor([[nan, nan]])")
    monkeypatch.setattr(training, "train", diverges)
    s = tune(ID, "ppo", trials=2, out=tmp_path / "s", **TINY)
    assert [t["state"] for t in s["trials"]] == ["FAIL", "FAIL"] and s["n_finished"] == 0 and s["best"] is None
    assert all(t["error"].startswith("training diverged: Expected parameter loc") for t in s["trials"])
    assert main(["rl", "tune", ID, "--trials", "2", "--timesteps", "256", "--episodes", "1",
                 "--out", str(tmp_path / "s")]) == 1
    assert "no trial was scored" in capsys.readouterr().err

    def bug(*args, **kwargs):
        raise ValueError("some other mistake")
    monkeypatch.setattr(training, "train", bug)
    with pytest.raises(ValueError, match="some other mistake"):
        tune(ID, "ppo", trials=1, out=tmp_path / "t", **TINY)


def test_the_best_is_checked_on_the_suite_seeds(tmp_path, capsys, monkeypatch):
    """check_best trains the best and the defaults with seeds 0.. and scores them as the suite does
    (episodes from seed 0), each also replayed at other physics steps (its credible score: the
    lowest); a second check scores the runs made, without training or replaying them again."""
    from trajopt.cli.rl import check_text
    from trajopt.rl.tuning import check_best
    from trajopt.tasks.play import policy_on_task
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")       # one episode per score (the suite's three: the same code)
    out = tmp_path / "s"
    s = tune(ID, "ppo", trials=2, out=out, **TINY)
    s["best"] = s["trials"][1]                       # whichever scored higher: the check is of trial 1
    (out / "tuning.json").write_text(json.dumps(s))
    c = check_best(out, seeds=1)
    assert c["best"]["trial"] == 1 and c["defaults"]["trial"] == 0 and c["seeds"] == [0]
    run = out / "check" / "best_seed0"
    cfg = json.loads((run / "rl_config.json").read_text())
    assert cfg["seed"] == 0 and cfg["hyperparams"] == s["trials"][1]["hyperparams"] and cfg["timesteps_done"] == 256
    assert c["best"]["scores"] == [pytest.approx(policy_on_task(run)["score"])]
    assert c["difference"] == pytest.approx(c["best"]["mean"] - c["defaults"]["mean"])
    hold = json.loads((run / "task_hold.json").read_text())       # the suite's replays, of the check's run
    assert hold["own_score"] == c["best"]["scores"][0] and hold["own_substeps"] == 4 and hold["substeps"] == [2, 4, 8, 16]
    r = c["best"]["runs"][0]
    assert r["hold_scores"] == hold["scores"] and r["credible"] == min(hold["scores"]) == hold["slowest"]
    assert r["holds"] == hold["holds"] and r["physics_dt_ms"] == pytest.approx([16.5, 8.25, 4.125, 2.0625])
    assert c["best"]["credible"] == [r["credible"]] and c["best"]["holds"] == int(r["holds"])
    assert c["credible_difference"] == pytest.approx(c["best"]["credible_mean"] - c["defaults"]["credible_mean"])
    assert json.loads((out / "check.json").read_text()) == json.loads(json.dumps(c))
    made = (run / "model.zip").stat().st_mtime_ns, (run / "task_hold.json").stat().st_mtime_ns
    assert check_best(out, seeds=1)["best"]["scores"] == c["best"]["scores"]
    assert ((run / "model.zip").stat().st_mtime_ns, (run / "task_hold.json").stat().st_mtime_ns) == made
    text = check_text(c)
    assert "best minus the defaults" in text and "credibly (the lowest over the replays" in text
    assert f"{int(r['holds'])} of 1 hold" in text
    # the defaults as the best: nothing to check
    s["best"] = s["trials"][0]
    (out / "tuning.json").write_text(json.dumps(s))
    assert check_best(out, seeds=1)["note"] == "the defaults are the study's best"
    # no study, or a bad summary: refused, naming the file
    with pytest.raises(ValueError, match="no study here"):
        check_best(tmp_path / "none")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "tuning.json").write_text("{")
    with pytest.raises(ValueError, match=r"bad/tuning.json: not a study's summary"):
        check_best(tmp_path / "bad")
    with pytest.raises(ValueError, match="seeds must be"):
        check_best(out, seeds=0)


def _table(**changes):
    table = {"study": ID, "trials": 20, "trial": 7, "study_score": 19.0, "defaults_score": 18.0, "check_seeds": [0, 1, 2],
             "check_best_mean": 19.5, "check_defaults_mean": 18.1, "score_unit": "BL/min",
             "params": {**DEFAULT_PARAMS["ppo"], "learning_rate": 1e-3, "activation_fn": "relu"}}
    table.update(changes)
    return table


def test_tuned_values_are_used_on_the_robot_s_task_ids_only(tmp_path, monkeypatch):
    from trajopt.rl.tuning import tuned
    path = tmp_path / "tuned.toml"
    assert tuned.read_tuned(path) == {}                          # no file: the defaults everywhere
    path.write_text(tuned.tuned_text({("ppo", "tripod"): _table()}))
    assert tuned.read_tuned(path)[("ppo", "tripod")] == _table()
    hp, source = tuned.task_hyperparams("ppo", "SoftTripodClimbStep-v0", n_envs=2, timesteps=30_000, path=path)
    assert hp["learning_rate"] == 1e-3 and hp["policy_kwargs"]["activation_fn"] == "relu"
    assert source == f"tuned: tuned.toml [ppo.tripod] (study {ID}, trial 7)"
    for algo, target in (("ppo", "SoftTripod-v2"), ("ppo", "SoftPuppyWalk-v0"), ("sac", "SoftTripodWalk-v0")):
        hp, source = tuned.task_hyperparams(algo, target, n_envs=2, timesteps=30_000, path=path)
        assert source == "defaults" and hp == default_hyperparams(algo, n_envs=2, timesteps=30_000)
    # a run records where its values came from; the rl_zoo3 entry has them, the activation as rl_zoo3 writes it
    monkeypatch.setattr(tuned, "TUNED_FILE", path)
    run = train(ID, "ppo", timesteps=64, out=tmp_path / "runs", name="r", n_envs=1, vec_env="dummy",
                progress_bar=False, hyperparams={"n_steps": 32, "batch_size": 32, "n_epochs": 1})
    assert run.config["hyperparams"]["learning_rate"] == 1e-3
    assert run.config["hyperparams_source"] == (f"tuned: tuned.toml [ppo.tripod] (study {ID}, trial 7), with "
                                                "batch_size, n_epochs, n_steps given")
    from trajopt.rl.zoo import zoo_entry
    entry = zoo_entry("ppo", "SoftTripodCarry-v0")
    assert entry["learning_rate"] == 1e-3 and "activation_fn=nn.ReLU" in entry["policy_kwargs"]
    assert zoo_entry("ppo", "SoftPuppyCarry-v0")["learning_rate"] == 3e-4


@pytest.mark.parametrize("text, match", [
    ("[td3.tripod]\n", r"\[td3\] must be one of"),
    ("STUDY_PUPPY", r"\[ppo.tripod\]: study must be a task id of the tripod, got 'SoftPuppyWalk-v0'"),
    ("SCORE_NAN", r"\[ppo.tripod\]: study_score must be finite, got nan"),
    ("CREDIBLE_NAN", r"\[ppo.tripod\]: check_best_credible must be finite, got nan"),
    ("CREDIBLE_STR", r"\[ppo.tripod\]: check_defaults_credible must be a float, got 'x'"),
    ("[ppo.snake]\n", r"\[ppo.snake\]: the robot must be one of"),
    ("[ppo.tripod]\nstudy = 3\n", r"\[ppo.tripod\]: study must be a str, got 3"),
    ("[ppo.tripod\n", r"tuned.toml: "),
])
def test_a_bad_tuned_file_is_refused_naming_the_table(tmp_path, text, match):
    from trajopt.rl.tuning import tuned
    path = tmp_path / "tuned.toml"
    bad = {"STUDY_PUPPY": _table(study="SoftPuppyWalk-v0"), "SCORE_NAN": _table(study_score=float("nan")),
           "CREDIBLE_NAN": _table(check_best_credible=float("nan")),
           "CREDIBLE_STR": _table(check_defaults_credible="x")}.get(text)
    path.write_text(tuned.tuned_text({("ppo", "tripod"): bad}) if bad else text)
    with pytest.raises(ValueError, match=match):
        tuned.read_tuned(path)
    path.write_text(tuned.tuned_text({("ppo", "tripod"): _table(params={**DEFAULT_PARAMS["ppo"], "n_epochs": 7})}))
    with pytest.raises(ValueError, match=r"\[ppo.tripod\]: params: ppo parameter n_epochs must be one of"):
        tuned.read_tuned(path)


def test_the_best_is_adopted_only_when_it_beat_the_defaults_on_the_suite_seeds(tmp_path):
    from trajopt.rl.tuning import tuned
    from trajopt.rl.tuning.adopt import adopt
    out, path = tmp_path / "study", tmp_path / "tuned.toml"
    out.mkdir()
    defaults = {"number": 0, "score": 18.0, "params": DEFAULT_PARAMS["ppo"], "defaults": True}
    best = {"number": 5, "score": 19.0, "params": _table()["params"], "defaults": False}
    (out / "tuning.json").write_text(json.dumps({"env_id": ID, "algo": "ppo", "timesteps": 30000, "n_envs": 2,
                                                 "trials": [defaults, best], "n_finished": 20, "best": best,
                                                 "defaults": defaults, "score_unit": "BL/min"}))
    with pytest.raises(ValueError, match="not checked yet"):
        adopt(out, path)
    (out / "check.json").write_text("{}")
    with pytest.raises(ValueError, match=r"check.json: not a check \(KeyError"):
        adopt(out, path)

    def check(trial, difference, credible=None):
        credible = difference if credible is None else credible
        (out / "check.json").write_text(json.dumps({"seeds": [0, 1, 2], "difference": difference,
                                                    "credible_difference": credible,
                                                    "best": {"trial": trial, "mean": 18.0 + difference,
                                                             "credible_mean": 17.5 + credible},
                                                    "defaults": {"trial": 0, "mean": 18.0, "credible_mean": 17.5}}))
    check(4, 1.0)
    with pytest.raises(ValueError, match=r"checks trial 4, not the study's best \(trial 5\)"):
        adopt(out, path)
    check(5, -0.2)
    with pytest.raises(ValueError, match="the defaults stay"):
        adopt(out, path)
    check(5, 0.7)
    c = json.loads((out / "check.json").read_text())
    c["best"]["std"], c["defaults"]["std"] = 1.2, 0.9             # standard error 1.5 / sqrt(3) = 0.87 > 0.7
    (out / "check.json").write_text(json.dumps(c))
    with pytest.raises(ValueError, match=r"a difference of \+0.700, not above its standard error 0.866"):
        adopt(out, path)
    check(5, 0.7, credible=-0.1)          # higher at its own physics step, not over the replays
    with pytest.raises(ValueError, match=r"scored credibly 17.400 \(the lowest over the replays at other physics "
                                         r"steps\), the defaults 17.500: a difference of -0.100, not above its "
                                         r"standard error 0.000: the defaults stay"):
        adopt(out, path)
    check(5, 0.7, credible=0.3)
    c = json.loads((out / "check.json").read_text())
    c["best"]["credible_std"], c["defaults"]["credible_std"] = 0.6, 0.3      # 0.67 / sqrt(3) = 0.39 > 0.3
    (out / "check.json").write_text(json.dumps(c))
    with pytest.raises(ValueError, match=r"a difference of \+0.300, not above its standard error 0.387"):
        adopt(out, path)
    del c["credible_difference"]                    # a check made before it replayed its runs
    (out / "check.json").write_text(json.dumps(c))
    with pytest.raises(ValueError, match=r"check.json: made without the replays at other physics steps .*check it "
                                         r"again"):
        adopt(out, path)
    check(5, 0.7)
    c = json.loads((out / "check.json").read_text())
    (out / "check.json").write_text(json.dumps({**c, "seeds": [0]}))
    with pytest.raises(ValueError, match=r"checked on 1 seed\(s\); adopting needs 3"):
        adopt(out, path)
    summary = json.loads((out / "tuning.json").read_text())
    (out / "tuning.json").write_text(json.dumps({**summary, "timesteps": 256}))
    with pytest.raises(ValueError, match="its trials had 256 steps and 2 environments, not the suite's 30000"):
        adopt(out, path)
    (out / "tuning.json").write_text(json.dumps({**summary, "best": defaults}))
    with pytest.raises(ValueError, match="the defaults are the study's best: nothing to adopt"):
        adopt(out, path)
    (out / "tuning.json").write_text(json.dumps(summary))
    (out / "check.json").write_text(json.dumps(c))
    assert not path.exists()
    # a table adopted already with a better check stays
    path.write_text(tuned.tuned_text({("ppo", "tripod"): _table(check_best_mean=19.0)}))
    with pytest.raises(ValueError, match=r"\[ppo.tripod\] \(study SoftTripodWalk-v0, trial 7\) scored 19.000 on its "
                                         r"check, this best 18.700: it stays"):
        adopt(out, path)
    path.unlink()
    path.write_text(tuned.tuned_text({("sac", "puppy"): _table(study="SoftPuppyWalk-v0",
                                                                params=DEFAULT_PARAMS["sac"])}))
    check(5, 0.7)
    table = adopt(out, path)
    assert table["trial"] == 5 and table["check_best_mean"] == 18.7 and table["params"] == best["params"]
    assert table["check_best_credible"] == 18.2 and table["check_defaults_credible"] == 17.5
    assert tuned.read_tuned(path)[("ppo", "tripod")] == table                  # written and read back whole
    assert set(tuned.read_tuned(path)) == {("ppo", "tripod"), ("sac", "puppy")}      # the other table kept


def test_the_suite_report_marks_runs_made_with_other_values(tmp_path, monkeypatch):
    """bench_suite's other_hyperparams: a Tripod PPO run made with the defaults is marked once the
    Tripod's PPO values are adopted (with where its values came from), not before; its quick
    runs' own --hp are part of what it asked for."""
    import importlib.util
    from types import SimpleNamespace
    from trajopt.rl.tuning import tuned
    from trajopt.sweep import load_spec  # noqa: F401  (the bench script imports the sweep)
    spec = importlib.util.spec_from_file_location("bench_suite", tuning_study.__file__.rsplit("/trajopt/", 1)[0]
                                                  + "/benchmarks/bench_suite.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    run_dir = tmp_path / "run"
    hp = {"n_steps": 32, "batch_size": 32, "n_epochs": 1}
    monkeypatch.setattr(tuned, "TUNED_FILE", tmp_path / "none.toml")        # made with the defaults
    train(ID, "ppo", timesteps=64, out=tmp_path, name="run", n_envs=2, vec_env="dummy", progress_bar=False,
          hyperparams=hp)
    run = SimpleNamespace(kind="rl-train", params={"hp": [f"{k}={v}" for k, v in hp.items()]})
    rl = bench.rl_config_of(run_dir)                  # what the suite's ledger keeps of the run
    assert bench.other_hyperparams(run, rl) is None
    monkeypatch.setattr(tuned, "TUNED_FILE", tmp_path / "tuned.toml")
    (tmp_path / "tuned.toml").write_text(tuned.tuned_text({("ppo", "tripod"): _table()}))
    assert bench.other_hyperparams(run, rl) == "defaults, with batch_size, n_epochs, n_steps given"
    assert bench.other_hyperparams(SimpleNamespace(kind="optimize", params={}), None) is None
    (tmp_path / "tuned.toml").write_text("[ppo.snake]\n")          # a bad file is an error, not "no mark"
    with pytest.raises(ValueError, match="the robot must be one of"):
        bench.other_hyperparams(run, rl)


def test_the_command_adopts_and_writes_the_rl_zoo3_files_beside(tmp_path, monkeypatch, capsys):
    """``trajopt rl tune ... --check 3 --adopt``: the table written and the rl_zoo3 files beside it
    written again with its values (here in a temporary folder standing for trajopt/rl/zoo)."""
    import trajopt.rl.tuning as tuning_pkg
    from trajopt.rl.tuning import tuned
    out, zoo = tmp_path / "study", tmp_path / "zoo"
    out.mkdir(), zoo.mkdir()
    defaults = {"number": 0, "score": 18.0, "params": DEFAULT_PARAMS["ppo"], "defaults": True}
    best = {"number": 5, "score": 19.0, "params": _table()["params"], "defaults": False}
    summary = {"env_id": ID, "algo": "ppo", "timesteps": 30000, "n_envs": 2, "seed": 100, "eval_first_seed": 100,
               "trials": [defaults, best], "n_finished": 20, "best": best, "defaults": defaults,
               "score_unit": "BL/min", "hp_overrides": []}
    check = {"seeds": [0, 1, 2], "difference": 1.5, "wins": 3, "score_unit": "BL/min",
             "credible_difference": 1.0,
             "best": {"trial": 5, "scores": [19.4, 19.5, 19.6], "mean": 19.5, "std": 0.1,
                      "credible": [18.9, 19.0, 19.1], "credible_mean": 19.0, "credible_std": 0.1, "holds": 3},
             "defaults": {"trial": 0, "scores": [18.0, 18.0, 18.0], "mean": 18.0, "std": 0.0,
                          "credible": [18.0, 18.0, 18.0], "credible_mean": 18.0, "credible_std": 0.0, "holds": 3}}
    (out / "tuning.json").write_text(json.dumps(summary))
    (out / "check.json").write_text(json.dumps(check))
    monkeypatch.setattr(tuning_pkg, "tune", lambda *a, **k: summary)
    monkeypatch.setattr(tuning_pkg, "check_best", lambda *a, **k: check)
    monkeypatch.setattr(tuned, "TUNED_FILE", zoo / "tuned.toml")
    assert main(["rl", "tune", ID, "--out", str(out), "--check", "3", "--adopt"]) == 0
    text = capsys.readouterr().out
    assert "best minus the defaults: +1.500 BL/min; higher on 3 of 3 seeds" in text and "adopted trial 5" in text
    assert tuned.read_tuned(zoo / "tuned.toml")[("ppo", "tripod")]["check_best_mean"] == 19.5
    ppo = (zoo / "ppo.yml").read_text()
    tripod = ppo.split("SoftTripodTurn-v0:")[1].split("\n\n")[0]
    assert "learning_rate: !!float 0.001" in tripod and "activation_fn=nn.ReLU" in tripod
    puppy = ppo.split("SoftPuppyTurn-v0:")[1].split("\n\n")[0]
    assert "learning_rate: !!float 0.0003" in puppy
