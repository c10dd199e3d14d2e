"""Training PPO / SAC (Stable-Baselines3) on ``SoftTripod-v2`` / ``SoftPuppy-v2`` (the Coulomb
law by default, the paper's with ``contact="paper"``).

A run writes one directory, ``OUT/NAME`` (default ``NAME = ROBOT_ALGO_seedS``)::

    model.zip               the final policy (also after Ctrl-C)
    vecnormalize.pkl        observation (and for PPO reward) normalisation statistics
    rl_config.json          robot, algorithm, budget, seed, environment settings,
                            hyper-parameters, simulation steps used, wall time, status
    checkpoints/            model_<N>_steps.zip + model_vecnormalize_<N>_steps.pkl, every
                            ``checkpoint_every`` environment steps (and N = 0, the untrained policy)
    logs/                   SB3 logger output: progress.csv and TensorBoard event files
                            (``tensorboard --logdir OUT``)
    monitor/                per-environment episode returns and lengths (SB3 Monitor)
"""
from __future__ import annotations

import copy
import functools
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..hardware.signals import Terminated, signal_label, signal_of
from . import require_sb3
from .envs import TRAIN_HORIZON, env_id, make_env, robot_name, task_of
from .hyperparams import ALGOS, jsonable, vecnormalize_kwargs
from .tuning.tuned import task_hyperparams

__all__ = ["train", "TrainRun", "CONFIG_NAME", "MODEL_NAME", "VECNORM_NAME", "write_config",
           "checkpoint_steps", "sb3_keywords", "ACTIVATIONS"]

CONFIG_NAME = "rl_config.json"
MODEL_NAME = "model.zip"
VECNORM_NAME = "vecnormalize.pkl"


@dataclass
class TrainRun:
    """What :func:`train` did: where it saved, how many steps, how long, and how it ended
    (``status`` "done" or "interrupted"; ``signal``: the signal that interrupted it, SIGINT for
    Ctrl-C, None when it finished)."""

    run_dir: Path
    model_path: Path
    config: dict[str, Any]
    status: str
    timesteps: int
    sim_steps: int
    wall_time_s: float
    checkpoints: list[Path] = field(default_factory=list)
    signal: int | None = None


def write_config(run_dir: Path, config: dict[str, Any]) -> Path:
    from ..results.result import atomic_write_bytes
    path = Path(run_dir) / CONFIG_NAME
    atomic_write_bytes(path, json.dumps(jsonable(config), indent=1).encode())
    return path


def _algo_class(algo: str):
    sb3 = require_sb3()
    return {"ppo": sb3.PPO, "sac": sb3.SAC}[algo]


def episode_steps_for(robot: str, max_episode_steps: int | None = None) -> int:
    """The episodes' length of a run on ``robot`` (a robot or a task id): ``max_episode_steps``,
    or by default :data:`~trajopt.rl.envs.TRAIN_HORIZON` (trajopt's horizon) on a robot and the
    registered :data:`soft_envs.MAX_EPISODE_STEPS` on a task id, whose score is defined over them."""
    if max_episode_steps is not None:
        return int(max_episode_steps)
    from soft_envs import MAX_EPISODE_STEPS
    return MAX_EPISODE_STEPS if task_of(robot) is not None else TRAIN_HORIZON


def train(robot: str, algo: str = "ppo", timesteps: int = 30_000, seed: int = 0,
          out: str | os.PathLike = "results/runs", *, name: str | None = None, n_envs: int | None = None,
          vec_env: str = "auto", frame_skip: int = 1, max_episode_steps: int | None = None,
          env_kwargs: dict[str, Any] | None = None, hyperparams: dict[str, Any] | None = None,
          checkpoint_every: int | None = None, progress_bar: bool = True, verbose: int = 0,
          log_stdout: bool = False, torch_threads: int | None = 1, callback=None,
          overwrite: bool = False) -> TrainRun:
    """Train ``algo`` ("ppo" | "sac") on ``robot`` ("tripod" | "puppy", or a task id such as
    ``"SoftTripodClimbStep-v0"``, whose keywords go in ``env_kwargs``: ``difficulty``) for ``timesteps``
    environment steps and save the run in ``out/name`` (see the module docstring).
    ``max_episode_steps``: :func:`episode_steps_for` (None: trajopt's horizon on a robot, the
    registered 300 steps on a task id).

    ``n_envs``: parallel environments (default ``os.cpu_count()``); ``vec_env``: "subproc",
    "dummy" or "auto" (subprocesses when ``n_envs > 1``). ``env_kwargs`` go to ``gym.make``
    (e.g. ``incline_deg``, ``target_heading_deg``). ``hyperparams`` override
    :func:`~trajopt.rl.tuning.tuned.task_hyperparams` (on a task id its robot's tuned values where
    a study found better ones, else :func:`~trajopt.rl.hyperparams.default_hyperparams`; the run's
    rl_config.json says which, ``hyperparams_source``), key by key: a ``policy_kwargs`` given
    replaces the whole of it. ``checkpoint_every``: environment steps
    between checkpoints (default: a tenth of the budget). ``torch_threads``: PyTorch CPU
    threads of the learner (1: the networks are tiny and the environment workers need the
    cores; ``None`` leaves PyTorch's default). Ctrl-C stops training and saves the model with
    ``status="interrupted"``. An existing run of the same name is an error unless
    ``overwrite`` (then its checkpoints are deleted first); a run of the same name in progress
    is refused (``out/NAME.lock``, :mod:`trajopt.results.reservation`).
    """
    require_sb3()
    import torch
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    target = robot if task_of(robot) is not None else robot_name(robot)    # what make_env makes
    max_episode_steps = episode_steps_for(robot, max_episode_steps)
    robot = robot_name(robot)
    algo = algo.lower()
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    timesteps = int(timesteps)
    if timesteps < 1:
        raise ValueError(f"timesteps must be positive, got {timesteps}")
    n_envs = int(n_envs or os.cpu_count() or 1)
    if n_envs < 1:
        raise ValueError(f"n_envs must be positive, got {n_envs}")
    if vec_env not in ("auto", "subproc", "dummy"):
        raise ValueError(f"vec_env must be 'auto', 'subproc' or 'dummy', got {vec_env!r}")
    use_subproc = vec_env == "subproc" or (vec_env == "auto" and n_envs > 1)
    env_kwargs = dict(env_kwargs or {})
    if task_of(target) is None:                     # a task id sets its own
        env_kwargs.setdefault("task", "walk")
    elif "task" in env_kwargs:
        raise ValueError(f"env_kwargs: 'task' is set by the task id {target}, got task={env_kwargs['task']!r}")
    # the law is recorded explicitly, so the run replays with it whatever the default becomes
    from soft_envs import ENV_KWARGS
    from soft_envs.envs import CONTACT_LAWS
    env_kwargs.setdefault("contact", ENV_KWARGS[env_id(robot)]["contact"])
    if env_kwargs.get("substeps") is None:          # and its physics steps (the law's default)
        env_kwargs["substeps"] = int(CONTACT_LAWS[env_kwargs["contact"]].default_substeps)
    # a task id: its robot's tuned values where a study found better ones (trajopt/rl/zoo/tuned.toml)
    hp, hp_source = task_hyperparams(algo, target, n_envs=n_envs, timesteps=timesteps)
    if hyperparams and set(hyperparams) >= set(hp):
        hp_source = "given"                         # every key (the tuning study's trials)
    elif hyperparams:
        hp_source += f", with {', '.join(sorted(hyperparams))} given"
    hp.update(hyperparams or {})
    sb3_keywords(hp)                                # an unknown activation name: refused before the run folder exists
    checkpoint_every = int(checkpoint_every or max(timesteps // 10, 1))

    run_dir = Path(out) / (name or f"{robot}{'_' + task_of(target) if target != robot else ''}_{algo}_seed{seed}")
    from ..results.reservation import lock_path, reserve
    with reserve(lock_path(run_dir), f"RL run {run_dir.name}"):   # a second run of this name is refused
        ckpt_dir = _prepare_run_dir(run_dir, overwrite)
        if torch_threads is not None:
            torch.set_num_threads(int(torch_threads))

        env_cfg = {"robot": target, "frame_skip": int(frame_skip), "max_episode_steps": int(max_episode_steps),
                   "drop_com_xz": True, "env_kwargs": env_kwargs}
        factory = functools.partial(make_env, target, frame_skip=int(frame_skip),
                                    max_episode_steps=int(max_episode_steps), drop_com_xz=True,
                                    env_kwargs=env_kwargs, ignore_sigint_in_worker=use_subproc)
        venv = make_vec_env(factory, n_envs=n_envs, seed=seed, monitor_dir=str(run_dir / "monitor"),
                            vec_env_cls=SubprocVecEnv if use_subproc else DummyVecEnv)
        vn_kwargs = vecnormalize_kwargs(algo, hp.get("gamma", 0.99))
        venv = VecNormalize(venv, **vn_kwargs)
        try:
            return _train(venv, robot, algo, timesteps, seed, run_dir, ckpt_dir, n_envs, use_subproc, env_cfg,
                          hp, hp_source, vn_kwargs, checkpoint_every, frame_skip, progress_bar, verbose, log_stdout, callback)
        finally:
            try:
                venv.close()
            except (EOFError, BrokenPipeError, ConnectionResetError, OSError):   # workers already gone
                pass


def _prepare_run_dir(run_dir: Path, overwrite: bool) -> Path:
    """Create the run's folders; an existing run is an error unless ``overwrite`` (then its
    checkpoints are deleted). Returns the checkpoint folder."""
    ckpt_dir = run_dir / "checkpoints"
    if (run_dir / CONFIG_NAME).exists():
        if not overwrite:
            raise ValueError(f"{run_dir} holds a run already; choose another name or overwrite it "
                             "(--overwrite)")
        for old in [*ckpt_dir.glob("model_*_steps.zip"), *ckpt_dir.glob("model_vecnormalize_*_steps.pkl")]:
            old.unlink()
    for d in (run_dir, ckpt_dir, run_dir / "logs", run_dir / "monitor"):
        d.mkdir(parents=True, exist_ok=True)
    return ckpt_dir


def _save_atomically(model, venv, model_path: Path, vecnorm_path: Path) -> None:
    """The final model and its VecNormalize statistics, each complete or not at all (a kill
    during the save leaves the previous files)."""
    from ..results.files import atomic_output
    with atomic_output(model_path) as tmp, open(tmp, "wb") as fh:
        model.save(fh)
    with atomic_output(vecnorm_path) as tmp:
        venv.save(str(tmp))


def _train(venv, robot, algo, timesteps, seed, run_dir, ckpt_dir, n_envs, use_subproc, env_cfg, hp, hp_source,
           vn_kwargs, checkpoint_every, frame_skip, progress_bar, verbose, log_stdout, callback) -> TrainRun:
    import torch
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback
    from stable_baselines3.common.logger import configure

    config: dict[str, Any] = {
        "robot": robot, "env_id": env_id(env_cfg["robot"]), "task": task_of(env_cfg["robot"]),
        "algo": algo, "timesteps": timesteps,
        "seed": int(seed), "n_envs": n_envs, "vec_env": "subproc" if use_subproc else "dummy",
        "env": env_cfg, "hyperparams": hp, "hyperparams_source": hp_source,
        "vecnormalize": vn_kwargs,
        "checkpoint_every": checkpoint_every, "status": "running",
        "sb3_version": require_sb3().__version__, "torch_version": torch.__version__,
    }
    write_config(run_dir, config)

    # (a copy: SB3 writes into policy_kwargs, the config keeps what was asked for)
    model = _algo_class(algo)("MlpPolicy", venv, seed=seed, device="cpu", verbose=verbose, **sb3_keywords(hp))
    formats = ["csv"] + (["tensorboard"] if _available("torch.utils.tensorboard", "tensorboard") else [])
    formats += ["stdout"] if log_stdout else []
    if progress_bar and not _available("tqdm", "rich"):
        warnings.warn("no progress bar: it needs tqdm and rich (pip install rich)", stacklevel=2)
        progress_bar = False
    model.set_logger(configure(str(run_dir / "logs"), formats))
    # the untrained policy is checkpoint 0 (the start of the speed-vs-steps curves)
    model.save(ckpt_dir / "model_0_steps.zip")
    venv.save(str(ckpt_dir / "model_vecnormalize_0_steps.pkl"))
    callbacks = [CheckpointCallback(save_freq=max(checkpoint_every // n_envs, 1), save_path=str(ckpt_dir),
                                    name_prefix="model", save_vecnormalize=True)]
    if callback is not None:
        callbacks.append(callback)

    status, signum = "done", None
    t0 = time.perf_counter()
    try:
        model.learn(total_timesteps=timesteps, callback=CallbackList(callbacks),
                    progress_bar=progress_bar)
    except (KeyboardInterrupt, Terminated) as exc:     # Ctrl-C, SIGTERM, SIGHUP: the model is saved
        status, signum = "interrupted", signal_of(exc)
        print(f"\ninterrupted by {signal_label(signum)} after {model.num_timesteps} steps: saving the model to "
              f"{run_dir}", file=sys.stderr)
    wall = time.perf_counter() - t0
    model_path = run_dir / MODEL_NAME
    _save_atomically(model, venv, model_path, run_dir / VECNORM_NAME)
    model.logger.close()                # progress.csv and the event files: flushed and closed now, not at GC
    done = int(model.num_timesteps)
    config.update(status=status, timesteps_done=done, sim_steps=done * int(frame_skip), wall_time_s=wall)
    write_config(run_dir, config)
    checkpoints = sorted(ckpt_dir.glob("model_*_steps.zip"), key=checkpoint_steps)
    return TrainRun(run_dir=run_dir, model_path=model_path, config=config, status=status,
                    timesteps=done, sim_steps=done * int(frame_skip), wall_time_s=wall,
                    checkpoints=checkpoints, signal=signum)


#: activation functions by name (``policy_kwargs=dict(activation_fn="relu")``: what ``--hp``, the
#: run's rl_config.json and the tuning study can write), as rl_zoo3 names them
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU"}


def sb3_keywords(hp: dict[str, Any]) -> dict[str, Any]:
    """A copy of ``hp`` for the algorithm's constructor: an ``activation_fn`` given by name (a key
    of :data:`ACTIVATIONS`) becomes the PyTorch module; ValueError naming an unknown one."""
    import torch
    hp = copy.deepcopy(hp)
    act = (hp.get("policy_kwargs") or {}).get("activation_fn")
    if isinstance(act, str):
        if act not in ACTIVATIONS:
            raise ValueError(f"policy_kwargs: activation_fn must be one of {tuple(ACTIVATIONS)}, got {act!r}")
        hp["policy_kwargs"]["activation_fn"] = getattr(torch.nn, ACTIVATIONS[act])
    return hp


def _available(*modules: str) -> bool:
    import importlib
    try:
        for m in modules:
            importlib.import_module(m)
    except ImportError:
        if "tensorboard" in modules:
            warnings.warn("no TensorBoard log: tensorboard is not installed (pip install tensorboard)",
                          stacklevel=3)
        return False
    return True


def checkpoint_steps(path: Path) -> int:
    """N of ``model_<N>_steps.zip`` (environment steps at which it was saved)."""
    stem = Path(path).stem
    try:
        return int(stem.split("_")[-2])
    except (IndexError, ValueError):
        raise ValueError(f"{path}: not a checkpoint name model_<N>_steps.zip") from None
