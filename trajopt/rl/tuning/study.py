"""The tuning study itself (:mod:`trajopt.rl.tuning`): trials, the SQLite storage shared by the
worker processes, going on after a stop, and the summary (``tuning.json``)."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ...results.files import HAVE_FILE_LOCKS, FileLock
from ..hyperparams import SUITE_N_ENVS, SUITE_TIMESTEPS
from .space import DEFAULT_PARAMS, SPACES, check_algo, hp_overrides, hyperparams_of, sample_hyperparams
from .tuned import task_hyperparams

__all__ = ["TuningWorkerError", "TrainingDiverged", "TUNING_SEED", "EVAL_FIRST_SEED", "TUNING_DIR", "STUDY_DB",
           "SUMMARY", "tune", "tuning_summary", "default_out"]

#: training seed of every trial (the suite's runs use 0, 1, 2)
TUNING_SEED = 100
#: first evaluation episode's seed of a trial (the suite's episodes are seeded 0, 1, 2)
EVAL_FIRST_SEED = 100
#: where studies go by default (one folder per id and algorithm)
TUNING_DIR = Path("results/tuning")
#: SQLite file of the study, and the summary, inside ``out``
STUDY_DB, SUMMARY, LOCK = "study.db", "tuning.json", "study.lock"
#: seconds between a running trial's heartbeats; one silent for ``_GRACE_S`` was cut short
_HEARTBEAT_S, _GRACE_S = 60, 180


def _counted(study) -> int:
    """Trials that count towards the budget: finished, scored or failed with an error (one
    stopped by Ctrl-C or a kill does not count)."""
    from optuna.trial import TrialState
    return sum(t.state == TrialState.COMPLETE or (t.state == TrialState.FAIL and "error" in t.user_attrs)
               for t in study.get_trials(deepcopy=False))


def _storage(out: Path):
    """The study's SQLite storage, with the heartbeat that finds a trial cut short and tries it again
    (Optuna calls the heartbeat experimental: its warning is silenced here, where it is meant)."""
    import warnings
    import optuna
    from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return RDBStorage(f"sqlite:///{(out / STUDY_DB).resolve()}", heartbeat_interval=_HEARTBEAT_S,
                          grace_period=_GRACE_S,
                          heartbeat_stale_trial_callback=RetryHeartbeatStaleTrialCallback(max_retry=3),
                          engine_kwargs={"connect_args": {"timeout": 60}})


def _study_name(env: str, algo: str) -> str:
    return f"{env}_{algo}"


def default_out(env: str, algo: str) -> Path:
    """The folder of the study of ``algo`` on ``env`` when none is given: ``results/tuning/ENV_ALGO``."""
    return TUNING_DIR / _study_name(env, algo)


class TrainingDiverged(Exception):
    """A trial's hyper-parameters made training diverge (NaN in the networks) or its score is not a
    number: the trial failed, and counts."""


class TuningWorkerError(RuntimeError):
    """A worker process of a study ended with an error (printed by the worker); the study is kept."""


def _objective(trial, env: str, algo: str, out: Path, timesteps: int, n_envs: int, episodes: int) -> float:
    """Train with the trial's hyper-parameters and score the policy (the module docstring)."""
    from ...tasks.play import policy_on_task
    from ..hyperparams import jsonable
    from ..training import train
    params = sample_hyperparams(trial, algo)
    hp = hyperparams_of(params, algo, n_envs=n_envs, timesteps=timesteps)
    t0 = time.perf_counter()
    try:
        run = train(env, algo, timesteps=timesteps, seed=TUNING_SEED, out=out / "trials",
                    name=f"trial_{trial.number:04d}", n_envs=n_envs, vec_env="dummy", max_episode_steps=None,
                    hyperparams=hp, checkpoint_every=timesteps, progress_bar=False, overwrite=True)
    except ValueError as exc:
        if "invalid values" not in str(exc):        # torch's distributions refusing NaN parameters
            raise
        trial.set_user_attr("error", f"training diverged: {exc}"[:500])
        raise TrainingDiverged(str(exc)) from exc
    if run.status != "done":                        # stopped (Ctrl-C, SIGTERM): so is the study
        import signal
        from ...hardware.signals import Terminated
        raise KeyboardInterrupt if run.signal in (None, signal.SIGINT) else Terminated(run.signal)
    ev = policy_on_task(run.run_dir, episodes=episodes, first_seed=EVAL_FIRST_SEED)
    if not np.isfinite(ev["score"]):
        trial.set_user_attr("error", f"score {ev['score']}")
        raise TrainingDiverged(f"score {ev['score']}")
    trial.set_user_attr("hyperparams", jsonable(hp))      # what it trained with, as this code made them
    trial.set_user_attr("wall_time_s", time.perf_counter() - t0)
    trial.set_user_attr("success_rate", float(ev["success_rate"]))
    trial.set_user_attr("episode_scores", [float(e["score"]) for e in ev["episodes"]])
    trial.set_user_attr("score_unit", ev["score_unit"])
    trial.set_user_attr("score_name", ev["score_name"])
    return float(ev["score"])


def _study_lock(out: Path) -> FileLock:
    """The lock on ``out/study.lock`` shared by a study's processes: SQLite ignores ``SELECT ...
    FOR UPDATE``, so two processes taking the next queued trial, or failing a stale one, at the same
    moment could take the same; under this lock only one does at a time."""
    return FileLock(out / LOCK)

    def close(self) -> None:
        self.release()
        self._file.close()


def _queue_again(study, trial) -> None:
    """A trial stopped by Ctrl-C or SIGTERM: failed (if Optuna has not marked it), and its
    parameters queued again (as the defaults' when they were)."""
    from optuna.trial import TrialState
    frozen = next(t for t in study.get_trials(deepcopy=False) if t.number == trial.number)
    if frozen.state == TrialState.RUNNING:
        study.tell(trial, state=TrialState.FAIL)
    if frozen.params:
        study.enqueue_trial(frozen.params, user_attrs={"defaults": True} if frozen.user_attrs.get("defaults")
                            else {"again_of": frozen.number})


def _worker(env: str, algo: str, out: str, trials: int, timesteps: int, n_envs: int, episodes: int,
            seed: int, k: int) -> None:
    """One process of a study: trials until ``trials`` are counted (:func:`_counted`). Its TPE
    sampler is seeded from ``seed``, the worker's number ``k`` and the trials already in the study
    (a study that goes on does not draw its first trials again)."""
    import optuna
    from ...hardware.signals import Terminated
    out = Path(out)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    lock = _study_lock(out)
    try:
        with lock:
            study = optuna.load_study(study_name=_study_name(env, algo), storage=_storage(out))
            entropy = [int(seed), int(k), len(study.get_trials(deepcopy=False))]
        study.sampler = optuna.samplers.TPESampler(seed=int(np.random.SeedSequence(entropy).generate_state(1)[0]))
        current: dict[str, Any] = {}

        def objective(trial) -> float:
            lock.release()                          # the trial is taken: the others may take theirs
            current["trial"] = trial
            return _objective(trial, env, algo, out, timesteps, n_envs, episodes)

        while _counted(study) < trials:
            current.clear()
            lock.acquire()                          # held while Optuna fails stale trials and takes the next
            try:
                study.optimize(objective, n_trials=1, catch=(TrainingDiverged,),
                               callbacks=[lambda s, t: _write_summary(s, env, algo, out, timesteps, n_envs)])
            except (KeyboardInterrupt, Terminated):
                if "trial" in current:              # (the objective released the lock)
                    with lock:
                        _queue_again(study, current["trial"])
                raise
            finally:
                lock.release()
    finally:
        lock.close()


def _settings(study, env: str, algo: str, out: Path, settings: dict[str, Any]) -> None:
    """A new study gets ``settings`` and the defaults queued; an existing one must have the same
    settings (ValueError otherwise), gets its stale trials failed (and queued again) and the
    defaults queued again if their trial was lost (stopped before it was scored)."""
    import warnings
    import optuna
    from optuna.trial import TrialState
    old = study.user_attrs.get("settings")
    if old is not None and old != settings:
        raise ValueError(f"{out / STUDY_DB}: a study made with {old}, not {settings}; choose another --out")
    if old is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            optuna.storages.fail_stale_trials(study)
    kept = (TrialState.COMPLETE, TrialState.RUNNING, TrialState.WAITING)
    if not any(t.user_attrs.get("defaults") and (t.state in kept or "error" in t.user_attrs)
               for t in study.get_trials(deepcopy=False)):
        study.enqueue_trial(DEFAULT_PARAMS[algo], user_attrs={"defaults": True})
    if old is None:
        study.set_user_attr("settings", settings)


def tune(env: str, algo: str = "ppo", *, trials: int = 20, out: str | os.PathLike | None = None,
         workers: int = 1, timesteps: int = SUITE_TIMESTEPS, n_envs: int = SUITE_N_ENVS,
         episodes: int | None = None, seed: int = 0) -> dict[str, Any]:
    """Tune ``algo`` on the task id ``env`` (the module docstring says how): ``trials`` trials in
    ``workers`` processes, in ``out`` (default ``results/tuning/ENV_ALGO``; an existing study there
    goes on). Returns :func:`tuning_summary` (also in ``out/tuning.json``). ``episodes``:
    evaluation episodes per trial (default the suite's, :func:`trajopt.tasks.scores.default_episodes`);
    ``seed`` seeds the TPE samplers. A study in ``out`` made with other settings (id, algorithm,
    budget, environments, episodes) is refused rather than mixed; so is bad input, before
    anything is written."""
    import optuna
    from soft_envs import TASK_ENV_IDS
    from ...tasks.scores import default_episodes
    algo = check_algo(algo)
    if env not in TASK_ENV_IDS:
        raise ValueError(f"env must be a task id ({sorted(TASK_ENV_IDS)[0]}, ...; docs/tasks.md), got {env!r}")
    episodes = default_episodes() if episodes is None else episodes
    for name, value, low in (("trials", trials, 1), ("workers", workers, 1), ("timesteps", timesteps, 1),
                             ("n_envs", n_envs, 1), ("episodes", episodes, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if workers > 1 and not HAVE_FILE_LOCKS:
        raise ValueError("workers > 1 needs POSIX file locks (fcntl), which this system lacks")
    out = Path(out) if out is not None else default_out(env, algo)
    settings = {"env_id": env, "algo": algo, "timesteps": int(timesteps), "n_envs": int(n_envs),
                "seed": TUNING_SEED, "eval_first_seed": EVAL_FIRST_SEED, "episodes": int(episodes)}
    if (out / STUDY_DB).exists():                   # another id or algorithm's study: refused, untouched
        others = set(optuna.get_all_study_names(_storage(out))) - {_study_name(env, algo)}
        if others:
            raise ValueError(f"{out / STUDY_DB} holds the study {sorted(others)[0]}, not {_study_name(env, algo)}; "
                             "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    lock = _study_lock(out)
    try:
        with lock:
            study = optuna.create_study(study_name=_study_name(env, algo), storage=_storage(out),
                                        direction="maximize", load_if_exists=True)
            _settings(study, env, algo, out, settings)
    finally:
        lock.close()
    rollouts = SPACES[algo].get("n_steps_total", ("choice", ()))[1]
    if any(n > timesteps for n in rollouts):
        import warnings
        warnings.warn(f"timesteps {timesteps} is below {algo}'s largest rollout ({max(rollouts)} transitions): "
                      f"its n_steps_total choices above the budget all train with rollouts of {timesteps} "
                      "(trajopt.rl.hyperparams.ppo_rollout), so the study draws them without effect",
                      UserWarning, stacklevel=2)
    args = (env, algo, str(out), int(trials), int(timesteps), int(n_envs), int(episodes), int(seed))
    if workers == 1:
        _worker(*args, 0)
    else:
        _run_workers([(*args, k) for k in range(workers)])
    study = optuna.load_study(study_name=_study_name(env, algo), storage=_storage(out))
    return _write_summary(study, env, algo, out, timesteps, n_envs)


def _worker_main(parent: int, args: tuple) -> None:
    """A worker process: it ends with its parent, takes SIGTERM as the CLI does (the trial in
    progress is queued again) and leaves the computing threads at one."""
    import sys
    from soft_envs.envs.threads import limit_threads
    from ...hardware.signals import COMMAND_SIGNALS, StopSignals, Terminated
    from ...workers import start_worker
    start_worker(parent)
    limit_threads()
    try:
        with StopSignals(signals=COMMAND_SIGNALS):
            _worker(*args)
    except Terminated as exc:
        sys.exit(128 + exc.signum)


def _run_workers(jobs: list[tuple]) -> None:
    """:func:`_worker` of each of ``jobs`` in its own process. Ctrl-C (or any error here) ends
    them all with SIGTERM; each queues its trial in progress again."""
    import multiprocessing
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_worker_main, args=(os.getpid(), job), name=f"tune-{k}") for k, job in enumerate(jobs)]
    try:
        for p in procs:
            p.start()
        for p in procs:
            p.join()
    finally:
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join()
    failed = [p.name for p in procs if p.exitcode not in (0, None)]
    if failed:
        raise TuningWorkerError(f"tuning workers {failed} ended with exit codes "
                                f"{[p.exitcode for p in procs if p.name in failed]} (their error is printed above)")


def tuning_summary(study, env: str, algo: str, timesteps: int, n_envs: int) -> dict[str, Any]:
    """What a study found: each trial (number, state, parameters, Stable-Baselines3 keywords,
    score, wall time, error), the defaults' trial, the best one and its ``--hp`` overrides (of what
    ``trajopt rl train`` starts from on the id now: the robot's tuned values where adopted). A
    trial's keywords are those it trained with (recorded since 2026-12-07; a trial of an older study
    has those its parameters give now); where its parameters give other keywords now, they are its
    ``hyperparams_now``, which the check and ``--hp`` use."""
    from optuna.trial import TrialState
    from ..hyperparams import jsonable
    rows = []
    for t in study.get_trials(deepcopy=False):
        if t.state == TrialState.WAITING:
            continue
        row = {"number": t.number, "state": t.state.name, "params": t.params,
               "score": t.value if t.state == TrialState.COMPLETE else None,
               "defaults": bool(t.user_attrs.get("defaults")), **{k: v for k, v in t.user_attrs.items()
                                                                   if k != "defaults"}}
        if set(t.params) == set(SPACES[algo]):
            now = jsonable(hyperparams_of(t.params, algo, n_envs=n_envs, timesteps=timesteps))
            if "hyperparams" not in row:            # a trial of a study made before they were recorded
                row["hyperparams"] = now
            elif row["hyperparams"] != now:         # trained with other keywords than its parameters give now
                row["hyperparams_now"] = now
        rows.append(row)
    done = [r for r in rows if r["score"] is not None]
    best = max(done, key=lambda r: r["score"], default=None)
    defaults = next((r for r in done if r["defaults"]), None)
    summary = {**study.user_attrs.get("settings", {}), "n_finished": len(done), "trials": rows,
               "defaults": defaults, "best": best, "score_unit": best and best.get("score_unit"),
               "hp_overrides": hp_overrides(hyperparams_of(best["params"], algo, n_envs=n_envs, timesteps=timesteps),
                                            algo, base=task_hyperparams(algo, env, n_envs=n_envs, timesteps=timesteps)[0])
               if best else []}
    return summary


def _write_summary(study, env: str, algo: str, out: Path, timesteps: int, n_envs: int) -> dict[str, Any]:
    from ...results.files import atomic_write_bytes
    summary = tuning_summary(study, env, algo, timesteps, n_envs)
    atomic_write_bytes(out / SUMMARY, json.dumps(summary, indent=1).encode())
    return summary
