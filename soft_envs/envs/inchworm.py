"""``SoftInchworm-v2``: the five-motor Inchworm, a strip on two feet made with ``trajopt mesh``.

The specification (spaces, rewards, arguments) is :class:`SoftInchwormEnv`'s docstring, built by
:func:`~.env_docs.env_docstring` from the robot's own parts below (``help(SoftInchwormEnv)``).
"""
from __future__ import annotations

import os
from typing import Any

from ..sim import Robot
from .base import SoftRobotEnv
from .env_docs import RobotDoc, env_docstring

__all__ = ["SoftInchwormEnv"]

#: what the environment's specification says about the Inchworm
DOC = RobotDoc(
    name="inchworm", env_name="SoftInchworm",
    description="""
The *Inchworm* (docs/robots.md): a 14 cm foam strip, 15 mm thick, on two full-width feet
(26 g), carrying a 70 g motor assembly on top, meshed from a closed surface by `trajopt mesh`
(157 nodes, 467 tets) and simulated with linear tetrahedral finite elements (neo-Hookean
foam), implicit Euler time stepping, ground contact with friction, and cables modelled as
one-sided springs. It has no left or right legs: each foot has two motors pulling a pair of
cables along its front and its back face, and a fifth motor winds a pair of belly cables
under the strip between the feet, which humps the strip and draws the feet together (an
inchworm's stride). The goal is to walk forward (+x at rest) or uphill (`incline_deg`).""",
    actions=(("Contraction of the fore foot's front-face cables", "fore_foot_front"),
             ("Contraction of the fore foot's back-face cables", "fore_foot_back"),
             ("Contraction of the hind foot's front-face cables", "hind_foot_front"),
             ("Contraction of the hind foot's back-face cables", "hind_foot_back"),
             ("Contraction of the belly cables (humps the strip, draws the feet together)", "belly")),
    n_tendons=10,
    tendons="fore_foot_front_a, fore_foot_front_b, fore_foot_back_a, fore_foot_back_b, hind_foot_front_a, "
            "hind_foot_front_b, hind_foot_back_a, hind_foot_back_b, belly_a, belly_b",
    contractions="fore_foot_front, fore_foot_back, hind_foot_front, hind_foot_back, belly",
    body_length_m=0.14,
    example='env = gym.make("SoftInchworm-v2", frame_skip=2)',
    versions=("v2",),
)


class SoftInchwormEnv(SoftRobotEnv):
    __doc__ = env_docstring(DOC)

    def __init__(self, robot: str | os.PathLike | Robot = "inchworm", **kwargs: Any):
        super().__init__(robot, **kwargs)
