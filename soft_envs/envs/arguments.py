"""Validation of the keywords of :class:`~soft_envs.envs.base.SoftRobotEnv` (the task's own
keywords are checked by :class:`~soft_envs.envs.task.LocomotionTask`, ``domain_randomization`` by
:func:`~soft_envs.envs.domain.parse_domain_randomization`): every bad value is a ValueError naming
the keyword, raised before anything is built."""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..sim.motors import check_motor_model

__all__ = ["check_env_arguments", "is_number", "number_in", "RENDER_MODES"]

RENDER_MODES = ("human", "rgb_array")


def is_number(v: Any) -> bool:
    """A real number (Python or NumPy), not a bool."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def number_in(name: str, value: Any, low: float = -math.inf, high: float = math.inf, *, positive: bool = False,
              what: str = "") -> float:
    """``value`` as a float if it is a finite number in [low, high] (and > 0 with ``positive``),
    else a ValueError ``<name> must be a <positive|finite> number[ in [low, high]][ what], got ...``."""
    ok = is_number(value) and math.isfinite(value) and low <= value <= high and (value > 0 or not positive)
    if not ok:
        bounds = "" if (low, high) == (-math.inf, math.inf) else f" in [{low:g}, {high:g}]"
        raise ValueError(f"{name} must be a {'positive' if positive else 'finite'} number{bounds}"
                         f"{' ' + what if what else ''}, got {value!r}")
    return float(value)


def _is_integer(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def check_env_arguments(*, frame_skip: Any, timestep: Any, substeps: Any, gait_period: Any, reset_noise_scale: Any,
                        motor_speed_rpm: Any, motor_model: Any, incline_deg: Any, observe_nodes: Any, render_mode: Any,
                        width: Any, height: Any, camera_config: Any) -> None:
    """Raise ValueError naming the first bad keyword (see the module docstring)."""
    if not (_is_integer(frame_skip) and frame_skip >= 1):
        raise ValueError(f"frame_skip must be a positive integer, got {frame_skip!r}")
    if not (substeps is None or (_is_integer(substeps) and substeps >= 1)):
        raise ValueError(f"substeps must be a positive integer (physics steps per control step) or None "
                         f"(the contact law's default), got {substeps!r}")
    for name, v in (("timestep", timestep), ("gait_period", gait_period)):
        if not (is_number(v) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number [s], got {v!r}")
    if not (is_number(reset_noise_scale) and math.isfinite(reset_noise_scale) and reset_noise_scale >= 0):
        raise ValueError(f"reset_noise_scale must be a number >= 0 [m], got {reset_noise_scale!r}")
    if not (motor_speed_rpm is None or (isinstance(motor_speed_rpm, str) and motor_speed_rpm == "robot")
            or (is_number(motor_speed_rpm) and math.isfinite(motor_speed_rpm) and motor_speed_rpm > 0)):
        raise ValueError(f"motor_speed_rpm must be \"robot\" (each motor's max_speed_rpm from the robot file), a "
                         f"positive number [rpm] or None (no limit), got {motor_speed_rpm!r}")
    check_motor_model(motor_model)
    if not (is_number(incline_deg) and abs(incline_deg) < 90):
        raise ValueError(f"incline_deg must be a number in (-90, 90), got {incline_deg!r}")
    if not isinstance(observe_nodes, (bool, np.bool_)):
        raise ValueError(f"observe_nodes must be True or False, got {observe_nodes!r}")
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be one of {list(RENDER_MODES)} or None, got {render_mode!r}")
    for name, v in (("width", width), ("height", height)):
        if not (_is_integer(v) and 16 <= v <= 8192):
            raise ValueError(f"{name} must be an integer number of pixels in 16..8192, got {v!r}")
    if camera_config is not None and not isinstance(camera_config, Mapping):
        raise ValueError(f"camera_config must be a dict or None, got {type(camera_config).__name__}")
