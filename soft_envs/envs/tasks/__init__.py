"""The benchmark's tasks (issue #39): walk, turn, slope up, slope down, rough terrain, climb a
step, cross a trench, reach a goal, carry a payload, push a box; each a registered Gymnasium id per robot
(``SoftTripodWalk-v0``, ``SoftPuppyReachGoal-v0``, ...: :data:`soft_envs.TASK_ENV_IDS`) with a
``difficulty`` keyword (:mod:`.difficulty`) and a specification in its class docstring
(:mod:`.docs`; docs/tasks.md). The classes take the robot as their first argument
(``"tripod"``, ``"puppy"``, a robot.toml path or a Robot); every id passes its robot.
"""
from .base import TaskEnv
from .box_task import BoxTaskEnv
from .carry import CarryEnv
from .difficulty import DEFAULT_DIFFICULTY, DIFFICULTIES, LEVELS, check_difficulty
from .goal import ReachGoalEnv
from .locomotion import SlopeDownEnv, SlopeUpEnv, TurnEnv, WalkEnv
from .push import PushBoxEnv
from .terrain import ClimbStepEnv, CrossTrenchEnv, RoughTerrainEnv, task_ground, task_keywords

__all__ = ["TaskEnv", "WalkEnv", "TurnEnv", "SlopeUpEnv", "SlopeDownEnv", "RoughTerrainEnv", "ClimbStepEnv",
           "CrossTrenchEnv", "ReachGoalEnv", "BoxTaskEnv", "CarryEnv", "PushBoxEnv",
           "TASK_CLASSES", "task_ground", "task_keywords", "DIFFICULTIES", "DEFAULT_DIFFICULTY", "LEVELS",
           "check_difficulty"]

#: task key (of :data:`~.difficulty.LEVELS`) -> its class
TASK_CLASSES = {"walk": WalkEnv, "turn": TurnEnv, "slope_up": SlopeUpEnv, "slope_down": SlopeDownEnv,
                "rough_terrain": RoughTerrainEnv, "climb_step": ClimbStepEnv, "cross_trench": CrossTrenchEnv,
                "reach_goal": ReachGoalEnv, "carry": CarryEnv, "push_box": PushBoxEnv}
