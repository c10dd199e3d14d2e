"""Trajectory optimisation of cable-driven soft robot gaits (Bern et al., RSS 2019, III-IV).

``optimize_gait(env, task="walk")`` returns a :class:`Result`; see :mod:`trajopt.optimize`.
Depends on ``soft_envs``, never the reverse.
"""
from .gauss_newton import GaussNewtonOptions, gauss_newton
from .objectives import ObjectiveWeights
from .optimize import optimize_gait
from .parameterization import GaitParameterization
from .results import Result

__all__ = ["optimize_gait", "Result", "GaitParameterization", "ObjectiveWeights",
           "GaussNewtonOptions", "gauss_newton"]
