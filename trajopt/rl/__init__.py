"""RL baseline: Stable-Baselines3 PPO and SAC on the same simulator as ``trajopt``.

    trajopt rl train tripod --algo ppo --timesteps 30000 --seed 0   # results/runs/tripod_ppo_seed0/
    trajopt rl evaluate results/runs/tripod_ppo_seed0   # the trajopt metric (BL/min, upright)
    trajopt rl export results/runs/tripod_ppo_seed0     # a trajopt Result: results/tripod_ppo_seed0.npz

Python API: :func:`train` (:mod:`trajopt.rl.training`), :func:`load_policy`,
:func:`evaluate_policy_metric`, :func:`export_result` (:mod:`trajopt.rl.evaluate`); the
environment set-up in :mod:`trajopt.rl.envs` and the hyper-parameters, with the reasons for
them, in :mod:`trajopt.rl.hyperparams`.

Stable-Baselines3 (and with it PyTorch) is an optional dependency (``pip install
soft-envs[rl]``): nothing here imports it until a model is trained or loaded, so
``import trajopt`` and the ``trajopt`` command work without it.
"""
from __future__ import annotations

from typing import Any

__all__ = ["MissingRLDependencies", "require_sb3", "INSTALL_HINT", "train", "load_policy",
           "evaluate_policy_metric", "export_result", "evaluate_trajopt_result"]

INSTALL_HINT = "pip install soft-envs[rl]"


class MissingRLDependencies(ImportError):
    """stable-baselines3 / torch are not installed (the message says how to install them)."""


def require_sb3():
    """Import and return :mod:`stable_baselines3`, or raise :class:`MissingRLDependencies`
    with the install command."""
    try:
        import stable_baselines3
    except ImportError as exc:
        raise MissingRLDependencies(
            f"the RL baseline needs stable-baselines3 and PyTorch, which are not installed "
            f"({exc}); install them with: {INSTALL_HINT}") from exc
    return stable_baselines3


_LAZY = {"train": ".training", "load_policy": ".evaluate", "evaluate_policy_metric": ".evaluate",
         "export_result": ".evaluate", "evaluate_trajopt_result": ".evaluate"}


def __getattr__(name: str) -> Any:          # PEP 562: keep ``import trajopt.rl`` light
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
