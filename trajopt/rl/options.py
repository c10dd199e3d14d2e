"""A training run from the options of ``trajopt rl train`` (the command line and a sweep's
``rl-train`` runs, :mod:`trajopt.sweep.kinds`, call this one function)."""
from __future__ import annotations

import inspect
import os
import sys
from typing import Any

from ..results.files import RESULTS_DIR

__all__ = ["train_with_options", "TRAIN_OPTIONS", "RUNS_DIR"]

#: parent folder of RL runs by default
RUNS_DIR = RESULTS_DIR / "runs"


def train_with_options(robot: str, *, algo: str = "ppo", timesteps: int = 30_000, seed: int = 0,
                       out: str | os.PathLike = RUNS_DIR, name: str | None = None, n_envs: int | None = None,
                       vec_env: str = "auto", frame_skip: int = 1, episode_steps: int | None = None,
                       incline: float = 0.0, contact: str | None = None, heading: float = 0.0,
                       difficulty: str | None = None,
                       checkpoint_every: int | None = None, hp: list[str] | tuple[str, ...] = (),
                       overwrite: bool = False, no_progress: bool = False, verbose: bool = False) -> Any:
    """:func:`trajopt.rl.training.train` with the command's option names: ``incline``,
    ``contact`` and ``heading`` set up the environment, ``hp`` holds ``KEY=VALUE`` overrides of
    the hyper-parameters, ``difficulty`` the level of a task id (``robot`` =
    ``"SoftTripodClimbStep-v0"``; None: the task's default), ``episode_steps`` the episodes'
    length (None: :func:`~trajopt.rl.training.train`'s default, trajopt's horizon on a robot's
    id, the registered 300 steps on a task id, whose score is defined over them), ``no_progress`` hides the progress bar (never shown when stderr is no
    terminal), ``verbose`` prints SB3's logger. Returns the :class:`~trajopt.rl.training.TrainRun`."""
    from .envs import task_of
    from .hyperparams import parse_overrides
    from .training import train
    env_kwargs: dict[str, Any] = {}
    if incline:
        env_kwargs["incline_deg"] = incline
    if heading:
        env_kwargs["target_heading_deg"] = heading
    if contact:
        env_kwargs["contact"] = contact
    if difficulty is not None:
        if task_of(robot) is None:
            raise ValueError(f"--difficulty applies to a task id (SoftTripodWalk-v0 ...), not to {robot!r}")
        from soft_envs.envs.tasks import check_difficulty
        env_kwargs["difficulty"] = check_difficulty(difficulty)
    bar = not no_progress and sys.stderr.isatty()
    heartbeat = None if no_progress or bar else _Heartbeat(timesteps, algo, robot)
    try:
        return train(robot, algo, timesteps, seed, out, name=name, n_envs=n_envs, vec_env=vec_env,
                     frame_skip=frame_skip, max_episode_steps=episode_steps, env_kwargs=env_kwargs,
                     hyperparams=parse_overrides(list(hp)), checkpoint_every=checkpoint_every, progress_bar=bar,
                     log_stdout=verbose, overwrite=overwrite,
                     callback=None if heartbeat is None else heartbeat.callback())
    finally:
        if heartbeat is not None:
            heartbeat.close()


class _Heartbeat:
    """Off a terminal (no bar), a plain line on stderr when training starts and after 30 s
    without one, with the environment steps done (:class:`trajopt.progress.Progress`); nothing
    for a run refused before it trains."""

    def __init__(self, timesteps: int, algo: str, robot: str):
        self.timesteps, self.algo, self.robot = int(timesteps), algo, robot
        self.progress = None

    def callback(self):
        from . import require_sb3
        require_sb3()                # MissingRLDependencies, saying how to install, before the import
        from stable_baselines3.common.callbacks import BaseCallback
        outer = self

        class _Count(BaseCallback):
            def _on_training_start(self) -> None:
                from ..progress import Progress
                outer.progress = Progress(outer.timesteps, "rl train", "step", tty=False, per_item=False,
                                          first_line=f"rl train: {outer.algo.upper()} on {outer.robot}, "
                                                     f"{outer.timesteps:,} environment steps (a line at least "
                                                     "every 30 s)")

            def _on_step(self) -> bool:
                if outer.progress is not None:
                    outer.progress.n = int(self.num_timesteps)
                return True

            def _on_training_end(self) -> None:
                outer.close()

        return _Count()

    def close(self) -> None:
        if self.progress is not None:
            self.progress.close()


#: the options of ``trajopt rl train`` and of a sweep's ``rl-train`` runs (the keywords above)
TRAIN_OPTIONS = tuple(p for p in inspect.signature(train_with_options).parameters if p != "robot")
