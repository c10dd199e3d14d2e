"""Gymnasium environments of cable-driven soft robots, and the gradient protocol of trajopt.

This layer turns the physics of :mod:`soft_envs.sim` into Gymnasium environments
(``SoftTripod-v2``: :class:`SoftTripodEnv`, ``SoftPuppy-v2``: :class:`SoftPuppyEnv`,
``SoftHexapod-v2``: :class:`SoftHexapodEnv`, ``SoftInchworm-v2``: :class:`SoftInchwormEnv`, all
:class:`SoftRobotEnv`, registered on ``import soft_envs``) and offers ``trajopt`` its one way into
the physics: the :class:`GradientEnv` protocol (rollouts with exact sensitivities, the robot, the
simulation time step, the slope) with :func:`make_gradient_env` / :func:`as_gradient_env`, plus the
re-exports below (the failure exception, body-frame measurements, cable points, strain energy, the
robot fingerprint that ties a result to its robot, the physical parameters and tracked markers of
calibration, compiling the kernels ahead of a first run, and the motors' law of
:mod:`soft_envs.sim.motors`: :class:`MotorLaw`, :data:`MOTOR_MODELS`, :func:`motor_step`,
:func:`line_excess`, :func:`winding_speed`, :func:`load_torque`, :data:`MOTOR_DEFAULTS`).
It may import :mod:`soft_envs.sim`, Gymnasium, numpy and :mod:`soft_envs.render`; never
``trajopt``. The benchmark's tasks (``SoftTripodWalk-v0``, ..., docs/tasks.md) are the
subpackage :mod:`soft_envs.envs.tasks`, imported when one is made.
"""
from ..sim import Box, RolloutStopped, Robot, SimulationError, Trajectory, load_robot, with_box
from ..sim.contact import CONTACT_LAWS
from ..sim.fingerprint import robot_fingerprint
from ..sim.motors import MOTOR_MODELS, MotorLaw, check_motor_model, line_excess, load_torque, motor_step, winding_speed
from ..sim.robot import MOTOR_DEFAULTS
from ..sim.warmup import compile_ahead
from .base import MOTOR_NO_LOAD_RPM, PAPER_GAIT_PERIOD, PAPER_TIMESTEP, SoftRobotEnv, with_contact_law
from .domain import DEFAULT_DOMAIN_RANDOMIZATION
from .identification import (PHYSICAL_PARAMETERS, Marker, MarkerSet, check_parameters, parameter_values,
                             scale_parameters, with_parameters)
from .measure import (BodyFrame, cable_points, heading_vector, strain_energy_density, tilt_deg_of, wrap_angle,
                      yaw_of)
from .factory import as_gradient_env, make_gradient_env
from .protocol import GradientEnv
from .hexapod import SoftHexapodEnv
from .inchworm import SoftInchwormEnv
from .puppy import SoftPuppyEnv
from .tripod import SoftTripodEnv

__all__ = ["SoftRobotEnv", "SoftTripodEnv", "SoftPuppyEnv", "SoftHexapodEnv", "SoftInchwormEnv", "GradientEnv",
           "make_gradient_env",
           "as_gradient_env", "Robot", "Trajectory", "SimulationError", "RolloutStopped", "load_robot", "Box", "with_box",
           "robot_fingerprint",
           "BodyFrame", "yaw_of",
           "tilt_deg_of", "wrap_angle", "heading_vector", "cable_points", "strain_energy_density",
           "PAPER_TIMESTEP", "PAPER_GAIT_PERIOD", "MOTOR_NO_LOAD_RPM", "DEFAULT_DOMAIN_RANDOMIZATION",
           "PHYSICAL_PARAMETERS", "parameter_values", "with_parameters", "scale_parameters", "check_parameters", "Marker",
           "MarkerSet", "compile_ahead", "with_contact_law", "CONTACT_LAWS", "MOTOR_MODELS", "MotorLaw",
           "check_motor_model", "line_excess", "load_torque", "motor_step", "winding_speed", "MOTOR_DEFAULTS"]
