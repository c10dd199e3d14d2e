"""The tuned hyper-parameters the RL baseline trains with on the task ids: ``trajopt/rl/zoo/tuned.toml``.

One table per algorithm and robot (``[ppo.tripod]``), written by :func:`.adopt.adopt` (``trajopt rl tune
ID --adopt``) from a study (:mod:`.study`) whose best was checked on the suite's seeds
(:mod:`.check`) and beat the defaults there. Its ``params`` (a point of
:data:`~.space.SPACES`) are used on every task id of that robot (a study is made on one id, the
walk: that they carry to the robot's other tasks is an assumption docs/tasks.md states), by
``trajopt rl train ID``, the task suite and the rl_zoo3 files (:mod:`trajopt.rl.zoo`). An
algorithm and robot without a table, and the robots' own ids (``SoftTripod-v2``: the headline's
runs), keep the documented defaults (:mod:`trajopt.rl.hyperparams`). The other keys say where the
values come from: the study's id, trials, the best trial and its score, the defaults' score, and
the check (each side's mean over the suite's seeds, and its credible mean: each run's lowest score
over its replays at other physics steps; tables adopted before the check replayed its runs lack it).
"""
from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path
from typing import Any

from ..hyperparams import ALGOS, default_hyperparams
from .space import check_algo, hyperparams_of

__all__ = ["TUNED_FILE", "read_tuned", "task_hyperparams", "tuned_text"]

#: the shipped file (package data, beside the rl_zoo3 files)
TUNED_FILE = Path(__file__).resolve().parents[1] / "zoo" / "tuned.toml"
#: what a table must hold besides ``params``
_FIELDS = {"study": str, "trials": int, "trial": int, "study_score": float, "defaults_score": float,
           "check_seeds": list, "check_best_mean": float, "check_defaults_mean": float, "score_unit": str}
#: what a table may hold: the check's credible means (tables adopted before the check replayed its runs lack them)
_OPTIONAL = {"check_best_credible": float, "check_defaults_credible": float}


def read_tuned(path: str | os.PathLike | None = None) -> dict[tuple[str, str], dict[str, Any]]:
    """The tables of ``path`` (default :data:`TUNED_FILE`) by (algorithm, robot), each checked:
    ``params`` a point of the space, the other fields of their types. A missing file is no table;
    a bad one is a ValueError naming the file and the field."""
    path = Path(TUNED_FILE if path is None else path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        return {}
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: {exc}") from None
    from ..envs import ROBOTS, robot_name, task_of
    tables: dict[tuple[str, str], dict[str, Any]] = {}
    for algo, robots in data.items():
        if algo not in ALGOS or not isinstance(robots, dict):
            raise ValueError(f"{path}: [{algo}] must be one of {ALGOS}, a table of robots")
        for robot, entry in robots.items():
            where = f"{path}: [{algo}.{robot}]"
            if robot not in ROBOTS or not isinstance(entry, dict):
                raise ValueError(f"{where}: the robot must be one of {sorted(ROBOTS)}")
            for field, kind in {**_FIELDS, "params": dict,
                                **{f: k for f, k in _OPTIONAL.items() if f in entry}}.items():
                value = entry.get(field)
                ok = isinstance(value, kind) or (kind is float and isinstance(value, int))
                if not ok or isinstance(value, bool):
                    raise ValueError(f"{where}: {field} must be a {kind.__name__}, got {value!r}")
            if task_of(entry["study"]) is None or robot_name(entry["study"]) != robot:
                raise ValueError(f"{where}: study must be a task id of the {robot}, got {entry['study']!r}")
            if entry["trials"] < 1 or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0
                                              for v in entry["check_seeds"]):
                raise ValueError(f"{where}: trials must be >= 1 and check_seeds seeds (integers >= 0)")
            bad = [f for f, kind in {**_FIELDS, **_OPTIONAL}.items() if kind is float and f in entry
                   and not math.isfinite(entry[f])]
            if bad:
                raise ValueError(f"{where}: {bad[0]} must be finite, got {entry[bad[0]]!r}")
            try:
                hyperparams_of(entry["params"], algo)
            except ValueError as exc:
                raise ValueError(f"{where}: params: {exc}") from None
            tables[(algo, robot)] = entry
    return tables


def task_hyperparams(algo: str, target: str, *, n_envs: int = 1, timesteps: int | None = None,
                     path: str | os.PathLike | None = None) -> tuple[dict[str, Any], str]:
    """The hyper-parameters the baseline trains ``algo`` with on ``target`` (a task id, a robot or
    its id), and where they come from: the tuned table of the task id's robot (``"tuned: FILE
    [algo.robot] (study ..., trial N)"``), else the documented defaults (``"defaults"``)."""
    from ..envs import robot_name, task_of
    algo = check_algo(algo)
    if task_of(target) is not None:
        path = Path(TUNED_FILE if path is None else path)
        robot = robot_name(target)
        entry = read_tuned(path).get((algo, robot))
        if entry is not None:
            hp = hyperparams_of(entry["params"], algo, n_envs=n_envs, timesteps=timesteps)
            return hp, f"tuned: {path.name} [{algo}.{robot}] (study {entry['study']}, trial {entry['trial']})"
    return default_hyperparams(algo, n_envs=n_envs, timesteps=timesteps), "defaults"


def tuned_text(tables: dict[tuple[str, str], dict[str, Any]]) -> str:
    """The TOML of ``tables`` (sorted by algorithm and robot), with the header that says what it is."""
    try:
        import tomli_w
    except ImportError:
        raise ImportError("writing the tuned values needs tomli-w: pip install soft-envs[tune]") from None
    lines = ["# The RL baseline's tuned hyper-parameters (trajopt rl tune ID --check 3 --adopt; written by",
             "# trajopt.rl.tuning.adopt). A table per algorithm and robot: its params, a point of",
             "# trajopt.rl.tuning.SPACES, are used on every task id of the robot; the others keep",
             "# trajopt/rl/hyperparams.py's defaults. docs/tasks.md, \"Tuning the baselines\".", ""]
    nested: dict[str, dict[str, Any]] = {}
    for (algo, robot) in sorted(tables):
        nested.setdefault(algo, {})[robot] = tables[(algo, robot)]
    return "\n".join(lines) + tomli_w.dumps(nested)
