"""``argparse`` ``type=`` functions for the ``trajopt`` command line.

Every numeric argument is checked when the command line is parsed, so a bad value ends in one
line naming the argument (``trajopt optimize: error: argument --keyframes: must be an integer
>= 1, got '0'``) and exit code 2, before any work is done. Output locations are checked the same
way (an unwritable ``--out`` is refused before a long run, not after it). Standard library only.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Callable

from .results.files import check_output_dir

__all__ = ["contact_law", "integer", "positive_int", "nonnegative_int", "number", "positive_float", "nonnegative_float",
           "slope_deg", "speed", "file_name", "frame_size", "output_dir", "output_file", "cycles", "steps",
           "difficulty_level"]


def integer(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """An integer in [lo, hi] (either bound may be None)."""
    bounds = " and ".join(t for t in ((f">= {lo}" if lo is not None else ""), (f"<= {hi}" if hi is not None else ""))
                          if t)

    def parse(text: str) -> int:
        try:
            value = int(text, 10)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer{' ' + bounds if bounds else ''}, got {text!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"must be an integer {bounds}, got {text!r}")
        return value
    parse.__name__ = "integer"
    return parse


positive_int = integer(1)
nonnegative_int = integer(0)
#: gait cycles played (an upper bound keeps a typo from allocating the machine's memory)
cycles = integer(1, 1000)
#: simulation steps of a phase
steps = integer(1, 100_000)


def number(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           hi_open: bool = False) -> Callable[[str], float]:
    """A finite number in the interval [lo, hi] (open at a bound with ``lo_open`` / ``hi_open``)."""
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    what = "a finite number" + (" " + " and ".join(parts) if parts else "")

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        if lo is not None and (value <= lo if lo_open else value < lo):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        if hi is not None and (value >= hi if hi_open else value > hi):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        return value
    parse.__name__ = "number"
    return parse


positive_float = number(0.0, lo_open=True)
nonnegative_float = number(0.0)
slope_deg = number(-90.0, 90.0, lo_open=True, hi_open=True)


def speed(text: str) -> float | str:
    """A target speed [BL/min] > 0, or ``max`` (the fastest gait within the motors' limit,
    :mod:`trajopt.fastest`)."""
    if text.strip().lower() == "max":
        return "max"
    try:
        return positive_float(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0 [BL/min] or 'max', got {text!r}") from None


def file_name(text: str) -> str:
    """A plain file name: no directory part (that is what ``--out`` is for), not empty."""
    if not text or text in (".", "..") or "/" in text or "\\" in text or "\0" in text:
        raise argparse.ArgumentTypeError(f"must be a file name without a directory (use --out for that), got {text!r}")
    return text


def frame_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, each in 16..4096."""
    try:
        w, h = (int(v, 10) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be WIDTHxHEIGHT in pixels (e.g. 480x360), got {text!r}")
    if not (16 <= w <= 4096 and 16 <= h <= 4096):
        raise argparse.ArgumentTypeError(f"width and height must be 16..4096 pixels, got {text!r}")
    return w, h


def output_dir(text: str) -> Path:
    """A directory that exists and is writable, or can be created (nothing is created here)."""
    try:
        return check_output_dir(Path(text), "directory")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("directory "))


def output_file(text: str) -> Path:
    """A file path whose directory exists and is writable, or can be created; not a directory.
    Whether the file may be replaced is the command's decision (``--overwrite``)."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path}: is a directory, expected a file name")
    try:
        check_output_dir(path.parent, "directory")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{path}: {str(exc).removeprefix('directory ')}")
    return path


def contact_law(text: str) -> str:
    """A contact law of the registry ``soft_envs.envs.CONTACT_LAWS`` (``paper``,
    ``coulomb``, and any law registered since: a new law is known to the command line without
    editing it). The registry is imported only when a ``--contact`` value is parsed, so
    ``trajopt --help`` stays light."""
    from soft_envs.envs import CONTACT_LAWS
    if text not in CONTACT_LAWS:
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from "
                                         f"{', '.join(map(repr, CONTACT_LAWS))})")
    return text


def difficulty_level(text: str) -> str:
    """A benchmark task's level (``easy``, ``medium``, ``hard``: :data:`soft_envs.envs.tasks.DIFFICULTIES`);
    a ValueError naming the levels otherwise."""
    from soft_envs.envs.tasks.difficulty import check_difficulty
    try:
        return check_difficulty(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
