"""The tasks a gait is optimised for, as objects: :data:`TASKS` (walk, turn, incline, custom).

A task says everything that differs between tasks, so that no other module asks for a task by
its name:

* its target COM path (:meth:`Task.target_path`, paper eq. 5, Fig. 3) and, when the body must
  also face along it, the target heading (:meth:`Task.target_heading`, the heading term of
  :mod:`trajopt.optim.objectives`);
* its gait shape, as overrides of the :class:`~trajopt.optim.gait.GaitSpec` defaults
  (:attr:`Task.gait_defaults`; :meth:`GaitSpec.for_task <trajopt.optim.gait.GaitSpec.for_task>`);
* its objective weights, as overrides of the :class:`~trajopt.optim.objectives.ObjectiveWeights`
  defaults (:attr:`Task.weight_defaults`; :meth:`ObjectiveWeights.for_task
  <trajopt.optim.objectives.ObjectiveWeights.for_task>`);
* its default contact law (:attr:`Task.contact`, None: the robot file's);
* whether it walks on the slope ``--angle`` (:attr:`Task.on_slope`), and how its speed is
  reported (:attr:`Task.speed_along_path`: along the COM path, for a curved target);
* the benchmark task of :mod:`soft_envs.envs.tasks` it is the open-loop objective of
  (:attr:`Task.env_task`), whose slope or ground at ``--difficulty`` it walks on
  (:meth:`Task.environment`: :func:`soft_envs.envs.tasks.task_keywords`) and on whose Gymnasium
  id its gait is scored (:mod:`trajopt.tasks.play`).

Every benchmark task is a task here (:data:`ENV_TASKS`): walk and turn as they are, the slopes,
rough terrain, the step and the trench as the walk on their ground, carrying a payload and
pushing a box as the walk with the task's box added to the robot (the payload on its top, the box
ahead of it), and reaching a goal as the walk along ``--heading`` (a goal in a fixed direction; a
goal drawn anew at each reset needs a closed loop: docs/tasks.md).

Adding a task is one subclass of :class:`Task` and one line in :data:`TASKS` (a test shows it).
This module imports nothing heavy at import time: the command line reads the task names here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

__all__ = ["Task", "Walk", "Turn", "Incline", "Custom", "OnTaskGround", "TASKS", "ENV_TASKS", "get_task",
           "command_line_tasks", "speed_along_path", "TURN_KEYFRAMES", "TURN_INTERPOLATION", "TURN_HEADING_WEIGHT"]

#: keyframes per cycle of the turn (the walk and incline keep the paper's 4): with 4, a leg makes
#: one stride per 72-step cycle, and the Puppy cannot both walk and turn a quarter circle in two
#: such strides; 12 let each leg make up to three strides per cycle (:mod:`trajopt.optim.gait`)
TURN_KEYFRAMES = 12
#: how the turn's keyframes are joined (:data:`trajopt.optim.gait.INTERPOLATIONS`): straight lines, so
#: under the motors' speed limit a cable can move at the motor's full speed (the paper's
#: zero-tangent spline peaks at 1.5x its mean slope: 2/3 of it). Puppy right turn under the limit,
#: Coulomb law, 10 iterations from the Coulomb walk: +68.7 deg over the horizon, +33.8 per cycle,
#: 6.1 BL/min along the path, linear; +47.9, +24.4, 3.4 BL/min with the spline (README)
TURN_INTERPOLATION = "linear"
#: the turn's heading weight: a heading error of 1 rad costs as much as a COM error of 1 body
#: length (weights 0.1 and 0.3 turned less)
TURN_HEADING_WEIGHT = 1.0


@dataclass(frozen=True)
class Task:
    """A straight walk at a speed along a heading; subclasses change what differs.

    ``gait_defaults`` / ``weight_defaults``: overrides of the GaitSpec / ObjectiveWeights field
    defaults; ``contact``: the contact law the task runs on when none is chosen (None: the robot
    file's); ``on_slope``: the environment's ground is tilted by the slope angle;
    ``speed_along_path``: the task's speed is reported along the COM path (a curved target);
    ``needs_target``: the caller gives the target path (not offered on the command line);
    ``env_task``: the benchmark task (a key of ``soft_envs.TASKS``) it is the objective of."""

    name: str = "walk"
    gait_defaults: Mapping[str, Any] = field(default_factory=dict)
    weight_defaults: Mapping[str, Any] = field(default_factory=dict)
    contact: str | None = None
    on_slope: bool = False
    speed_along_path: bool = False
    needs_target: bool = False
    env_task: str | None = None

    def environment(self, robot, difficulty: str | None = None) -> dict[str, Any]:
        """The keywords of :func:`soft_envs.envs.make_gradient_env` that put ``robot`` on this
        task's ground at ``difficulty`` (None: the task's default level): a slope's
        ``incline_deg``, a terrain's ``ground`` (:func:`soft_envs.envs.tasks.task_keywords`, the
        rough terrain's of seed 0); ``{}`` on the plane."""
        if self.env_task is None:
            return {}
        from soft_envs.envs.tasks import DEFAULT_DIFFICULTY, task_keywords
        return task_keywords(self.env_task, robot, difficulty or DEFAULT_DIFFICULTY)

    def target_path(self, start, n_steps: int, dt: float, speed: float, heading_deg: float,
                    turn: str = "right"):
        """The target COM path (n_steps + 1, 2) [m] from ``start`` (x, z) at ``speed`` [m/s]
        along ``heading_deg`` (``turn``: the side of a turn; unused here)."""
        from .targets import straight_line
        return straight_line(start, n_steps, dt, speed, heading_deg)

    def target_heading(self, n_steps: int, dt: float, speed: float, turn: str = "right"):
        """Target headings (n_steps + 1,) [rad] relative to the start for the heading term, or
        None when the task does not track the body's heading."""
        return None


@dataclass(frozen=True)
class Walk(Task):
    """Paper IV-A: a straight line at a constant speed, bilaterally symmetric gait."""

    name: str = "walk"
    env_task: str | None = "walk"


@dataclass(frozen=True)
class OnTaskGround(Walk):
    """The walk on a benchmark task's slope or ground (:attr:`env_task`: slope up or down, rough
    terrain, a step, a trench; the level from ``--difficulty``), with its box (carry a payload,
    push a box: the robot's COM walks, the box rides or is pushed), or along ``--heading``
    towards a goal (reach a goal): the same objective as the walk."""


@dataclass(frozen=True)
class Incline(Task):
    """Paper IV-C: the walk on ground tilted by the slope angle (gravity rotated); the same
    objective."""

    name: str = "incline"
    on_slope: bool = True


@dataclass(frozen=True)
class Turn(Task):
    """Paper IV-B: a quarter circle to the ``turn`` side, symmetry off, :data:`TURN_KEYFRAMES`
    keyframes joined by straight lines (:data:`TURN_INTERPOLATION`: the motors' full speed under
    their limit), the body's heading tracked along the arc, and the Coulomb law: the turn pivots
    on feet that stick, which the paper's viscous-like friction cannot hold (with it the Puppy
    turns 36 degrees per cycle, 74 over the horizon; with Coulomb 43, 89: without the motors'
    limit, with the spline)."""

    name: str = "turn"
    gait_defaults: Mapping[str, Any] = field(
        default_factory=lambda: {"n_keyframes": TURN_KEYFRAMES, "symmetry": False,
                                 "interpolation": TURN_INTERPOLATION})
    weight_defaults: Mapping[str, Any] = field(default_factory=lambda: {"heading": TURN_HEADING_WEIGHT})
    contact: str | None = "coulomb"
    speed_along_path: bool = True
    env_task: str | None = "turn"

    def target_path(self, start, n_steps, dt, speed, heading_deg, turn="right"):
        from .targets import quarter_circle
        return quarter_circle(start, n_steps, dt, speed, heading_deg, direction=turn)

    def target_heading(self, n_steps, dt, speed, turn="right"):
        from .targets import quarter_circle_heading
        return quarter_circle_heading(n_steps, dt, speed, 0.0, turn)


@dataclass(frozen=True)
class Custom(Task):
    """A target path given as an array (``optimize_gait(..., target=...)``)."""

    name: str = "custom"
    needs_target: bool = True

    def target_path(self, start, n_steps, dt, speed, heading_deg, turn="right"):
        raise ValueError("task 'custom' needs a target array (optimize_gait(..., target=...))")


#: name -> task; adding a task: a subclass of Task and one line here (or ``TASKS[name] = task``)
TASKS: dict[str, Task] = {t.name: t for t in (Walk(), Turn(), Incline(), Custom())}
TASKS.update({name: OnTaskGround(name=name, env_task=name)
              for name in ("slope_up", "slope_down", "rough_terrain", "climb_step", "cross_trench", "reach_goal",
                           "carry", "push_box")})
#: benchmark task (``soft_envs.TASKS``) -> the task here that is its open-loop objective
ENV_TASKS: dict[str, str] = {t.env_task: name for name, t in TASKS.items() if t.env_task is not None}


def get_task(name: str) -> Task:
    """The task called ``name``; a ValueError naming the known ones otherwise."""
    try:
        return TASKS[name]
    except (KeyError, TypeError):
        raise ValueError(f"task must be one of {tuple(TASKS)}, got {name!r}") from None


def speed_along_path(name: str) -> bool:
    """Whether a result of task ``name`` reports its speed along its COM path (a curved target,
    the turn) rather than along the target's direction; False for names that are no task ("rl")."""
    return name in TASKS and TASKS[name].speed_along_path


def command_line_tasks() -> list[str]:
    """The tasks ``trajopt optimize --task`` offers (those that make their own target)."""
    return [name for name, t in TASKS.items() if not t.needs_target]
