"""Gymnasium environments of cable-driven soft robots (registered on ``import soft_envs``).

``SoftTripod-v0`` (:class:`SoftTripodEnv`) and ``SoftPuppy-v0`` (:class:`SoftPuppyEnv`), both
:class:`SoftRobotEnv` subclasses offering the :class:`GradientEnv` hooks for ``trajopt``.
"""
from .base import SoftRobotEnv
from .protocol import GradientEnv
from .puppy import SoftPuppyEnv
from .tripod import SoftTripodEnv

__all__ = ["SoftRobotEnv", "SoftTripodEnv", "SoftPuppyEnv", "GradientEnv"]
