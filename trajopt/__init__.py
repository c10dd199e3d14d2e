"""Trajectory optimisation of cable-driven soft robot gaits (Bern et al., RSS 2019, III-IV).

``optimize_gait(env, task="walk")`` returns a :class:`Result`; see :mod:`trajopt.optim.optimize`.

The package is laid out by role (docs/architecture.md draws the map):

* :mod:`trajopt.optim`: the optimisation core (Gauss-Newton, the QP step, objectives, the
  keyframe parameterisation, the gait's shape, the motors' limits);
* :mod:`trajopt.tasks`: what a gait is optimised for (walk, turn, incline) and its target path;
* :mod:`trajopt.results`: result files, their checks, the robot fingerprint, atomic writes;
* :mod:`trajopt.calibration`, :mod:`trajopt.robustness`, :mod:`trajopt.codesign`: fitting the
  model to markers, gaits under perturbed physics, robot and gait optimised together;
* :mod:`trajopt.cli` (the ``trajopt`` command), :mod:`trajopt.rl` (the Stable-Baselines3
  baseline), :mod:`trajopt.sweep` (Ray sweeps), :mod:`trajopt.hardware` (RoboClaw playback);
* beside them: :mod:`.optimize_run` (a run's files, checkpoints and resume), :mod:`.fastest`
  (``--speed max``), :mod:`.evaluation` and :mod:`.replay` (playing controls back),
  :mod:`.plots`, :mod:`.argtypes`, :mod:`.progress`.

This layer reaches the physics only through the environments' gradient protocol and the names
:mod:`soft_envs.envs` exports (:class:`~soft_envs.envs.GradientEnv`,
:func:`~soft_envs.envs.make_gradient_env`, ``SimulationError``, body-frame measurements); no
module under ``trajopt/`` imports :mod:`soft_envs.sim`, and nothing in ``soft_envs`` imports
``trajopt``. ``import trajopt`` is light: the names below are loaded on first use (PEP 562), so
``import trajopt.hardware`` (which reads result files and talks to motor controllers) needs
neither ``soft_envs``, numba nor scipy. :mod:`trajopt.rl` imports Stable-Baselines3 only when a
model is trained or loaded.
"""
from __future__ import annotations

import importlib
from typing import Any

__all__ = ["optimize_gait", "OptimizeSettings", "Result", "GaitSpec", "GaitParameterization", "ObjectiveWeights",
           "GaussNewtonOptions", "measure_gait", "evaluate_controls", "evaluate_result"]

_LAZY = {"optimize_gait": ".optim.optimize", "OptimizeSettings": ".optim.optimize_settings", "Result": ".results", "GaitSpec": ".optim.gait",
         "GaitParameterization": ".optim.parameterization", "ObjectiveWeights": ".optim.objectives",
         "GaussNewtonOptions": ".optim.gauss_newton", "measure_gait": ".evaluation",
         "evaluate_controls": ".evaluation", "evaluate_result": ".evaluation"}


def __getattr__(name: str) -> Any:          # PEP 562: load on first use
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
