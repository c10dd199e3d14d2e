"""Reading a co-design's checkpoint, ``DIR/codesign.partial.json``, and refusing a damaged one.

The checkpoint is ``{"settings": {...}, "state": {...}}``: the run's settings (a resumed run must
have the same) and its :class:`~trajopt.codesign.joint.JointState`. :func:`read_partial` checks
every field a resumed run uses (types, finite numbers, the screening's progress) and
:func:`check_partial_sizes` the lengths once the problem is known; a damaged file (truncated,
not an object, a field missing, NaN where a number must be finite) is a ValueError of one line
naming the file and the field: the command line exits 2 and leaves the file as it is.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

from .joint import JointState
from .screen import ScreenProgress

__all__ = ["read_partial", "check_partial_sizes"]

_ADVICE = "continue it only once it is whole, or start afresh with --overwrite"
_STATE_FIELDS = {f.name for f in dataclasses.fields(JointState)}
_PROGRESS_FIELDS = {f.name for f in dataclasses.fields(ScreenProgress)}


def _refuse(path: Path, field: str, what: str) -> ValueError:
    return ValueError(f"{path}: field '{field}' {what}; {_ADVICE}")


def _finite_list(v: Any, field: str, path: Path, allow_empty: bool = False) -> None:
    if not isinstance(v, list) or (not v and not allow_empty):
        raise _refuse(path, field, f"must be a list of numbers, got {_short(v)}")
    for i, x in enumerate(v):
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise _refuse(path, field, f"must hold finite numbers, got {x!r} at index {i}")


def _count(v: Any, field: str, path: Path) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise _refuse(path, field, f"must be a whole number >= 0, got {_short(v)}")


def _number(v: Any, field: str, path: Path, *, finite: bool = True) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (finite and not math.isfinite(v)):
        raise _refuse(path, field, f"must be a {'finite ' if finite else ''}number, got {_short(v)}")


def _list_of_dicts(v: Any, field: str, path: Path) -> None:
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise _refuse(path, field, f"must be a list of objects, got {_short(v)}")


def _short(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _check_progress(p: Any, path: Path) -> None:
    field = "state.screen_progress"
    if not isinstance(p, dict):
        raise _refuse(path, field, f"must be an object or null, got {_short(p)}")
    for key in sorted(set(p) - _PROGRESS_FIELDS):
        raise _refuse(path, f"{field}.{key}", "is not a field of a screening's progress")
    for key in ("rounds_done", "theta", "z", "speed"):
        if key not in p:
            raise _refuse(path, f"{field}.{key}", "is missing")
    _count(p["rounds_done"], f"{field}.rounds_done", path)
    _finite_list(p["theta"], f"{field}.theta", path)
    _finite_list(p["z"], f"{field}.z", path)
    _number(p["speed"], f"{field}.speed", path, finite=False)
    if not isinstance(p.get("path", []), list):
        raise _refuse(path, f"{field}.path", f"must be a list of designs, got {_short(p['path'])}")
    for i, theta in enumerate(p.get("path", [])):
        _finite_list(theta, f"{field}.path[{i}]", path)
    _list_of_dicts(p.get("rows", []), f"{field}.rows", path)
    for key in ("finished", "holds"):
        if not isinstance(p.get(key, False), bool):
            raise _refuse(path, f"{field}.{key}", f"must be true or false, got {_short(p[key])}")
    if "own" in p:
        _number(p["own"], f"{field}.own", path, finite=False)


def read_partial(path: str | Path) -> tuple[dict, JointState]:
    """``(settings, state)`` of the checkpoint ``path`` (module docstring); ValueError naming
    the file and the field when it is damaged."""
    path = Path(path)
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as err:
        raise ValueError(f"{path}: not UTF-8 (byte {err.object[err.start]:#04x} at offset {err.start}); "
                         f"{_ADVICE}") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not JSON (cut short, or edited?): {err.msg} at line {err.lineno} column "
                         f"{err.colno}; {_ADVICE}") from None
    except OSError as err:
        raise ValueError(f"{path}: cannot be read ({err.strerror or err}); {_ADVICE}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object with 'settings' and 'state', got a "
                         f"{type(data).__name__}; {_ADVICE}")
    for key in ("settings", "state"):
        if key not in data:
            raise _refuse(path, key, "is missing")
        if not isinstance(data[key], dict):
            raise _refuse(path, key, f"must be an object, got {_short(data[key])}")
    state = data["state"]
    for key in sorted(set(state) - _STATE_FIELDS):
        raise _refuse(path, f"state.{key}", "is not a field of a co-design's state")
    if "w" not in state:
        raise _refuse(path, "state.w", "is missing")
    _finite_list(state["w"], "state.w", path)
    if state.get("best_w") is not None:
        _finite_list(state["best_w"], "state.best_w", path)
        if len(state["best_w"]) != len(state["w"]):
            raise _refuse(path, "state.best_w", f"has {len(state['best_w'])} numbers, state.w {len(state['w'])}")
    for key in ("stage", "iteration", "rejections", "best_path_len", "sim_steps"):
        if key in state:
            _count(state[key], f"state.{key}", path)
    if state.get("lam") is not None:
        _number(state["lam"], "state.lam", path)
    if "wall_time_s" in state:
        _number(state["wall_time_s"], "state.wall_time_s", path)
    if "best_speed" in state:              # -inf: no credible speed yet (a start that falls at a physics step)
        _number(state["best_speed"], "state.best_speed", path, finite=False)
    if not isinstance(state.get("path", []), list):
        raise _refuse(path, "state.path", f"must be a list of designs, got {_short(state['path'])}")
    for i, theta in enumerate(state.get("path", [])):
        _finite_list(theta, f"state.path[{i}]", path)
    for key in ("stage_rows", "history", "screen_rows"):
        if key in state:
            _list_of_dicts(state[key], f"state.{key}", path)
    for key in ("done", "screened", "best_holds"):
        if key in state and not isinstance(state[key], bool):
            raise _refuse(path, f"state.{key}", f"must be true or false, got {_short(state[key])}")
    if state.get("best_evaluation") is not None and not isinstance(state["best_evaluation"], dict):
        raise _refuse(path, "state.best_evaluation", f"must be an object or null, got {_short(state['best_evaluation'])}")
    if state.get("screen_progress") is not None:
        _check_progress(state["screen_progress"], path)
    return data["settings"], JointState.from_dict(state)


def check_partial_sizes(path: str | Path, state: JointState, nz: int, n_theta: int) -> None:
    """The checkpoint's vectors have the problem's sizes: ``w`` (and ``best_w``) ``nz +
    n_theta`` numbers, each design of ``path`` ``n_theta``, the screening's ``theta`` and ``z``
    theirs; else a ValueError naming the file and the field."""
    path = Path(path)
    n = nz + n_theta
    if len(state.w) != n:
        raise _refuse(path, "state.w", f"has {len(state.w)} numbers, the problem {n} (keyframes {nz} + design "
                                       f"{n_theta})")
    if state.best_w is not None and len(state.best_w) != n:
        raise _refuse(path, "state.best_w", f"has {len(state.best_w)} numbers, the problem {n}")
    for i, theta in enumerate(state.path):
        if len(theta) != n_theta:
            raise _refuse(path, f"state.path[{i}]", f"has {len(theta)} numbers, the design {n_theta}")
    p = state.screen_progress
    if p is not None:
        for key, size in (("theta", n_theta), ("z", nz)):
            if len(p[key]) != size:
                raise _refuse(path, f"state.screen_progress.{key}", f"has {len(p[key])} numbers, expected {size}")
        for i, theta in enumerate(p.get("path", [])):
            if len(theta) != n_theta:
                raise _refuse(path, f"state.screen_progress.path[{i}]", f"has {len(theta)} numbers, the design "
                                                                        f"{n_theta}")
