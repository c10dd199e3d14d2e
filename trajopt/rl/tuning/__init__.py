"""Tuning the RL baseline's hyper-parameters on a task id: an Optuna study.

    trajopt rl tune SoftTripodWalk-v0 --algo ppo --trials 20 --workers 2
    # -> results/tuning/SoftTripodWalk-v0_ppo/: study.db, tuning.json, trials/trial_0000 ...

**A trial** trains ``algo`` on the id the way the suite does (examples/suite.toml: :data:`SUITE_TIMESTEPS`
environment steps, :data:`SUITE_N_ENVS` environments stepped in one process, the registered
300-step episodes; :func:`trajopt.rl.training.train`) with hyper-parameters drawn by
:func:`sample_hyperparams`. Its value is the task's own score of the trained policy
(:func:`trajopt.tasks.play.policy_on_task`, the suite's evaluation: deterministic, 3 episodes).
Higher is better for every task's score.

**Held out:** the trials train with seed :data:`TUNING_SEED` and are scored on the episodes seeded
from :data:`EVAL_FIRST_SEED`, not the suite's training seeds 0-2 and evaluation episodes 0-2. The
best of N trials on one seed is an optimistic figure; the suite's runs made with the tuned
values are an independent measure of them.

**Search space:** rl_zoo3's (``rl_zoo3.hyperparams_opt``: the same parameters, the discount and the
learning rate log-uniform as ``1 - gamma`` and ``lr``), with ranges narrowed to budgets of
10^4-10^5 steps on a CPU: PPO collects at most 2048 transitions per update (rl_zoo3's 4096 per
environment would leave 3 updates in 30k steps) and takes batches of at least 32 (rl_zoo3's 4
would cost hours of gradient steps per trial); SAC keeps one gradient step per vector step of
``train_freq`` and the baseline's 1000 warm-up steps. PPO also draws its initial action noise
(``log_std_init``): with 30 updates it matters (RL Zoo's tuned MuJoCo files set it). The names
and ranges are in :data:`SPACES`.

**The first trial is the documented defaults** (:func:`~trajopt.rl.hyperparams.default_hyperparams`,
enqueued; PPO's ``ent_coef`` 0 is drawn as the range's floor, 1e-8), so the study says what tuning
gains over them.

**Sampler and stopping:** Optuna's TPE (the defaults and 9 random trials, then TPE), seeded from
``seed``, the worker's number and the trials already made. No pruning: a trial's score exists
only once the policy is trained and played (an evaluation during training would cost a tenth of
the budget each time). The study stops when ``trials`` trials have finished, scored or failed
(:class:`TrainingDiverged`: a choice whose training diverges to NaN); several ``workers``
(processes) share the study, so the last ones may finish ``workers - 1`` more. Any other error
stops the study (the trial stays failed and does not count).

**Resuming:** the study lives in ``out/study.db`` (SQLite; one study per folder: another id or
algorithm there is refused, and so are other settings). The same command with the same ``out``
goes on where it stopped: the finished trials are kept; a trial stopped by Ctrl-C or SIGTERM is
marked failed and its parameters are queued again; one whose process was killed outright (SIGKILL,
a power cut) is found by Optuna's heartbeat when the study goes on, three minutes after its last
beat, and queued again the same way. Worker processes take the next trial under a file lock
(``out/study.lock``): SQLite cannot lock a row, and two could take the same trial.
``out/tuning.json`` is written (atomically) after every trial: each trial's parameters and score,
the defaults', the best, and the ``--hp`` overrides that train with the best (``trajopt rl train
ID --hp ...``).

**Checking the best** (:func:`check_best`, ``trajopt rl tune ID --check 3``): the best and the
defaults trained with the suite's seeds 0-2 and scored as the suite scores, each run also
replayed at other physics steps (its credible score: the lowest), in ``out/check/`` and
``out/check.json``; ``--adopt`` (:mod:`.adopt`) takes the best only when it beat the defaults
both at its own physics step and credibly.

The modules: :mod:`.space` (the search space), :mod:`.study` (the study), :mod:`.check`.
"""
from __future__ import annotations

from .check import CHECK, check_best
from .space import DEFAULT_PARAMS, SPACES, hp_overrides, hyperparams_of, sample_hyperparams
from .study import (EVAL_FIRST_SEED, TUNING_DIR, TUNING_SEED, TrainingDiverged, TuningWorkerError, default_out,
                    tune, tuning_summary)

__all__ = ["TuningWorkerError", "TrainingDiverged", "SPACES", "DEFAULT_PARAMS", "TUNING_SEED", "EVAL_FIRST_SEED",
           "TUNING_DIR", "sample_hyperparams", "hyperparams_of", "tune", "tuning_summary", "hp_overrides", "check_best",
           "CHECK", "default_out"]
