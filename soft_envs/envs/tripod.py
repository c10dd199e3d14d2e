"""``SoftTripod-v0`` / ``-v1`` / ``-v2``: the two-motor Tripod of Bern et al. (RSS 2019), section IV-A.

The specification (spaces, rewards, arguments) is :class:`SoftTripodEnv`'s docstring, built by
:func:`~.env_docs.env_docstring` from the robot's own parts below (``help(SoftTripodEnv)``).
"""
from __future__ import annotations

import os
from typing import Any

from ..sim import Robot
from .base import SoftRobotEnv
from .env_docs import RobotDoc, env_docstring

__all__ = ["SoftTripodEnv"]

#: what the environment's specification says about the Tripod
DOC = RobotDoc(
    name="tripod", env_name="SoftTripod",
    description="""
The *Tripod* of Bern, Banzet, Poranne and Coros, "Trajectory optimization for cable-driven
soft robot locomotion" (Robotics: Science and Systems 2019), section IV-A: a 14 cm foam
body (24 g) with three legs and a 44 g motor assembly on top, simulated with linear
tetrahedral finite elements (neo-Hookean foam, about 150 nodes in the shipped mesh),
implicit Euler time stepping, ground contact with friction, and cables modelled as
one-sided springs.
Two motors drive the middle leg, each through a pair of cables: `front` bends it forward,
`back` bends it backward, both together lift it. The two outer legs are passive. The goal is
to walk forward (+x at rest) or, with `task="turn"`, to turn on the spot.""",
    actions=(("Contraction of the middle leg's front cables (bends it forward)", "front"),
             ("Contraction of the middle leg's back cables (bends it backward)", "back")),
    n_tendons=4, tendons="front_a, front_b, back_a, back_b", contractions="front, back",
    body_length_m=0.14,
    example='env = gym.make("SoftTripod-v2", frame_skip=2, task="turn", turn_direction="left")',
)


class SoftTripodEnv(SoftRobotEnv):
    __doc__ = env_docstring(DOC)

    def __init__(self, robot: str | os.PathLike | Robot = "tripod", **kwargs: Any):
        super().__init__(robot, **kwargs)
