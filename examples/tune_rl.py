"""Tune the RL baseline's hyper-parameters on a task id: a small Optuna study.

Run:  python examples/tune_rl.py      (about 15 minutes on one core; needs pip install soft-envs[tune])

Each trial trains PPO on SoftTripodWalk-v0 and scores the policy with the task's own score (the
suite's evaluation) on evaluation episodes the suite does not use; the first trial is the
documented defaults (trajopt/rl/hyperparams.py), so the study says what tuning gains. This
example's trials are short (5000 steps; the suite's budget is 30000): what it shows is how a
study runs, goes on and reports. The study the docs quote is

    trajopt rl tune SoftTripodWalk-v0 --algo ppo --trials 20 --workers 2

(results/tuning/SoftTripodWalk-v0_ppo/; the same command again goes on where it stopped).
The folder holds the study (study.db, SQLite), each trial's run (trials/trial_0000 ...) and the
summary (tuning.json). docs/tasks.md, "Tuning the baselines", says what the studies found.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks it to 2 trials of 256 steps, in
results/tuning/example_quick.
"""
import os

from trajopt.cli.rl import tuning_text
from trajopt.rl.tuning import tune

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
STUDY = dict(trials=2, timesteps=256, episodes=1) if QUICK else dict(trials=6, timesteps=5000)
OUT = "results/tuning/example_quick" if QUICK else "results/tuning/example"   # a quick run never mixes with a full one


def main() -> None:
    # 1. The study: trial 0 is the defaults, then Optuna's TPE sampler draws from
    #    trajopt.rl.tuning.SPACES["ppo"] (rl_zoo3's parameters, ranges fit to these budgets).
    summary = tune("SoftTripodWalk-v0", "ppo", out=OUT, **STUDY)
    # 2. What it found, best first, and the command that trains with the best.
    print(tuning_text(summary))
    if summary["best"] and summary["defaults"]:
        gain = summary["best"]["score"] - summary["defaults"]["score"]
        print(f"best minus the defaults: {gain:+.3f} {summary['score_unit']} (one training seed each: "
              "train the best with seeds 0-2 before believing it)")
    print(f"wrote {OUT}/tuning.json")


if __name__ == "__main__":
    main()
