r"""Identification of physical parameters from tracked markers (the paper fits E and nu
"through trial and error", II-A).

Markers are points bound to the mesh (a robot.toml's ``[[markers]]``); their measured tracks
(:mod:`trajopt.calibration.tracks`) are compared, sample by sample, with the simulated markers of the
controls that were played, interpolated between the simulation steps to each sample's time. The
fit minimises the marker residuals

.. math::
    r_{k,i} = p_i(x_k(\theta)) - q_{k,i}, \qquad q_{k,i} = R(\omega) A_0 y_{k,i} + b \;\;
    \text{(camera frame; } q = y \text{ in the robot's frame)}

over the observed samples by Gauss-Newton with a trust region (scipy's ``least_squares``,
method "trf"), with the exact Jacobian ``dp/dtheta`` of the whole rollout, rest state included
(``GradientEnv.rollout_parameters``: the same recurrence as dx/dz, with the energy terms'
``d(dE/dx)/dtheta``). Positive parameters are fitted as ``log theta``, the Poisson ratio as
itself in [-0.99, 0.49]. In the camera frame a rigid transform (rotation vector ``omega``
about the Kabsch estimate ``A_0`` and translation ``b``) is fitted alongside.

Standard errors: ``cov = s^2 (J^T J)^{-1}`` with ``s^2 = |r|^2 / (N - p)`` at the solution,
mapped to the parameters' units. Separability: the parameter columns of J, with the pose
projected out and normalised to unit length, form ``C = J_n^T J_n`` (a correlation-like
matrix); each eigenvalue below ``1e-3`` of the largest names the parameters of its eigenvector
(components above 0.3) that the data cannot tell apart, and a column with no information is
named alone.

What ``trajopt calibrate`` checks before it writes a robot from a fit (units, time span, RMS
against the tracker's noise, evaluation limit, standard errors, bounds):
:mod:`trajopt.calibration.checks`.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from soft_envs.envs import PHYSICAL_PARAMETERS, MarkerSet, SimulationError, make_gradient_env, parameter_values, \
    with_parameters

__all__ = ["MarkerData", "CalibrationFit", "fit_parameters", "simulate_markers", "synthetic_tracks", "kabsch",
           "rotation_jacobian", "separability_warnings", "SEPARABILITY_RATIO", "PARAMETER_BOUNDS"]

#: eigenvalues of the normalised J^T J below this fraction of the largest are flagged
SEPARABILITY_RATIO = 1e-3
#: the fitted parameters with a bounded range (the rest are positive, fitted as their logarithm)
PARAMETER_BOUNDS = {"poisson_ratio": (-0.99, 0.49)}
_MM = 1e3          # residuals are fitted in millimetres (well-scaled tolerances)


@dataclass
class MarkerData:
    """What a calibration fits: the ``robot`` (its current parameters are the starting point),
    the bound ``markers``, the controls ``u`` (K, n_motors) played with simulation step ``dt``
    on ground sloping ``incline_deg`` uphill along ``heading_deg``, and the measured samples:
    ``times`` (N,) [s], ``marker_index`` (N,) into ``markers``, ``values`` (N, 3) [m], in the
    robot's frame or, with ``frame="camera"``, in a camera's. The simulated markers are
    interpolated linearly between the simulation steps to each sample's time (samples outside
    ``[0, K dt]`` are dropped by :meth:`from_tracks`)."""

    robot: Any
    markers: MarkerSet
    u: np.ndarray
    dt: float
    times: np.ndarray
    marker_index: np.ndarray
    values: np.ndarray
    frame: str = "robot"
    incline_deg: float = 0.0
    heading_deg: float = 0.0

    def __post_init__(self):
        if self.frame not in ("robot", "camera"):
            raise ValueError(f"frame must be 'robot' or 'camera', got {self.frame!r}")
        n = len(self.times)
        if self.marker_index.shape != (n,) or self.values.shape != (n, 3):
            raise ValueError(f"times (N,), marker_index (N,) and values (N, 3) must agree, got {self.times.shape}, "
                             f"{self.marker_index.shape} and {self.values.shape}")
        if n < 3:
            raise ValueError(f"only {n} marker samples fall within the {len(self.u) * self.dt:.3g} s of controls: "
                             "need at least 3")
        K = len(self.u)
        s = np.clip(self.times / self.dt, 0.0, K)
        self.step = np.minimum(np.floor(s).astype(np.int64), K - 1)       # interval [step, step + 1]
        self.weight = s - self.step

    @classmethod
    def from_tracks(cls, tracks, robot, markers: MarkerSet, u: np.ndarray, dt: float, **kw) -> "MarkerData":
        """The samples of ``tracks`` (:class:`trajopt.calibration.tracks.Tracks`) within the controls' span."""
        T = len(u) * dt
        t, idx, vals = [], [], []
        for i, name in enumerate(markers.names):
            if name in tracks.samples:
                ts, ps = tracks.samples[name]
                keep = (ts >= 0) & (ts <= T + 1e-9 * dt)
                t.append(ts[keep])
                idx.append(np.full(int(keep.sum()), i))
                vals.append(ps[keep])
        cat = lambda a, shape: np.concatenate(a) if a else np.zeros(shape)      # noqa: E731
        return cls(robot, markers, np.asarray(u, dtype=np.float64), float(dt), cat(t, 0),
                   cat(idx, 0).astype(np.int64), cat(vals, (0, 3)), **kw)

    def truncated(self, fraction: float) -> "MarkerData | None":
        """The first ``fraction`` of the controls and the samples within them (None when fewer
        than 3 samples remain)."""
        K = max(1, int(np.ceil(fraction * len(self.u))))
        keep = self.times <= K * self.dt
        if keep.sum() < 3:
            return None
        return MarkerData(self.robot, self.markers, self.u[:K], self.dt, self.times[keep], self.marker_index[keep],
                          self.values[keep], self.frame, self.incline_deg, self.heading_deg)

    def at_samples(self, p: np.ndarray) -> np.ndarray:
        """Marker quantities ``p`` (K+1, m, ...) at the samples' times (N, ...)."""
        w = self.weight.reshape(-1, *([1] * (p.ndim - 2)))
        return (1.0 - w) * p[self.step, self.marker_index] + w * p[self.step + 1, self.marker_index]


@dataclass
class CalibrationFit:
    """The outcome of :func:`fit_parameters` (values in the units of
    :data:`soft_envs.envs.PHYSICAL_PARAMETERS`; RMS in mm)."""

    names: tuple[str, ...]
    initial: np.ndarray
    values: np.ndarray
    std_errors: np.ndarray
    correlation: np.ndarray
    rms_before_mm: float
    rms_after_mm: float
    rms_per_marker_mm: dict
    n_observations: int
    iterations: int
    message: str
    warnings: list = field(default_factory=list)
    pose: dict | None = None
    predicted_before: np.ndarray | None = None      # (K+1, m, 3) in the measurements' frame
    predicted_after: np.ndarray | None = None
    stopped_at_limit: bool = False     # the last stage ended at max_evaluations, not converged

    def summary(self) -> dict[str, Any]:
        """JSON-ready description (no arrays of tracks)."""
        return {"parameters": {n: {"initial": float(a), "fitted": float(b), "std_error": float(s),
                                   "unit": PHYSICAL_PARAMETERS[n].unit}
                               for n, a, b, s in zip(self.names, self.initial, self.values, self.std_errors)},
                "correlation": self.correlation.tolist(), "rms_before_mm": self.rms_before_mm,
                "rms_after_mm": self.rms_after_mm, "rms_per_marker_mm": self.rms_per_marker_mm,
                "n_observations": self.n_observations, "iterations": self.iterations, "message": self.message,
                "stopped_at_limit": bool(self.stopped_at_limit), "warnings": list(self.warnings), "pose": self.pose}


# ---------------------------------------------------------------------- geometry
def kabsch(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)``: the rotation and translation with ``A src_i + b ~ dst_i`` in least squares
    (points (N, 3), N >= 3 not collinear)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    A = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return A, cd - A @ cs


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v]_x`` for v (..., 3): (..., 3, 3)."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def rotation_jacobian(omega: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``d (R(omega) v) / d omega`` (..., 3, 3) for the rotation vector ``omega`` and points
    ``v`` (..., 3): ``-[R v]_x J_l(omega)`` with the left Jacobian of SO(3)."""
    th = float(np.linalg.norm(omega))
    W = _skew(omega)
    if th < 1e-8:
        Jl = np.eye(3) + 0.5 * W
    else:
        Jl = np.eye(3) + (1 - np.cos(th)) / th**2 * W + (th - np.sin(th)) / th**3 * W @ W
    Rv = np.einsum("ij,...j->...i", Rotation.from_rotvec(omega).as_matrix(), v)
    return -_skew(Rv) @ Jl


# ---------------------------------------------------------------------- simulation
def simulate_markers(data: MarkerData, names: Sequence[str], theta: np.ndarray, jacobian: bool = True):
    """``(p (K+1, m, 3), dp/dtheta (K+1, m, 3, ntheta) or None)``: the markers of the rollout of
    ``data.u`` from rest on the robot with parameters ``names = theta``."""
    robot = with_parameters(data.robot, dict(zip(names, theta)))
    env = make_gradient_env(robot, incline_deg=data.incline_deg, heading_deg=data.heading_deg, timestep=data.dt)
    if not jacobian:
        return data.markers.positions(env.rollout(data.u).x), None
    traj = env.rollout_parameters(data.u, list(names))
    return data.markers.positions(traj.x), data.markers.jacobian(traj.dxdtheta)


def synthetic_tracks(robot, markers: MarkerSet, u: np.ndarray, dt: float, *, rate_hz: float = 30.0,
                     noise_m: float = 5e-4, missing: float = 0.0, camera: tuple | None = None,
                     rng: np.random.Generator | None = None, incline_deg: float = 0.0, heading_deg: float = 0.0):
    """``(times (S,), positions (S, m, 3), mask (S, m))``: what a tracker sampling at ``rate_hz``
    would record of the markers while ``robot`` plays ``u``: the simulated tracks interpolated
    to the sample times, plus Gaussian noise of ``noise_m`` [m] per coordinate, a fraction
    ``missing`` of samples dropped at random, and with ``camera = (A, b)`` expressed in a
    camera frame (``y = A^T (p - b)``, i.e. ``p = A y + b``). For tests, examples, and checking
    what an experiment can identify before making it."""
    rng = np.random.default_rng(0) if rng is None else rng
    env = make_gradient_env(robot, incline_deg=incline_deg, heading_deg=heading_deg, timestep=dt)
    p = markers.positions(env.rollout(u).x)                                  # (K+1, m, 3)
    times = np.arange(0.0, len(u) * dt + 1e-12, 1.0 / rate_hz)
    s = times / dt
    k = np.minimum(np.floor(s).astype(np.int64), len(u) - 1)
    w = (s - k)[:, None, None]
    pos = (1.0 - w) * p[k] + w * p[k + 1] + rng.normal(scale=noise_m, size=(len(times), len(markers), 3))
    if camera is not None:
        A, b = (np.asarray(a, dtype=np.float64) for a in camera)
        pos = (pos - b) @ A
    mask = rng.random((len(times), len(markers))) >= missing
    return times, pos, mask


class _Problem:
    """The residual function of :func:`fit_parameters` over ``v = (transformed theta, pose)``."""

    def __init__(self, data: MarkerData, names: tuple[str, ...]):
        self.data, self.names = data, names
        self.log = np.array([PHYSICAL_PARAMETERS[n].positive for n in names])
        self.np = len(names)
        self.y = data.values                                  # (N, 3)
        self.A0, self._cache = np.eye(3), None
        self.camera = data.frame == "camera"

    def theta(self, v: np.ndarray) -> np.ndarray:
        t = v[:self.np].copy()
        t[self.log] = np.exp(t[self.log])
        return t

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of v: the Poisson ratio in [-0.99, 0.49], the rest free."""
        n = self.np + (6 if self.camera else 0)
        lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
        for j, name in enumerate(self.names):
            if name == "poisson_ratio":
                lo[j], hi[j] = PARAMETER_BOUNDS[name]
        return lo, hi

    def v0(self, theta: np.ndarray) -> np.ndarray:
        t = np.array(theta, dtype=np.float64)
        t[self.log] = np.log(t[self.log])
        if not self.camera:
            return t
        pred, _ = simulate_markers(self.data, self.names, theta, jacobian=False)
        self.A0, b = kabsch(self.y, self.data.at_samples(pred))
        return np.concatenate([t, np.zeros(3), b])

    def measured(self, v: np.ndarray) -> np.ndarray:
        """The measurements in the robot's frame (N, 3)."""
        if not self.camera:
            return self.y
        R = Rotation.from_rotvec(v[self.np:self.np + 3]).as_matrix() @ self.A0
        return self.y @ R.T + v[self.np + 3:]

    def evaluate(self, v: np.ndarray):
        key = v.tobytes()
        if self._cache is None or self._cache[0] != key:
            try:
                pred, dp = simulate_markers(self.data, self.names, self.theta(v))
            except (SimulationError, ValueError):
                pred = dp = None
            self._cache = (key, pred, dp)
        return self._cache[1], self._cache[2]

    def residuals(self, v: np.ndarray) -> np.ndarray:
        pred, _ = self.evaluate(v)
        if pred is None:
            return np.full(3 * len(self.y), np.inf)
        return _MM * (self.data.at_samples(pred) - self.measured(v)).ravel()

    def jac(self, v: np.ndarray) -> np.ndarray:
        _, dp = self.evaluate(v)
        J = self.data.at_samples(dp)                            # (N, 3, np) in theta
        scale = np.where(self.log, self.theta(v), 1.0)         # d theta / d v
        J = J * scale
        if self.camera:
            Ay = self.y @ self.A0.T
            Jw = -rotation_jacobian(v[self.np:self.np + 3], Ay)           # r = p - (R A0 y + b)
            Jb = -np.broadcast_to(np.eye(3), (len(self.y), 3, 3))
            J = np.concatenate([J, Jw, Jb], axis=2)
        return _MM * J.reshape(3 * len(self.y), -1)


def separability_warnings(J_theta: np.ndarray, names: Sequence[str], J_other: np.ndarray | None = None
                          ) -> tuple[list[str], np.ndarray]:
    """``(warnings, normalised J^T J)`` for the parameter columns ``J_theta`` (N, p), after
    projecting out ``J_other`` (the pose) (module docstring)."""
    J = np.array(J_theta, dtype=np.float64)
    scale = max(np.linalg.norm(J, axis=0).max(), 1e-300)
    if J_other is not None and J_other.size:
        J = J - J_other @ np.linalg.lstsq(J_other, J, rcond=None)[0]
    norms = np.linalg.norm(J, axis=0)
    out, live = [], norms > 1e-8 * scale
    for n in np.asarray(names)[~live]:
        out.append(f"the data carry no information about {n} (the markers do not move when it changes)")
    C = np.eye(len(names))
    if live.sum():
        Jn = J[:, live] / norms[live]
        C[np.ix_(live, live)] = Jn.T @ Jn
        w, V = np.linalg.eigh(C[np.ix_(live, live)])
        for lam, vec in zip(w, V.T):
            if lam < SEPARABILITY_RATIO * w[-1]:
                group = [n for n, c in zip(np.asarray(names)[live], vec) if abs(c) > 0.3]
                combo = " ".join(f"{c:+.2f} {n}" for n, c in zip(np.asarray(names)[live], vec) if abs(c) > 0.3)
                out.append(f"the data cannot separate {', '.join(group)}: the combination {combo} (relative "
                           f"changes) is undetermined (eigenvalue {lam / w[-1]:.1e} of the largest)")
    return out, C


def fit_parameters(data: MarkerData, names: Sequence[str], *, horizons: Sequence[float] = (0.25, 0.5, 1.0),
                   max_evaluations: int = 30, initial: Sequence[float] | None = None) -> CalibrationFit:
    """Fit the physical parameters ``names`` to the marker samples of ``data`` (module
    docstring), starting from the robot's values (or ``initial``).

    The fit runs on growing ``horizons`` (fractions of the controls' span), each warm-started
    from the last: residuals of long rollouts have local minima that the short ones do not
    (measured on the Coulomb-law Tripod, hidden values 20-25 % from the start: fitted on the
    whole span at once, E ends 18 % and mu 56 % off at 0.83 mm RMS; in three stages both are
    recovered to 1e-6). ``max_evaluations`` bounds the rollouts of each stage."""
    names = tuple(names)
    if not names:
        raise ValueError("give at least one parameter to fit")
    theta = parameter_values(data.robot, names) if initial is None else np.asarray(initial, dtype=np.float64)
    start = theta.copy()
    full = _Problem(data, names)
    v_start = full.v0(theta)
    r0 = full.residuals(v_start)
    if not np.isfinite(r0).all():
        raise ValueError("the simulation fails at the starting parameters: cannot calibrate from there")
    before, _ = full.evaluate(v_start)
    to_frame0 = _to_measurement_frame(full, v_start)
    predicted_before = to_frame0(before)
    nfev, message, at_limit = 0, "", False
    for frac in horizons:
        stage = data if frac >= 1.0 else data.truncated(frac)
        if stage is None:
            continue
        prob = full if stage is data else _Problem(stage, names)
        v0 = prob.v0(theta)
        lo, hi = prob.bounds()
        tol = 1e-8 if stage is data else 1e-4          # earlier stages only find the basin
        sol = least_squares(prob.residuals, np.clip(v0, lo, hi), jac=prob.jac, bounds=(lo, hi), method="trf",
                            x_scale="jac", ftol=tol, xtol=tol, gtol=1e-10, max_nfev=max_evaluations)
        theta, nfev, message = prob.theta(sol.x), nfev + int(sol.nfev), str(sol.message)
        at_limit = sol.status == 0                # max_nfev reached (scipy's status 0)
        v = sol.x
    if full is not prob:                      # the last horizon was shorter than the data
        v = full.v0(theta)
    return _analyse(full, v, start, r0, predicted_before, nfev, message, at_limit)


def _analyse(prob: _Problem, v: np.ndarray, start: np.ndarray, r0: np.ndarray, predicted_before: np.ndarray,
             nfev: int, message: str, at_limit: bool = False) -> CalibrationFit:
    """Values, standard errors, correlations, separability warnings and RMS at the solution."""
    data, names = prob.data, prob.names
    r, J = prob.residuals(v), prob.jac(v)
    N, p = len(r), len(v)
    s2 = float(r @ r) / max(N - p, 1)
    cov = s2 * np.linalg.pinv(J.T @ J)
    theta = prob.theta(v)
    std = np.sqrt(np.maximum(np.diag(cov)[:prob.np], 0.0)) * np.where(prob.log, theta, 1.0)
    warns, _ = separability_warnings(J[:, :prob.np], names, J[:, prob.np:] if prob.camera else None)
    d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    corr = (cov / np.outer(d, d))[:prob.np, :prob.np]
    after, _ = prob.evaluate(v)
    res = data.at_samples(after) - prob.measured(v)
    per_marker = {m: float(_MM * np.sqrt(np.mean(np.sum(res[data.marker_index == i] ** 2, axis=1))))
                  for i, m in enumerate(data.markers.names) if (data.marker_index == i).any()}
    rms = lambda rr: float(np.sqrt(3.0 * np.mean(rr ** 2)))      # noqa: E731  RMS distance [mm]
    pose = None
    if prob.camera:
        R = Rotation.from_rotvec(v[prob.np:prob.np + 3]).as_matrix() @ prob.A0
        pose = {"rotation_camera_to_robot": R.tolist(), "translation_m": v[prob.np + 3:].tolist()}
    return CalibrationFit(names, start, theta, std, corr, rms(r0), rms(r), per_marker, N // 3, nfev, message, warns,
                          pose, predicted_before, _to_measurement_frame(prob, v)(after), at_limit)


def _to_measurement_frame(prob: _Problem, v: np.ndarray):
    """The map of predicted marker positions (robot frame) into the measurements' frame."""
    if not prob.camera:
        return lambda p: p
    R = Rotation.from_rotvec(v[prob.np:prob.np + 3]).as_matrix() @ prob.A0
    b = v[prob.np + 3:]
    return lambda p: (p - b) @ R
