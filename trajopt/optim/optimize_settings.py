"""What :func:`~trajopt.optim.optimize.optimize_gait` optimises for, and under which limits: one
object (:class:`OptimizeSettings`) instead of a dozen keyword arguments."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..evaluation import DEFAULT_EVAL_CYCLES
from .gait import GaitSpec
from .gauss_newton import GaussNewtonOptions
from .objectives import ObjectiveWeights

__all__ = ["OptimizeSettings", "settings_with"]


@dataclass(frozen=True)
class OptimizeSettings:
    """The settings of one gait optimisation (``optimize_gait(env, task, settings)``).

    Attributes:
        gait: the control trajectory's shape (:class:`~trajopt.optim.gait.GaitSpec`); None:
            ``GaitSpec.for_task(task)``, the paper's 24 + 2 x 72 steps and 4 keyframes, symmetric
            except for the turn (paper IV-B), which has 12 keyframes
            (:data:`~trajopt.tasks.TURN_KEYFRAMES`).
        speed_bl_per_min: the speed of the target COM path [body lengths per minute], tracked,
            not enforced; None: :data:`~trajopt.optim.optimize.DEFAULT_SPEED` of the robot (8.0
            for a robot of another name).
        heading_deg: the direction of the walk [deg] from +x towards +z.
        turn: the side of a turn, ``"right"`` or ``"left"``.
        target: a custom target COM path, (K+1, 2) [m] (task ``"custom"``).
        weights: the objective's weights (:class:`~trajopt.optim.objectives.ObjectiveWeights`);
            None: ``ObjectiveWeights.for_task(task)`` (the turn also tracks the body's heading).
        options: the Gauss-Newton solver's options and stopping criteria
            (:class:`~trajopt.optim.gauss_newton.GaussNewtonOptions`).
        n_seeds: starts tried besides a warm start (cheap rollouts without sensitivities;
            0 with a warm start: the warm start alone).
        eval_cycles: cycles the result is evaluated over (>= 1).
        motor_model: the motors' law the controls obey at every step they play
            (:mod:`soft_envs.sim.motors`): ``"torque-speed"`` (the torque-speed line at the
            tensions' load torque and the gearbox's torque limit, :mod:`trajopt.optim.motor_torque`),
            ``"speed"`` (the speed limit alone: the results of before the line, bit for bit) or
            ``"ideal"`` (none); None: the environment's ``motor_model`` (a robot or a name:
            ``"torque-speed"``).
        motor_limit: False is ``motor_model="ideal"`` (kept for scripts of before the line).
        ensemble: physics steps per control step of other physics the gait is optimised on as
            well (e.g. ``(2, 8)`` besides the default 4; :mod:`trajopt.optim.ensemble`).
    """

    gait: GaitSpec | None = None
    speed_bl_per_min: float | None = None
    heading_deg: float = 0.0
    turn: str = "right"
    target: np.ndarray | None = None
    weights: ObjectiveWeights | None = None
    options: GaussNewtonOptions = GaussNewtonOptions()
    n_seeds: int = 8
    eval_cycles: int = DEFAULT_EVAL_CYCLES
    motor_model: str | None = None
    motor_limit: bool = True
    ensemble: tuple[int, ...] = ()


FIELDS = frozenset(f.name for f in dataclasses.fields(OptimizeSettings))


def settings_with(settings: OptimizeSettings | None, fields: dict[str, Any]) -> OptimizeSettings:
    """``settings`` (default :class:`OptimizeSettings`) with ``fields`` replaced; a name that is
    no field is refused with a TypeError naming it, as a function's unknown keyword is."""
    if settings is not None and not isinstance(settings, OptimizeSettings):
        raise TypeError(f"settings must be an OptimizeSettings, got {type(settings).__name__}")
    unknown = sorted(set(fields) - FIELDS)
    if unknown:
        raise TypeError(f"optimize_gait() got unexpected keyword argument(s) {', '.join(map(repr, unknown))}; "
                        f"the settings are {', '.join(sorted(FIELDS))}")
    base = OptimizeSettings() if settings is None else settings
    return dataclasses.replace(base, **fields) if fields else base
