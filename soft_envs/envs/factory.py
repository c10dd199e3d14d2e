"""Gradient environments for trajopt: :func:`make_gradient_env` builds a bare one for a robot,
:func:`as_gradient_env` finds the :class:`~soft_envs.envs.protocol.GradientEnv` in a (wrapped)
environment. Apart from :mod:`.protocol` because it knows the shipped robots' classes (which
import the protocol for their documentation)."""
from __future__ import annotations

import os
from typing import Any

from ..sim import Box, Robot, load_robot, with_box
from ..sim.ground import HeightField
from ..sim.motors import TORQUE_SPEED
from .base import PAPER_TIMESTEP, SoftRobotEnv
from .protocol import GRADIENT_ENV_MEMBERS, GradientEnv
from .puppy import SoftPuppyEnv
from .tripod import SoftTripodEnv

__all__ = ["as_gradient_env", "make_gradient_env"]


def make_gradient_env(robot: str | os.PathLike | Robot = "puppy", *, incline_deg: float = 0.0,
                      heading_deg: float = 0.0, timestep: float = PAPER_TIMESTEP,
                      contact: str | None = None, substeps: int | None = None,
                      motor_model: str = TORQUE_SPEED, ground: HeightField | None = None,
                      box: Box | None = None) -> SoftRobotEnv:
    """A bare environment for trajectory optimisation, reset without noise: its rollouts start
    at the exact rest state with the motors at ``robot.u_rest``.

    ``robot``: a shipped robot name (``"tripod"``, ``"puppy"``: their registered classes), a
    robot.toml path or a :class:`~soft_envs.sim.Robot`; the ground slopes by ``incline_deg``,
    rising along ``heading_deg`` (degrees from +x towards +z); ``timestep`` is the control step
    [s] (one row of a rollout's controls); ``contact`` the contact law ("paper", "coulomb"; None:
    the robot file's); ``substeps`` the physics steps per control step (None: the law's default,
    :attr:`~soft_envs.sim.contact.ContactLaw.default_substeps`); ``motor_model`` the motors' law of
    its steps (:mod:`soft_envs.sim.motors`; rollouts apply controls as given, whatever the law);
    ``ground`` a :class:`~soft_envs.sim.ground.HeightField` to stand on (None: the robot file's
    ``[ground]``, or the plane y = 0); ``box`` a :class:`~soft_envs.sim.Box` added to the robot
    (:func:`~soft_envs.sim.with_box`: a payload to carry, a box to push; None: none)."""
    if box is not None:
        robot = with_box(robot if isinstance(robot, Robot) else load_robot(robot), box)
    shipped = {"tripod": SoftTripodEnv, "puppy": SoftPuppyEnv}
    cls = shipped.get(robot, SoftRobotEnv) if isinstance(robot, str) else SoftRobotEnv
    env = cls(robot, incline_deg=incline_deg, target_heading_deg=heading_deg, timestep=timestep,
              reset_noise_scale=0.0, contact=contact, substeps=substeps, motor_model=motor_model, ground=ground)
    env.reset(seed=0)
    return env


def as_gradient_env(env_or_robot: Any, *, incline_deg: float = 0.0, heading_deg: float = 0.0,
                    contact: str | None = None, substeps: int | None = None) -> GradientEnv:
    """The :class:`GradientEnv` of a (wrapped) environment, i.e. its ``unwrapped`` object, or
    :func:`make_gradient_env` of a :class:`~soft_envs.sim.Robot`, a robot name or a robot.toml
    path. TypeError when the environment lacks a member of the protocol."""
    if isinstance(env_or_robot, (Robot, str, os.PathLike)):
        return make_gradient_env(env_or_robot, incline_deg=incline_deg, heading_deg=heading_deg, contact=contact,
                                 substeps=substeps)
    target = getattr(env_or_robot, "unwrapped", env_or_robot)
    missing = [name for name in GRADIENT_ENV_MEMBERS if not hasattr(target, name)]
    if missing:
        raise TypeError(f"{type(target).__name__} does not offer the gradient hook(s) {missing} "
                        "(see soft_envs.envs.protocol.GradientEnv)")
    return target
