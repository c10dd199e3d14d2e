"""The checks ``trajopt calibrate`` makes before it writes a robot.toml.

Each failed check is one string ``"<check>: what failed; try: what to do"``; the command refuses
to write anything when one fails, unless ``--force`` (then it writes and prints them as warnings).

Before the fit, on the data (:func:`check_tracks`):

- ``time-span``: fewer than :data:`MIN_USED_FRACTION` of the samples fall within the controls'
  span ``[0, K dt]`` (the rest would be dropped silently), or those that do cover less than half
  of it. Hints: times in milliseconds (the tracks end 300-3000 times after the controls), or
  tracks that last some other multiple of the controls (a time unit, another gait).
- ``plausible-tracks``: marker positions spread over more than :data:`MAX_SPREAD_BODY_LENGTHS`
  body lengths (the mesh's largest extent), markers in the robot's frame that stay that far from
  their rest points, or markers moving faster than :data:`MAX_SPEED_BODY_LENGTHS_PER_S` (measured
  over :data:`SPEED_WINDOW_S`, so that the tracker's noise does not count). Hint: the unit
  (:func:`unit_hint`: the distances between the tracked markers against those between their
  rest points, about 1000x for millimetres, 100x for centimetres, 39x for inches), else the
  frame or the time unit.

After the fit (:func:`check_fit`):

- ``rms-vs-noise``: the RMS marker distance after the fit above :data:`RMS_NOISE_FACTOR` times
  ``sqrt(3) noise``, the RMS distance that tracker noise of standard deviation ``noise`` per
  coordinate alone gives (``--noise``, default :data:`DEFAULT_NOISE_M`);
- ``evaluation-limit``: the last stage stopped at its ``--max-evaluations`` before converging;
- ``standard-errors``: a standard error at least as large as its value;
- ``at-bounds``: a parameter within :data:`BOUND_TOLERANCE` of its range at a bound
  (:data:`trajopt.calibration.calibrate.PARAMETER_BOUNDS`);
- ``model-misfit`` (:func:`check_model_misfit`): what is left after the fit is mostly a constant
  offset of each marker (its mean residual larger than the residual's scatter about it, and
  above :data:`MISFIT_FLOOR_M`): no physical parameter moves a marker by a constant, so the
  fitted values were bent to absorb something the model cannot explain (tracks with another
  origin, wrong marker points). It does not rely on ``--noise``: a noise stated too large hides
  such an offset from ``rms-vs-noise``, not from this check.
"""
from __future__ import annotations

import numpy as np

from soft_envs.envs import PHYSICAL_PARAMETERS

from .calibrate import PARAMETER_BOUNDS, CalibrationFit, MarkerData

__all__ = ["check_tracks", "check_fit", "check_model_misfit", "unit_hint", "body_length", "DEFAULT_NOISE_M",
           "RMS_NOISE_FACTOR", "MIN_USED_FRACTION", "MAX_SPREAD_BODY_LENGTHS", "MAX_SPEED_BODY_LENGTHS_PER_S",
           "SPEED_WINDOW_S", "BOUND_TOLERANCE", "MISFIT_FLOOR_M"]

#: tracker noise assumed without ``--noise`` [m, standard deviation per coordinate]
DEFAULT_NOISE_M = 1e-3
#: the RMS marker distance after a fit may be this many times the noise's own
RMS_NOISE_FACTOR = 3.0
#: at least this fraction of the tracks' samples must fall within the controls' span
MIN_USED_FRACTION = 0.5
#: marker positions may spread over this many body lengths at most
MAX_SPREAD_BODY_LENGTHS = 50.0
#: markers may move this many body lengths per second at most
MAX_SPEED_BODY_LENGTHS_PER_S = 5.0
#: speeds are displacements over at least this long [s]
SPEED_WINDOW_S = 0.25
#: a parameter this close to a bound (fraction of its range) is at the bound
BOUND_TOLERANCE = 1e-4
#: a constant offset of the markers below this [m, RMS] is no misfit (what trackers resolve)
MISFIT_FLOOR_M = 1e-4
#: tracks this many times the robot's size are in that unit: (low, high, unit, what to do)
_UNITS = ((500.0, 2000.0, "millimetres", "divide x, y, z by 1000"),
          (50.0, 200.0, "centimetres", "divide x, y, z by 100"),
          (25.0, 50.0, "inches", "multiply x, y, z by 0.0254"))


def body_length(robot) -> float:
    """The robot's size [m]: the largest extent of its rest mesh."""
    X = robot.mesh.points
    return float(np.max(X.max(axis=0) - X.min(axis=0)))


def _spread(points: np.ndarray) -> float:
    """Size of a point cloud [its units]: the diagonal of its 1st-99th percentile box."""
    lo, hi = np.percentile(points, [1.0, 99.0], axis=0)
    return float(np.linalg.norm(hi - lo))


def _speed(samples: dict) -> float:
    """The 95th percentile of marker speeds over windows of at least SPEED_WINDOW_S [units/s]
    (nan when no marker is tracked that long)."""
    speeds = []
    for t, p in samples.values():
        j = np.searchsorted(t, t + SPEED_WINDOW_S)
        i = np.flatnonzero(j < len(t))
        if i.size:
            speeds.append(np.linalg.norm(p[j[i]] - p[i], axis=1) / (t[j[i]] - t[i]))
    return float(np.percentile(np.concatenate(speeds), 95.0)) if speeds else float("nan")


def _scale(tracks, data: MarkerData) -> float:
    """How many times the distances between the tracked markers (their median positions) are
    those between their rest points (nan with fewer than two markers): about 1 for tracks in
    metres, whatever their frame."""
    names = [n for n in data.markers.names if n in tracks.samples]
    if len(names) < 2:
        return float("nan")
    tracked = np.array([np.median(tracks.samples[n][1], axis=0) for n in names])
    rest = np.array([data.markers.points[data.markers.names.index(n)] for n in names])
    i, j = np.triu_indices(len(names), 1)
    d_rest = np.linalg.norm(rest[i] - rest[j], axis=1)
    keep = d_rest > 1e-9
    if not keep.any():
        return float("nan")
    return float(np.median(np.linalg.norm(tracked[i] - tracked[j], axis=1)[keep] / d_rest[keep]))


def unit_hint(scale: float) -> str | None:
    """The unit that tracks ``scale`` times too large are in, and what to do (None: no unit)."""
    for lo, hi, unit, what in _UNITS:
        if lo <= scale <= hi:
            return f"tracks look like {unit}: {what} (the tracks are in metres)"
    return None


def check_tracks(tracks, data: MarkerData) -> list[str]:
    """The data checks (module docstring) of ``tracks`` (:class:`trajopt.calibration.tracks.Tracks`) and the
    samples ``data`` that fall within the controls' span."""
    failures = []
    T = len(data.u) * data.dt
    n_all, n_used = tracks.n_samples, len(data.times)
    covered = float(data.times.max() - data.times.min()) if n_used else 0.0
    if n_used < MIN_USED_FRACTION * n_all or covered < 0.5 * T:
        ratio = tracks.end_time / T
        if 300.0 <= ratio <= 3000.0:
            hint = "times look like milliseconds: divide t by 1000"
        elif ratio >= 2.0:
            hint = (f"the tracks last {ratio:.0f}x longer than the controls: check that t is in seconds since the "
                    "controls started and that --controls names the gait that was played")
        else:
            hint = "check that t is in seconds since the controls started and that --controls is the gait played"
        failures.append(f"time-span: only {n_used} of {n_all} samples fall within the controls' {T:.3g} s "
                        f"({len(data.u)} steps of {data.dt:g} s), covering {covered:.3g} s of it (the tracks end at "
                        f"{tracks.end_time:.4g} s); try: {hint}")
    L = body_length(data.robot)
    points = np.concatenate([p for _, p in tracks.samples.values()])
    spread = _spread(points)
    speed = _speed(tracks.samples)
    far = 0.0
    if data.frame == "robot":
        far = max(float(np.linalg.norm(np.median(p, axis=0) - data.markers.points[data.markers.names.index(n)]))
                  for n, (_, p) in tracks.samples.items())
    problems = []
    if spread > MAX_SPREAD_BODY_LENGTHS * L:
        problems.append(f"the positions spread over {spread:.3g} m, {spread / L:.0f} body lengths of {L:.3g} m")
    if far > MAX_SPREAD_BODY_LENGTHS * L:
        problems.append(f"a marker stays {far:.3g} m ({far / L:.0f} body lengths) from its rest point")
    if speed > MAX_SPEED_BODY_LENGTHS_PER_S * L:
        problems.append(f"markers move at {speed:.3g} m/s ({speed / L:.3g} body lengths/s, 95th percentile)")
    if problems:
        scale = _scale(tracks, data)
        hint = unit_hint(scale)
        if hint is not None:
            hint += f"; the markers lie {scale:.0f}x as far apart as their rest points"
        elif far > MAX_SPREAD_BODY_LENGTHS * L:
            hint = "tracks in a camera's coordinates need --frame camera (a rigid transform is fitted too)"
        else:
            hint = "check that t is in seconds and x, y, z in metres"
        failures.append(f"plausible-tracks: {'; '.join(problems)}; try: {hint}")
    return failures


def check_fit(fit: CalibrationFit, noise_m: float = DEFAULT_NOISE_M) -> list[str]:
    """The fit checks (module docstring) of ``fit`` with tracker noise ``noise_m`` [m]."""
    failures = []
    expected_mm = 1e3 * np.sqrt(3.0) * noise_m
    if not fit.rms_after_mm <= RMS_NOISE_FACTOR * expected_mm:
        failures.append(f"rms-vs-noise: the RMS marker error after the fit, {fit.rms_after_mm:.4g} mm, is above "
                        f"{RMS_NOISE_FACTOR:g}x the {expected_mm:.3g} mm that tracker noise of --noise {noise_m:g} m "
                        "explains; try: check the tracks' origin and frame (a constant offset or a camera's "
                        "coordinates: --frame camera), the units, the controls played (--controls, --play) and the "
                        "parameters fitted (--fit), or state the tracker's noise with --noise")
    if fit.stopped_at_limit:
        failures.append(f"evaluation-limit: the fit stopped at its limit of rollouts before converging ({fit.message}); "
                        "try: a larger --max-evaluations, fewer parameters in --fit, or a starting robot closer to the "
                        "measured one")
    for n, v, e in zip(fit.names, fit.values, fit.std_errors):
        unit = f" {PHYSICAL_PARAMETERS[n].unit}" if PHYSICAL_PARAMETERS[n].unit else ""
        if not e < abs(v):
            failures.append(f"standard-errors: {n} = {v:.6g} +- {e:.2g}{unit}: the error is not smaller than the "
                            "value, the data do not determine it; try: check the units, tracks that move it more "
                            "(longer, larger motions, more markers), or fewer parameters in --fit")
        if n in PARAMETER_BOUNDS:
            lo, hi = PARAMETER_BOUNDS[n]
            tol = BOUND_TOLERANCE * (hi - lo)
            if v <= lo + tol or v >= hi - tol:
                failures.append(f"at-bounds: {n} = {v:.6g} is at a bound of its range [{lo:g}, {hi:g}]: the best "
                                "fit lies outside what the model allows; try: check the tracks' units and frame and "
                                "the controls, or fit fewer parameters")
    return failures


def check_model_misfit(fit: CalibrationFit, data: MarkerData, noise_m: float = DEFAULT_NOISE_M) -> list[str]:
    """``model-misfit`` (module docstring): the residual after the fit split per marker into its
    mean (a constant offset, which no physical parameter produces) and its scatter about it;
    failed when the offset is the larger part and above :data:`MISFIT_FLOOR_M`. Named in its
    own function so that other misfit checks (a parameter the model lacks) sit beside it."""
    if fit.predicted_after is None or not len(data.times):
        return []
    res = data.values - data.at_samples(fit.predicted_after)             # (N, 3), the measurements' frame
    means = np.zeros_like(res)
    for i in np.unique(data.marker_index):
        sel = data.marker_index == i
        means[sel] = res[sel].mean(axis=0)
    offset = float(np.sqrt(np.mean(np.sum(means ** 2, axis=1))))
    scatter = float(np.sqrt(np.mean(np.sum((res - means) ** 2, axis=1))))
    if not (offset > scatter and offset > MISFIT_FLOOR_M):
        return []
    stated = np.sqrt(3.0) * noise_m
    noise = (f"; --noise {noise_m:g} m states {1e3 * stated:.3g} mm of tracker noise, {stated / scatter:.0f}x the "
             "residual's scatter, so rms-vs-noise cannot see it" if stated > RMS_NOISE_FACTOR * scatter else "")
    return [f"model-misfit: {1e3 * offset:.3g} mm of the {fit.rms_after_mm:.3g} mm RMS marker error after the fit is a "
            f"constant offset of each marker (its scatter about that offset: {1e3 * scatter:.3g} mm), which no "
            f"physical parameter can produce: the fitted values absorb a misfit of the model{noise}; try: check the "
            "tracks' origin and frame (--frame camera fits a rigid transform), the marker points (--marker-points) "
            "and the units"]
