"""The ``difficulty`` keyword of the benchmark's tasks: its levels and what each scales.

Every task takes ``difficulty`` = ``"easy"``, ``"medium"`` (the default) or ``"hard"``; each
level sets the parameters of :data:`LEVELS` (lengths in body lengths *L* of the robot, so the
Tripod and the Puppy meet the same task at their own scale). Anything else is a ValueError naming
the keyword and the value.
"""
from __future__ import annotations

from typing import Any

from ..domain import DEFAULT_DOMAIN_RANDOMIZATION

__all__ = ["DIFFICULTIES", "DEFAULT_DIFFICULTY", "LEVELS", "SCALES", "check_difficulty", "level"]

DIFFICULTIES = ("easy", "medium", "hard")
DEFAULT_DIFFICULTY = "medium"

#: the physical parameters randomised at each reset (``domain_randomization``) by the walk and
#: turn tasks: none, mild, the project's default ranges
_RANDOMIZATION = {
    "easy": None,
    "medium": {"friction": (0.85, 1.15), "payload_mass": (0.95, 1.05)},
    "hard": dict(DEFAULT_DOMAIN_RANDOMIZATION),
}

#: per task, per level, the parameters the level sets (see each task's Arguments section)
LEVELS: dict[str, dict[str, dict[str, Any]]] = {
    "walk": {k: {"domain_randomization": v} for k, v in _RANDOMIZATION.items()},
    "turn": {k: {"domain_randomization": v} for k, v in _RANDOMIZATION.items()},
    "slope_up": {"easy": {"incline_deg": 5.0}, "medium": {"incline_deg": 10.0}, "hard": {"incline_deg": 15.0}},
    "slope_down": {"easy": {"incline_deg": -5.0}, "medium": {"incline_deg": -10.0}, "hard": {"incline_deg": -15.0}},
    "rough_terrain": {"easy": {"amplitude_bl": 0.007}, "medium": {"amplitude_bl": 0.014},
                      "hard": {"amplitude_bl": 0.021}},
    "climb_step": {"easy": {"height_bl": 0.03}, "medium": {"height_bl": 0.06}, "hard": {"height_bl": 0.1}},
    "cross_trench": {"easy": {"length_bl": 0.1}, "medium": {"length_bl": 0.2}, "hard": {"length_bl": 0.35}},
    "reach_goal": {"easy": {"distance_bl": 0.5, "half_angle_deg": 30.0},
                   "medium": {"distance_bl": 1.0, "half_angle_deg": 90.0},
                   "hard": {"distance_bl": 1.5, "half_angle_deg": 180.0}},
    "carry": {"easy": {"mass_fraction": 0.1, "friction_coefficient": 0.8},
              "medium": {"mass_fraction": 0.25, "friction_coefficient": 0.6},
              "hard": {"mass_fraction": 0.5, "friction_coefficient": 0.4}},
    "push_box": {"easy": {"mass_fraction": 0.1}, "medium": {"mass_fraction": 0.25}, "hard": {"mass_fraction": 0.5}},
}

#: per task, what ``difficulty`` scales (one line, for the documentation)
SCALES = {
    "walk": "the physical parameters drawn at each reset (`domain_randomization`)",
    "turn": "the physical parameters drawn at each reset (`domain_randomization`)",
    "slope_up": "the slope's angle (`incline_deg`)",
    "slope_down": "the slope's angle (`incline_deg`, negative: downhill)",
    "rough_terrain": "the terrain's RMS height",
    "climb_step": "the step's height",
    "cross_trench": "the trench's length along the heading",
    "reach_goal": "the goal's distance and the range of its direction",
    "carry": "the payload's mass (a fraction of the robot's) and its friction coefficient on the robot",
    "push_box": "the box's mass (a fraction of the robot's)",
}


def check_difficulty(value: Any) -> str:
    """``value`` if it is a level, else ValueError naming the keyword and the value."""
    if not (isinstance(value, str) and value in DIFFICULTIES):
        raise ValueError(f"difficulty must be one of {', '.join(map(repr, DIFFICULTIES))}, got {value!r}")
    return value


def level(task: str, difficulty: Any) -> dict[str, Any]:
    """The parameters ``difficulty`` sets for ``task`` (a copy)."""
    return dict(LEVELS[task][check_difficulty(difficulty)])
