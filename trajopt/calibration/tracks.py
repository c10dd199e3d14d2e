"""Tracked marker positions from a CSV file.

The file (``trajopt calibrate --markers TRACKS.csv``) has the header ``t,marker,x,y,z`` (the five
names in any order) and one row per sample: time ``t`` [s] since the controls started, the
marker's name, and its position [m] (the robot's frame, or the camera's with ``--frame
camera``). UTF-8 text (a byte-order mark is allowed). Any sampling rate, per marker; rows in any
order (each marker's samples are sorted by time; two samples of one marker at the same time are
an error); a missing sample is a row with ``x``, ``y`` or ``z`` empty or ``nan`` (or no row at
all); ``inf`` is an error, not a missing sample. Every problem is a ValueError naming the file
and line (a file that is not UTF-8: the byte offset).

The calibration (:class:`trajopt.calibration.calibrate.MarkerData`) compares each sample with the
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

from ..results.files import decode_utf8
from ..results.result import atomic_write_bytes

__all__ = ["TRACK_COLUMNS", "Tracks", "read_tracks", "write_tracks", "read_utf8"]

TRACK_COLUMNS = ("t", "marker", "x", "y", "z")


@dataclass(frozen=True)
class Tracks:
    """Valid samples per marker: ``samples[name] = (t (s,), p (s, 3))``, sorted by time, times
    strictly increasing; ``n_missing`` rows had no position. ``markers`` lists the names with samples,
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
    """The number in ``text``; nan when empty or ``nan`` (a missing value); inf is refused."""
    s = text.strip()
    if s == "" or s.lower() == "nan":
        return np.nan
    try:
        value = float(s)
    except ValueError:
        raise ValueError(f"{where}: {what} must be a number, got {text!r}") from None
    if np.isinf(value):
        kind = "times" if what == "t" else "positions"
        raise ValueError(f"{where}: {what} is {value:g}: {kind} must be finite (a missing sample is empty or nan)")
    return value


def read_utf8(path: Path, what: str) -> str:
    """The text of ``path`` (UTF-8, an optional byte-order mark dropped); a ValueError naming the
    file (``what`` it is when absent) and, when it is not UTF-8, the offending byte's offset and line."""
    if not path.is_file():
        raise ValueError(f"{path}: {what} not found")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    return decode_utf8(data, path)


def read_tracks(path: str | Path, known_markers: Sequence[str]) -> Tracks:
    """Read a tracks CSV (module docstring); ``known_markers`` are the marker names of the robot
    (a row naming another is an error)."""
    path = Path(path)
    src = str(path)
    text = read_utf8(path, "tracks file")
    known = list(known_markers)
    raw: dict[str, list] = {}
    first: dict[tuple[str, float], int] = {}         # (marker, t) -> line
    missing = 0
    reader = csv.reader(io.StringIO(text, newline=""))
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
        if (name, t) in first:
            raise ValueError(f"{where}: marker {name!r} has a second sample at t = {t:g} s (the first on line "
                             f"{first[name, t]}): one sample per marker and time")
        first[name, t] = line
        p = [_number(row[at[c]], c, where) for c in "xyz"]
        if not np.isfinite(p).all():
            missing += 1
            continue
        raw.setdefault(name, []).append((t, *p))
    if not raw:
        raise ValueError(f"{src}: no marker positions (only the header, or every sample missing)")
    samples = {}
    for n, rows in raw.items():
        a = np.array(rows, dtype=np.float64)
        a = a[np.argsort(a[:, 0], kind="stable")]             # rows in any order: sorted by time
        samples[n] = (a[:, 0].copy(), a[:, 1:].copy())
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
