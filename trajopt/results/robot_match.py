"""Tying a result to the robot it was made for.

A :class:`~trajopt.results.Result` records ``robot_fingerprint``: the
:func:`soft_envs.envs.robot_fingerprint` of its robot (name, file, and hashes of the
``robot.toml`` and the mesh, normalised; the normalised ``robot.toml`` itself). Before a result
is replayed, rendered, evaluated, exported, plotted or played, :func:`check_robot` compares it with
the robot its ``robot`` field names today and refuses a mismatch (another robot, or an edited one:
a narrower motor range, another mesh) with a :class:`RobotMismatchError` naming both and the
fields that differ; ``ignore=True`` (``--ignore-robot-mismatch``) turns it into a warning. A
motor count that differs is refused even then: the controls cannot be applied.

``trajopt play`` also checks the hardware file's ``robot`` (:func:`check_hardware_robot`).
This module imports ``soft_envs`` only when it computes a fingerprint, so ``trajopt.hardware``
can use it without the simulator stack.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["RobotMismatchError", "IGNORE_FLAG", "fingerprint_of", "describe_difference", "check_robot",
           "check_hardware_robot", "check_for_play", "robot_reference", "locate_robot"]

IGNORE_FLAG = "--ignore-robot-mismatch"
#: robot.toml fields a result records itself and replays with, whatever the file says now: the
#: contact law (``settings["contact"]``; a result without it was made under the paper's law). The
#: shipped robot files changed ``[contact] model`` from "paper" to "coulomb": a
#: result made before is still a result of the same robot.
RESULT_OWNED_FIELDS = frozenset({"[contact].model"})


class RobotMismatchError(ValueError):
    """A result used with a robot other than the one it was made for."""


def _is_path(robot: str) -> bool:
    """A robot given as a ``robot.toml`` path, not a shipped name (as ``load_robot`` tells them apart)."""
    p = Path(robot)
    return p.suffix == ".toml" or p.is_file()


def robot_reference(robot: Any) -> str:
    """How a result records its robot: a shipped name as given, a ``robot.toml`` path made
    absolute (a relative one would only be found from the folder the result was made in)."""
    text = str(robot)
    return str(Path(text).resolve()) if _is_path(text) else text


def locate_robot(res: Any) -> str:
    """The robot a result names, as it can be found now: its ``robot`` (a shipped name, or a
    robot.toml path: absolute in results of release 0.2, relative to where it was made before), else, when
    that path is not found, the file of that name beside the result, or the path taken relative
    to the result's folder (a result folder copied or moved with its robot, e.g. a co-design's).
    Whether the robot found is the one the result was made for is :func:`check_robot`'s to say."""
    robot = str(res.robot)
    p = Path(robot)
    if not _is_path(robot) or p.is_file() or not getattr(res, "path", None):
        return robot
    folder = Path(res.path).parent
    for candidate in (folder / p.name, *(() if p.is_absolute() else (folder / p,))):
        if candidate.is_file():
            return str(candidate)
    return robot


def fingerprint_of(robot: Any) -> dict[str, Any]:
    """The fingerprint of a robot (a shipped name, a ``robot.toml`` path or a Robot made from
    one); ``{}`` for a robot built in Python."""
    from soft_envs.envs import robot_fingerprint
    return robot_fingerprint(robot) or {}


def _flatten(value: Any, where: str, out: dict[str, Any]) -> dict[str, Any]:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(v, f"{where}.{k}" if where else (f"[{k}]" if isinstance(v, dict) else k), out)
    elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        for i, v in enumerate(value):
            _flatten(v, f"{where}[{i}]", out)
    else:
        out[where] = value
    return out


def _short(v: Any) -> str:
    text = "(absent)" if v is _ABSENT else repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


_ABSENT = object()


def describe_difference(saved: dict[str, Any], current: dict[str, Any], max_fields: int = 4) -> str | None:
    """What differs between two fingerprints (None if they are the same robot description)."""
    if saved.get("sha256") == current.get("sha256"):
        return None
    if saved.get("name") != current.get("name"):
        return f"another robot ({current.get('name')!r} instead of {saved.get('name')!r})"
    parts = []
    if saved.get("toml_sha256") != current.get("toml_sha256"):
        old, new = _flatten(saved.get("toml", {}), "", {}), _flatten(current.get("toml", {}), "", {})
        changed = [k for k in sorted(set(old) | set(new))
                   if old.get(k, _ABSENT) != new.get(k, _ABSENT) and k not in RESULT_OWNED_FIELDS]
        if not changed and "toml" in saved and saved.get("mesh_sha256") == current.get("mesh_sha256"):
            return None         # only what the result records itself differs (its contact law)
        shown = [f"{k}: {_short(old.get(k, _ABSENT))} -> {_short(new.get(k, _ABSENT))}" for k in changed[:max_fields]]
        more = f" and {len(changed) - max_fields} more" if len(changed) > max_fields else ""
        parts.append("robot.toml changed" + (f" ({'; '.join(shown)}{more})" if shown else ""))
    if saved.get("mesh_sha256") != current.get("mesh_sha256"):
        parts.append("the mesh changed")
    return ", ".join(parts) or "the fingerprints differ"


def _label(fp: dict[str, Any]) -> str:
    return f"robot {fp.get('name')!r} ({fp.get('source')}, fingerprint {str(fp.get('sha256', ''))[:12]})"


def check_robot(res: Any, current: dict[str, Any], motor_names: list[str] | None = None, *, src: str,
                ignore: bool = False) -> str | None:
    """Check that ``res`` (a Result) fits the robot with fingerprint ``current`` and motors
    ``motor_names``. A mismatch raises :class:`RobotMismatchError` (a ValueError naming ``src``,
    both robots, what differs and the override flag), or with ``ignore`` returns the text of a
    warning. Results without a fingerprint (robots built in Python, older files) are checked by
    their motor names only. Returns None when everything matches."""
    names = list(res.motor_names)
    saved = res.robot_fingerprint or {}
    what = describe_difference(saved, current) if (saved and current) else None
    if motor_names is not None and len(motor_names) != len(names):
        raise RobotMismatchError(f"{src}: made for {len(names)} motors ({', '.join(names)}), but {res.robot!r} is "
                                 f"now a robot with {len(motor_names)} ({', '.join(motor_names)})"
                                 f"{f' ({what})' if what else ''}: the controls cannot be applied to it")
    if what is not None:
        text = f"{src} was made for {_label(saved)}, but {res.robot!r} is now {_label(current)}: {what}"
    elif motor_names is not None and list(motor_names) != names:
        text = (f"{src} was made for motors {names}, but robot {res.robot!r} has motors {list(motor_names)}")
    else:
        return None
    if ignore:
        return f"{text} (used anyway: {IGNORE_FLAG})"
    raise RobotMismatchError(f"{text}; optimise a gait for this robot, or pass {IGNORE_FLAG} to use the result "
                             "anyway")


def check_hardware_robot(hw_robot: str, hw_path: str, res: Any, *, src: str, ignore: bool = False,
                         fingerprint: Any = fingerprint_of) -> str | None:
    """Check the hardware file's ``robot`` (a robot name, or a ``robot.toml`` path relative to
    the hardware file) against the robot ``res`` was made for, as :func:`check_robot` does
    (raise, or return a warning with ``ignore``). An empty ``robot`` is not checked. A path, and
    a shipped robot's name, are compared by fingerprint when ``soft_envs`` is importable (a
    co-designed or edited robot keeps its name, and is another robot); by file, or by name,
    otherwise."""
    if not hw_robot or getattr(res, "robot", None) is None:       # nothing to compare
        return None
    saved = getattr(res, "robot_fingerprint", None) or {}
    what = None
    if hw_robot.endswith(".toml"):
        path = Path(hw_robot) if Path(hw_robot).is_absolute() else Path(hw_path).parent / hw_robot
        try:
            theirs = fingerprint(path)
            what = describe_difference(saved, theirs) if saved else None
            same = what is None if saved else _same_file(path, res.robot)
            label = _label(theirs)
        except ImportError:
            same, label = _same_file(path, saved.get("source", res.robot)), str(path)
    else:
        same = hw_robot in (res.robot, saved.get("name"))
        label = f"robot {hw_robot!r}"
        if same and saved:                 # the name is not enough: the shipped robot of that name
            try:
                theirs = fingerprint(hw_robot)
            except (ImportError, ValueError):     # no simulator here, or no shipped robot of that name
                theirs = None
            if theirs:
                what = describe_difference(saved, theirs)
                same, label = what is None, f"{_label(theirs)}, the shipped robot of that name"
    if same:
        return None
    made_for = _label(saved) if saved else f"robot {res.robot!r}"
    text = f"{hw_path} describes {label}, but {src} was made for {made_for}{f': {what}' if what else ''}"
    if ignore:
        return f"{text} (played anyway: {IGNORE_FLAG})"
    raise RobotMismatchError(f"{text}; pass {IGNORE_FLAG} to play it anyway")


def check_for_play(res: Any, hw_robot: str, hw_path: str, *, src: str, ignore: bool = False) -> list[str]:
    """``trajopt play``'s checks: the hardware file's ``robot`` against the result
    (:func:`check_hardware_robot`), and the result's fingerprint against its robot files as they
    are now (:func:`check_robot`; skipped, with a note, where ``soft_envs`` or the files are
    missing, e.g. on a computer that only plays). Raises :class:`RobotMismatchError`, or returns
    the warnings and notes to print."""
    notes = []
    note = check_hardware_robot(hw_robot, hw_path, res, src=src, ignore=ignore)
    if note:
        notes.append(note)
    if getattr(res, "robot_fingerprint", None):
        try:
            current = fingerprint_of(locate_robot(res))
        except ImportError:
            notes.append(f"the robot files of {src} were not checked (soft_envs is not installed)")
        except ValueError as exc:
            notes.append(f"the robot files of {src} were not checked ({exc})")
        else:
            note = check_robot(res, current, None, src=src, ignore=ignore)
            if note:
                notes.append(note)
    return notes


def _same_file(a: Path, b: str) -> bool:
    try:
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False
