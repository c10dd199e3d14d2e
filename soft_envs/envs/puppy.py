"""``SoftPuppy-v0`` / ``-v1`` / ``-v2``: the eight-motor quadruped Puppy of Bern et al. (RSS 2019), section IV-B.

The specification (spaces, rewards, arguments) is :class:`SoftPuppyEnv`'s docstring, built by
:func:`~.env_docs.env_docstring` from the robot's own parts below (``help(SoftPuppyEnv)``).
"""
from __future__ import annotations

import os
from typing import Any

from ..sim import Robot
from .base import SoftRobotEnv
from .env_docs import RobotDoc, env_docstring

__all__ = ["SoftPuppyEnv"]

#: the legs in motor order, and the faces of a leg its two motors pull along
_LEGS = ("hind left", "hind right", "fore left", "fore right")
_FACES = ("front", "back")

#: what the environment's specification says about the Puppy
DOC = RobotDoc(
    name="puppy", env_name="SoftPuppy",
    description="""
The *Puppy* of Bern, Banzet, Poranne and Coros, "Trajectory optimization for cable-driven
soft robot locomotion" (Robotics: Science and Systems 2019), section IV-B: a 13 cm,
four-legged foam body (90 g) carrying a 140 g motor assembly on top (top-heavy), simulated
with linear tetrahedral finite elements (neo-Hookean foam, about 200 nodes in the shipped
mesh), implicit Euler time stepping, ground contact with friction, and cables modelled as
one-sided springs. Each leg has two motors, one pulling a pair of cables along the front
face of the leg and one along the back face, so the cables bend the legs in the sagittal
plane; left and right motors are mirror pairs. The goal is to walk forward (+x at rest),
uphill (`incline_deg`), or to turn (`task="turn"`; the paper turns right, using a straight
leg as a pivot).""",
    actions=tuple((f"Contraction of the {leg} leg's {face}-face cables", f"{leg.replace(' ', '_')}_{face}")
                  for leg in _LEGS for face in _FACES),
    n_tendons=16,
    tendons="the 16 tendons in robot.toml order (hind_left_front_a, hind_left_front_b, hind_left_back_a, ..., "
            "fore_right_back_b: motor 0's pair first)",
    contractions="motors 0-7 (Action Space order)",
    body_length_m=0.13,
    example='env = gym.make("SoftPuppy-v2", incline_deg=10.0, domain_randomization={"friction": (0.7, 1.3)})',
)


class SoftPuppyEnv(SoftRobotEnv):
    __doc__ = env_docstring(DOC)

    def __init__(self, robot: str | os.PathLike | Robot = "puppy", **kwargs: Any):
        super().__init__(robot, **kwargs)
