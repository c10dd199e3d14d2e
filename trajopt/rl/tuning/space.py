"""The search space of the RL baseline's tuning study (:mod:`trajopt.rl.tuning`): rl_zoo3's
parameters with ranges fit to budgets of 10^4-10^5 steps on a CPU, the documented defaults as a
point of it, and the Stable-Baselines3 keywords (and ``--hp`` options) of a point."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..hyperparams import ALGOS, SUITE_N_ENVS, SUITE_TIMESTEPS, default_hyperparams, ppo_rollout

__all__ = ["SPACES", "DEFAULT_PARAMS", "sample_hyperparams", "hyperparams_of", "hp_overrides", "check_algo"]

#: the search space per algorithm: name -> ("log", low, high) | ("float", low, high) | ("choice", options)
SPACES: dict[str, dict[str, tuple]] = {
    "ppo": {
        "n_steps_total": ("choice", (256, 512, 1024, 2048)),      # transitions per update, all environments
        "batch_size": ("choice", (32, 64, 128, 256)),
        "n_epochs": ("choice", (5, 10, 20)),
        "learning_rate": ("log", 1e-4, 3e-3),
        "one_minus_gamma": ("log", 1e-3, 5e-2),
        "one_minus_gae_lambda": ("log", 1e-2, 2e-1),
        "clip_range": ("choice", (0.1, 0.2, 0.3)),
        "ent_coef": ("log", 1e-8, 1e-2),
        "max_grad_norm": ("float", 0.3, 2.0),
        "log_std_init": ("float", -2.0, 0.5),
        "net_arch": ("choice", ("small", "medium")),
        "activation_fn": ("choice", ("tanh", "relu")),
    },
    "sac": {
        "learning_rate": ("log", 1e-4, 3e-3),
        "batch_size": ("choice", (64, 128, 256, 512)),
        "one_minus_gamma": ("log", 1e-3, 5e-2),
        "tau": ("log", 1e-3, 5e-2),
        "train_freq": ("choice", (1, 2, 4, 8)),                 # gradient_steps the same: one per vector step
        "net_arch": ("choice", ("small", "medium", "big")),
    },
}
#: network widths of the ``net_arch`` choices (two hidden layers)
_WIDTHS = {"ppo": {"small": 64, "medium": 256}, "sac": {"small": 64, "medium": 128, "big": 256}}

#: the documented defaults (:mod:`trajopt.rl.hyperparams`) as a point of :data:`SPACES`: the first trial
DEFAULT_PARAMS: dict[str, dict[str, Any]] = {
    "ppo": {"n_steps_total": 1024, "batch_size": 64, "n_epochs": 10, "learning_rate": 3e-4, "one_minus_gamma": 0.01,
            "one_minus_gae_lambda": 0.05, "clip_range": 0.2, "ent_coef": 1e-8, "max_grad_norm": 0.5,
            "log_std_init": 0.0, "net_arch": "small", "activation_fn": "tanh"},
    "sac": {"learning_rate": 3e-4, "batch_size": 256, "one_minus_gamma": 0.01, "tau": 0.005, "train_freq": 1,
            "net_arch": "medium"},
}


def check_algo(algo: str) -> str:
    if not isinstance(algo, str) or algo.lower() not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    return algo.lower()


def sample_hyperparams(trial, algo: str) -> dict[str, Any]:
    """The parameters of :data:`SPACES` ``[algo]`` drawn by an Optuna ``trial`` (a dict of their values)."""
    params: dict[str, Any] = {}
    for name, (how, *range_) in SPACES[check_algo(algo)].items():
        if how == "choice":
            params[name] = trial.suggest_categorical(name, list(range_[0]))
        else:
            params[name] = trial.suggest_float(name, range_[0], range_[1], log=how == "log")
    return params


def hyperparams_of(params: dict[str, Any], algo: str, *, n_envs: int = SUITE_N_ENVS,
                   timesteps: int | None = SUITE_TIMESTEPS) -> dict[str, Any]:
    """The Stable-Baselines3 keywords of a point of :data:`SPACES` (``params``): the documented
    defaults with the drawn values in their place. ``activation_fn`` stays a name ("tanh", "relu"),
    which :func:`trajopt.rl.training.train` turns into the PyTorch module (and ``--hp`` can
    say). ValueError naming a parameter that is missing, unknown or outside its range."""
    algo = check_algo(algo)
    space = SPACES[algo]
    if set(params) != set(space):
        raise ValueError(f"{algo} parameters must be exactly {sorted(space)}; missing "
                         f"{sorted(set(space) - set(params))}, unknown {sorted(set(params) - set(space))}")
    for name, (how, *range_) in space.items():
        v = params[name]
        inside = (v in range_[0]) if how == "choice" else (
            isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and range_[0] <= v <= range_[1])
        if not inside:
            where = f"one of {list(range_[0])}" if how == "choice" else f"in [{range_[0]:g}, {range_[1]:g}]"
            raise ValueError(f"{algo} parameter {name} must be {where}, got {v!r}")
    hp = default_hyperparams(algo, n_envs=n_envs, timesteps=timesteps)
    width = _WIDTHS[algo][params["net_arch"]]
    p = dict(params)
    hp["gamma"] = 1.0 - float(p.pop("one_minus_gamma"))
    hp["learning_rate"] = float(p.pop("learning_rate"))
    hp["batch_size"] = int(p.pop("batch_size"))
    if algo == "ppo":
        hp["n_steps"], hp["batch_size"] = ppo_rollout(p.pop("n_steps_total"), hp["batch_size"], n_envs=n_envs,
                                                      timesteps=timesteps)
        hp["gae_lambda"] = 1.0 - float(p.pop("one_minus_gae_lambda"))
        hp["n_epochs"] = int(p.pop("n_epochs"))
        hp["clip_range"] = float(p.pop("clip_range"))
        hp["ent_coef"] = float(p.pop("ent_coef"))
        hp["max_grad_norm"] = float(p.pop("max_grad_norm"))
        hp["policy_kwargs"] = dict(net_arch=dict(pi=[width, width], vf=[width, width]),
                                   log_std_init=float(p.pop("log_std_init")), activation_fn=p.pop("activation_fn"))
    else:
        hp["tau"] = float(p.pop("tau"))
        hp["train_freq"] = hp["gradient_steps"] = int(p.pop("train_freq"))
        hp["policy_kwargs"] = dict(net_arch=[width, width])
    p.pop("net_arch")
    assert not p, p                                  # every parameter of the space is used
    return hp


def hp_overrides(hp: dict[str, Any], algo: str, *, n_envs: int = SUITE_N_ENVS,
                 timesteps: int = SUITE_TIMESTEPS, base: dict[str, Any] | None = None) -> list[str]:
    """The ``KEY=VALUE`` overrides (``trajopt rl train --hp``) of ``hp`` that differ from ``base``:
    what ``trajopt rl train`` starts from on the id (:func:`~.tuned.task_hyperparams`; default the
    documented defaults)."""
    if base is None:
        base = default_hyperparams(algo, n_envs=n_envs, timesteps=timesteps)
    out = []
    for key, value in hp.items():
        if base.get(key) != value:
            text = ("dict(" + ", ".join(f"{k}={v!r}" for k, v in value.items()) + ")") if isinstance(value, dict) \
                else repr(value)
            out.append(f"{key}={text}")
    return out


