"""Tracked marker positions from a CSV file.

The file (``trajopt calibrate --markers TRACKS.csv``) has the header ``t,marker,x,y,z`` (the five
names in any order) and one row per sample: time ``t`` [s] since the controls started, the
marker's name, and its position [m] (the robot's frame, or the camera's with ``--frame
camera``). Any sampling rate, per marker; rows in any order; a missing sample is a row with
``x``, ``y`` or ``z`` empty or ``nan`` (or no row at all). Every problem is a ValueError naming
the file and line.

The calibration (:class:`trajopt.calibrate.MarkerData`) compares each sample with the
simulated marker interpolated linearly between the two simulation steps around its time, so
any rate works and a missing sample simply contributes nothing (interpolating the noisy samples
onto the steps instead would smooth and re-weight them).
"""
from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .results import atomic_write_bytes

__all__ = ["TRACK_COLUMNS", "Tracks", "read_tracks", "write_tracks"]

TRACK_COLUMNS = ("t", "marker", "x", "y", "z")


@dataclass(frozen=True)
class Tracks:
    """Valid samples per marker: ``samples[name] = (t (s,), p (s, 3))``, times strictly
    increasing; ``n_missing`` rows had no position. ``markers`` lists the names with samples,
    in the order of the known markers given to :func:`read_tracks`."""

    source: str
    markers: tuple[str, ...]
    samples: dict
    n_missing: int = 0

    @property
    def n_samples(self) -> int:
        return sum(len(t) for t, _ in self.samples.values())

    @property
    def end_time(self) -> float:
        return max((float(t[-1]) for t, _ in self.samples.values() if len(t)), default=0.0)

    def median_interval(self) -> float:
        """The median time between consecutive samples of a marker [s] (nan with none)."""
        gaps = np.concatenate([np.diff(t) for t, _ in self.samples.values()] + [np.zeros(0)])
        return float(np.median(gaps)) if gaps.size else float("nan")


def _number(text: str, what: str, where: str) -> float:
    s = text.strip()
    if s == "" or s.lower() == "nan":
        return np.nan
    try:
        return float(s)
    except ValueError:
        raise ValueError(f"{where}: {what} must be a number, got {text!r}") from None


def read_tracks(path: str | Path, known_markers: Sequence[str]) -> Tracks:
    """Read a tracks CSV (module docstring); ``known_markers`` are the marker names of the robot
    (a row naming another is an error)."""
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise ValueError(f"{src}: tracks file not found")
    known = list(known_markers)
    raw: dict[str, list] = {}
    last: dict[str, tuple[float, int]] = {}
    missing = 0
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{src}:1: empty file; expected the header {','.join(TRACK_COLUMNS)}")
        cols = [h.strip().lower() for h in header]
        if sorted(cols) != sorted(TRACK_COLUMNS):
            raise ValueError(f"{src}:1: the header must name the columns {','.join(TRACK_COLUMNS)}, got "
                             f"{','.join(h.strip() for h in header)!r}")
        at = {c: cols.index(c) for c in TRACK_COLUMNS}
        for row in reader:
            line = reader.line_num
            where = f"{src}:{line}"
            if not any(c.strip() for c in row):
                continue
            if len(row) != len(TRACK_COLUMNS):
                raise ValueError(f"{where}: expected {len(TRACK_COLUMNS)} columns ({','.join(TRACK_COLUMNS)}), "
                                 f"got {len(row)}")
            name = row[at["marker"]].strip()
            if name not in known:
                raise ValueError(f"{where}: unknown marker {name!r} (the robot's markers: {', '.join(known)})")
            t = _number(row[at["t"]], "t", where)
            if not np.isfinite(t):
                raise ValueError(f"{where}: the time t is missing")
            if name in last and t <= last[name][0]:
                raise ValueError(f"{where}: time {t:g} s of marker {name!r} is not after its previous sample "
                                 f"at {last[name][0]:g} s (line {last[name][1]}): times must increase per marker")
            last[name] = (t, line)
            p = [_number(row[at[c]], c, where) for c in "xyz"]
            if not np.isfinite(p).all():
                missing += 1
                continue
            raw.setdefault(name, []).append((t, *p))
    if not raw:
        raise ValueError(f"{src}: no marker positions (only the header, or every sample missing)")
    samples = {n: (np.array([r[0] for r in raw[n]]), np.array([r[1:] for r in raw[n]])) for n in raw}
    return Tracks(src, tuple(n for n in known if n in samples), samples, missing)


def write_tracks(path: str | Path, times: np.ndarray, names: Sequence[str], positions: np.ndarray,
                 mask: np.ndarray | None = None) -> Path:
    """Write ``positions`` (S, m, 3) [m] of markers ``names`` at ``times`` (S,) [s] as a tracks
    CSV (atomically); samples where ``mask`` (S, m) is False are written as missing (empty)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(TRACK_COLUMNS)
    for s, t in enumerate(times):
        for i, n in enumerate(names):
            ok = mask is None or mask[s, i]
            w.writerow([repr(float(t)), n] + ([repr(float(v)) for v in positions[s, i]] if ok else ["", "", ""]))
    atomic_write_bytes(Path(path), buf.getvalue().encode())
    return Path(path)
