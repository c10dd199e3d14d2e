"""Trajectory optimisation of cable-driven soft robot gaits (Bern et al., RSS 2019, III-IV).

``optimize_gait(env, task="walk")`` returns a :class:`Result`; see :mod:`trajopt.optimize`.

This layer optimises, evaluates, renders, exports and plays controls. It reaches the physics
only through the environments' gradient protocol and the names :mod:`soft_envs.envs` exports
(:class:`~soft_envs.envs.GradientEnv`, :func:`~soft_envs.envs.make_gradient_env`,
``SimulationError``, body-frame measurements); no module under ``trajopt/`` imports
:mod:`soft_envs.sim`, and nothing in ``soft_envs`` imports ``trajopt``. ``import trajopt`` is
light: the names below are loaded on first use (PEP 562; the solver function is
``trajopt.gauss_newton.gauss_newton``, as ``trajopt.gauss_newton`` is its module), so ``import trajopt.hardware`` (which
reads result files and talks to motor controllers) needs neither ``soft_envs``, numba nor scipy.
:mod:`trajopt.rl` imports Stable-Baselines3 only when a model is trained or loaded.
"""
from __future__ import annotations

import importlib
from typing import Any

__all__ = ["optimize_gait", "Result", "GaitSpec", "GaitParameterization", "ObjectiveWeights",
           "GaussNewtonOptions", "measure_gait", "evaluate_controls", "evaluate_result"]

_LAZY = {"optimize_gait": ".optimize", "Result": ".results", "GaitSpec": ".gait",
         "GaitParameterization": ".parameterization", "ObjectiveWeights": ".objectives",
         "GaussNewtonOptions": ".gauss_newton", "measure_gait": ".evaluation",
         "evaluate_controls": ".evaluation", "evaluate_result": ".evaluation"}


def __getattr__(name: str) -> Any:          # PEP 562: load on first use
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
