"""``trajopt calibrate``: inputs (robot, markers, tracks, controls) and outputs (calibration.json,
a new robot.toml with the fitted values, the before/after plot of the tracks). The fit itself is
:func:`trajopt.calibration.calibrate.fit_parameters`, the files :mod:`trajopt.calibration.files`; the checks of
the data and of the fit (:mod:`trajopt.calibration.checks`) refuse to write anything when one
fails, unless ``--force``. A calibration in ``--out`` is never replaced without ``--overwrite``,
and the folder is reserved while a calibration runs (``OUT/calibrate.lock``)."""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from soft_envs.envs import PHYSICAL_PARAMETERS, MarkerSet, check_parameters, load_robot, with_contact_law

from ..calibration.calibrate import MarkerData, fit_parameters
from ..calibration.checks import check_fit, check_model_misfit, check_tracks
from ..calibration.files import HEADER, plot_tracks, read_marker_points, write_calibrated_robot
from ..results.reservation import reserve
from ..results.result import Result, atomic_write_bytes
from ..calibration.tracks import read_tracks

__all__ = ["run_calibrate"]


def _parameter_names(text: str, robot) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise ValueError("--fit: give the parameters to fit, comma-separated, from: " + ", ".join(PHYSICAL_PARAMETERS))
    try:
        return check_parameters(robot, names)
    except ValueError as exc:
        raise ValueError(f"--fit: {exc}") from None


#: what a calibration writes into --out
OUTPUTS = ("robot.toml", "calibration.json", "tracks.png")
#: the lock reserving --out while a calibration runs (trajopt.results.reservation)
LOCK = "calibrate.lock"


def _output_toml(out: Path, source: Path) -> Path:
    target = out / "robot.toml"
    if target.resolve() == source.resolve():
        raise ValueError(f"{target} is the input robot file: calibrate never overwrites it; use another --out")
    if target.exists() and not (target.is_file() and target.read_text(errors="replace").startswith(HEADER)):
        raise ValueError(f"{target} exists and was not written by trajopt calibrate: use another --out")
    return target


def _check_outputs(out: Path, overwrite: bool) -> None:
    """A calibration in ``out`` is never replaced without ``--overwrite`` (refused before the fit)."""
    there = [name for name in OUTPUTS if (out / name).exists()]
    for name in there:
        if not (out / name).is_file():
            raise ValueError(f"{out / name}: exists and is not a file; use another --out")
    if there and not overwrite:
        raise ValueError(f"{out} holds a calibration ({', '.join(there)}): it is never replaced without "
                         "--overwrite (or choose another --out)")


def _inputs(args) -> tuple[Any, MarkerSet, MarkerData, tuple[str, ...], Any]:
    robot = with_contact_law(load_robot(args.robot), getattr(args, "contact", None))
    markers = (read_marker_points(args.marker_points, robot.mesh) if args.marker_points else robot.marker_set)
    if not len(markers):
        raise ValueError(f"{robot.source}: the robot has no [[markers]]; add them or give --marker-points FILE")
    names = _parameter_names(args.fit, robot)
    res = Result.load(args.controls)
    if list(res.motor_names) != robot.motor_names:
        raise ValueError(f"{args.controls}: motors {list(res.motor_names)} are not the robot's {robot.motor_names}")
    u = res.u_post if args.play == "u_post" else res.u
    tracks = read_tracks(args.markers, markers.names)
    s = res.settings
    data = MarkerData.from_tracks(tracks, robot, markers, u, float(res.dt), frame=args.frame,
                                  incline_deg=float(s.get("incline_deg", 0.0)),
                                  heading_deg=float(s.get("heading_deg", 0.0)))
    return robot, markers, data, names, tracks


def _refuse_unless_forced(failures: list[str], target: Path, force: bool) -> None:
    """A ValueError (one line: exit 2, nothing written) naming the failed checks, unless ``force``."""
    if failures and not force:
        raise ValueError(f"refusing to write {target}: {len(failures)} check{'s' * (len(failures) > 1)} failed: "
                         + " | ".join(failures) + " (--force writes it anyway, with these warnings)")


def run_calibrate(args) -> int:
    robot, markers, data, names, tracks = _inputs(args)
    if robot.source.startswith("<"):
        raise ValueError("calibrate needs a robot from a robot.toml (a shipped name or a path)")
    out = Path(args.out)
    target = _output_toml(out, Path(robot.source))
    with reserve(out / LOCK, f"calibration folder {out}"):     # a second calibration into it is refused
        _check_outputs(out, getattr(args, "overwrite", False))
        return _calibrate_reserved(args, robot, markers, data, names, tracks, out, target)


def _calibrate_reserved(args, robot, markers, data, names, tracks, out: Path, target: Path) -> int:
    dropped = tracks.n_samples - len(data.times)
    print(f"{robot.summary()}\n{len(data.times)} samples of {len(markers)} markers over {len(data.u) * data.dt:.2f} s "
          f"(about {1.0 / tracks.median_interval():.3g} Hz per marker; "
          f"{tracks.n_missing} missing, {dropped} outside the controls' span); fitting {', '.join(names)}")
    failures = check_tracks(tracks, data)
    _refuse_unless_forced(failures, target, args.force)       # before the fit: no time spent on nonsense
    t0 = time.perf_counter()
    fit = fit_parameters(data, names, max_evaluations=args.max_evaluations)
    failures += check_fit(fit, args.noise) + check_model_misfit(fit, data, args.noise)
    _refuse_unless_forced(failures, target, args.force)
    out.mkdir(parents=True, exist_ok=True)
    write_calibrated_robot(Path(robot.source), target, robot, names, fit.values)
    plot = plot_tracks(data, fit, out / "tracks.png", tracks_file=args.markers)
    summary = {"robot": args.robot, "robot_toml": str(target), "markers": str(args.markers),
               "controls": str(args.controls), "contact": robot.contact.model, "played": args.play, "frame": args.frame, "dt": data.dt,
               "n_steps": len(data.u), "missing_samples": tracks.n_missing, "samples_used": len(data.times),
               "samples_read": tracks.n_samples, "noise_m": args.noise, "checks_failed": failures,
               "wall_time_s": time.perf_counter() - t0, **fit.summary()}
    atomic_write_bytes(out / "calibration.json", json.dumps(summary, indent=1).encode())
    w = max(len(n) for n in names)
    for n, a, b, e in zip(names, fit.initial, fit.values, fit.std_errors):
        unit = PHYSICAL_PARAMETERS[n].unit
        print(f"  {n.ljust(w)}  {a:.6g} -> {b:.6g} +- {e:.2g} {unit}".rstrip())
    print(f"  RMS marker error {fit.rms_before_mm:.3f} mm -> {fit.rms_after_mm:.3f} mm "
          f"({fit.iterations} rollouts; {fit.message})")
    for warning in fit.warnings:
        print(f"warning: {warning}")
    for failure in failures:
        print(f"warning: check failed (written anyway, --force): {failure}")
    print(f"wrote {target}, {plot}, {out / 'calibration.json'}")
    return 0
