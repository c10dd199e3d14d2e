"""``SoftHexapod-v2``: the twelve-motor Hexapod, a six-legged robot made with ``trajopt mesh``.

The specification (spaces, rewards, arguments) is :class:`SoftHexapodEnv`'s docstring, built by
:func:`~.env_docs.env_docstring` from the robot's own parts below (``help(SoftHexapodEnv)``).
"""
from __future__ import annotations

import os
from typing import Any

from ..sim import Robot
from .base import SoftRobotEnv
from .env_docs import RobotDoc, env_docstring

__all__ = ["SoftHexapodEnv"]

#: the legs in motor order (robot.toml), and the faces of a leg its two motors pull along
_LEGS = ("hind left", "hind right", "mid left", "mid right", "fore left", "fore right")
_FACES = ("front", "back")

#: what the environment's specification says about the Hexapod
DOC = RobotDoc(
    name="hexapod", env_name="SoftHexapod",
    description="""
The *Hexapod* (docs/robots.md): a 14 cm foam slab (77 g) on six legs, three a side (hind,
mid, fore), carrying a 180 g motor assembly on top, meshed from a closed surface by
`trajopt mesh` (183 nodes, 501 tets) and simulated with linear tetrahedral finite elements
(neo-Hookean foam), implicit Euler time stepping, ground contact with friction, and cables
modelled as one-sided springs. Each leg has two motors, one pulling a pair of cables along
the front face of the leg and one along the back face (the Puppy's layout), so the cables
bend the legs in the sagittal plane; left and right motors are mirror pairs. With six legs a
gait can keep a tripod of feet on the ground. The goal is to walk forward (+x at rest),
uphill (`incline_deg`), or to turn (`task="turn"`).""",
    actions=tuple((f"Contraction of the {leg} leg's {face}-face cables", f"{leg.replace(' ', '_')}_{face}")
                  for leg in _LEGS for face in _FACES),
    n_tendons=24,
    tendons="the 24 tendons in robot.toml order (hind_left_front_a, hind_left_front_b, hind_left_back_a, ..., "
            "fore_right_back_b: motor 0's pair first)",
    contractions="motors 0-11 (Action Space order)",
    body_length_m=0.14,
    example='env = gym.make("SoftHexapod-v2", incline_deg=5.0)',
    versions=("v2",),
)


class SoftHexapodEnv(SoftRobotEnv):
    __doc__ = env_docstring(DOC)

    def __init__(self, robot: str | os.PathLike | Robot = "hexapod", **kwargs: Any):
        super().__init__(robot, **kwargs)
