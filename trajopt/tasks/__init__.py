"""What a gait is optimised for: the tasks (:mod:`.registry`: walk, turn, incline, custom) and
their target paths (:mod:`.targets`); each benchmark task's score (:mod:`.scores`) and a
gait or policy played on its Gymnasium id (:mod:`.play`).

``from trajopt.tasks import TASKS, get_task`` reads the registry, which imports nothing heavy
(the command line lists the task names from it); :mod:`.targets` needs :mod:`soft_envs.envs`.
"""
from .registry import (Task, Walk, Turn, Incline, Custom, OnTaskGround, TASKS, ENV_TASKS, get_task, command_line_tasks, speed_along_path,
    TURN_KEYFRAMES, TURN_INTERPOLATION, TURN_HEADING_WEIGHT)

__all__ = ["Task", "Walk", "Turn", "Incline", "Custom", "OnTaskGround", "TASKS", "ENV_TASKS", "get_task", "command_line_tasks",
           "speed_along_path", "TURN_KEYFRAMES", "TURN_INTERPOLATION", "TURN_HEADING_WEIGHT"]
