"""What a co-design starts from, checked before anything is written: a given baseline gait
(``--baseline``), the design's parameters, and the summary of a finished co-design in ``--out``
(:mod:`trajopt.codesign.run` decides with them what the folder allows)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from soft_envs.envs import robot_fingerprint

from ..optim.motor_limit import motor_model_of
from ..results.result import Result
from ..results.robot_match import describe_difference

__all__ = ["check_baseline", "check_design", "read_summary"]


def check_baseline(path: Path, env, robot: str, motor_model: str) -> Result:
    """The given baseline (``--baseline``), checked: a ``--speed max`` result (the shipped
    design's fastest gait within the motors' limit) of the same robot, contact law, physics steps
    and motor model."""
    res = Result.load(path)
    changed = describe_difference(res.robot_fingerprint, robot_fingerprint(env.robot)) \
        if res.robot_fingerprint else "it records no robot"
    if changed:
        raise ValueError(f"{path}: the baseline was not made on {robot} ({changed})")
    if res.settings.get("contact") != env.contact_model:
        raise ValueError(f"{path}: the baseline was made under the {res.settings.get('contact')!r} contact law, "
                         f"the co-design runs under {env.contact_model!r} (--contact)")
    if not res.settings.get("motor_limit"):
        raise ValueError(f"{path}: the baseline was made without the motors' speed limit")
    if motor_model_of(res.settings) != motor_model:
        raise ValueError(f"{path}: the baseline was made under the {motor_model_of(res.settings)!r} motor model, "
                         f"the co-design runs under {motor_model!r} (--motor-model)")
    if int(res.settings.get("substeps", 1)) != int(env.substeps):
        raise ValueError(f"{path}: the baseline was made with {res.settings.get('substeps', 1)} physics steps per "
                         f"control step, the co-design runs with {env.substeps}")
    if res.task != "walk" or "search" not in res.settings:
        raise ValueError(f"{path}: not a --speed max result (a {res.task} of {res.settings.get('n_cycle')} steps a "
                         f"cycle at a target of {res.settings.get('speed_bl_per_min')} BL/min): the co-design's ratio "
                         "is against the shipped design's fastest gait within the motors' limit; make it with "
                         f"trajopt optimize {robot} --speed max{' --contact ' + env.contact_model if env.contact_model else ''}"
                         ", or leave --baseline out (the co-design then runs that search first)")
    return res


def check_design(design, vary, source: str) -> None:
    """Refuse a design with nothing to vary (every parameter's bounds equal)."""
    if not len(design):
        raise ValueError(f"{source}: [design] declares no parameter of the kinds {', '.join(vary)}")
    bounds = np.asarray(design.bounds, dtype=np.float64)
    if not (bounds[:, 1] > bounds[:, 0]).any():
        raise ValueError(f"{source}: [design] leaves nothing to vary: every parameter of {', '.join(vary)} has "
                         "equal bounds")


def read_summary(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise ValueError(f"{path}: not a readable co-design summary ({err}); start afresh with --overwrite, or "
                         "choose another --out") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not a co-design summary (a {type(data).__name__}); start afresh with "
                         "--overwrite, or choose another --out")
    return data
