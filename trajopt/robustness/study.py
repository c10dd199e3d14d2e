"""Gait robustness: replay a gait under perturbed physics, motors and ground.

``trajopt robustness RESULT --samples N --cycles C --out DIR`` plays the gait of RESULT (its prep
phase and C cycles) N times, each under perturbations drawn from :data:`PERTURBATIONS`, and
reports the speed distribution (median, 5th and 95th percentiles, in body lengths per minute),
the fraction of replays that stay upright, the heading drift (degrees per cycle), the worst
cases with their perturbations, the rank correlation of the speed with each perturbation (and
with the extra slope's component along the gait's heading) and a plot, beside the nominal replay (the gait as optimised,
which ``trajopt evaluate`` reports).

==========================  ==============================  =========================================
perturbation                range (uniform)                 what
==========================  ==============================  =========================================
``friction``                x 0.5 - 1.5                     the ground friction of the robot's law
                                                            (its friction parameter: paper weight or
                                                            Coulomb coefficient)
``youngs_modulus``          x 0.7 - 1.3                     foam stiffness (fitted, paper II-A)
``density``                 x 0.9 - 1.1                     body mass (weighed)
``payload_mass``            x 0.85 - 1.15                   motor assembly (cables, glue, wiring)
``contact_stiffness``       x 0.5 - 2 (log-uniform)         ground penalty stiffness
``cable_stiffness``         x 0.5 - 2 (log-uniform)         cable (fishing line, Bowden tube) stiffness
``motor_lag_s``             0 - 0.1 s                       first-order lag of the motors
``motor_speed``             x 0.6 - 1.4                     motor speed limit: each motor's
                                                            ``max_speed_rpm`` (robot file)
``timing_jitter_s``         0 - 10 ms                       half-width of a uniform jitter of each
                                                            control's time
``slope_deg``               0 - 10 deg                      extra ground slope ...
``slope_direction_deg``     0 - 360 deg                     ... rising towards this heading
``stall_torque``            x 0.8 - 1.2                     each motor's stall torque (battery sag:
                                                            the torque-speed line's end; gaits made
                                                            under the torque-speed model)
==========================  ==============================  =========================================

The applied controls of a replay are the gait's controls sampled at jittered times, followed by
the motors with the lag ``u_k = u_{k-1} + (1 - exp(-h / tau)) (u_cmd - u_{k-1})`` and at most
``v_max h`` per step (``v_max`` = the ``motor_speed`` factor x the robot's
:attr:`~soft_envs.sim.Robot.max_contraction_speed`, i.e. its ``max_speed_rpm`` x 2 pi / 60 x
spool radius). A gait made under the motors' torque-speed line (``settings["motor_model"]``,
:mod:`soft_envs.sim.motors`) is followed by motors with that line instead: the replay steps an
environment with ``motor_model="torque-speed"`` (winding at most ``v_max h (1 - tau /
stall_torque)`` at the load torque of the state before each step, none beyond ``max_torque``),
its motors' no-load speed scaled by ``motor_speed`` and their stall torque by ``stall_torque``;
gaits made under the speed limit alone are replayed open-loop as before (``stall_torque`` then
plays no part). Randomness is seeded per
sample (``numpy.random.default_rng([seed, i])``), so sample i is the same whatever N and
whichever worker runs it: every sample is one picklable call of :func:`run_sample`, run in
this process or, with ``--workers N``, as Ray tasks when Ray and ``trajopt sweep`` are installed.
Finished samples are appended to ``DIR/samples.jsonl``; a rerun with the same settings reuses
them (and runs only the missing ones, so N can grow).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Iterator

import numpy as np

from soft_envs.envs import (SimulationError, SoftRobotEnv, load_robot, make_gradient_env, scale_parameters, with_box,
                            with_contact_law)

from ..evaluation import measure_gait

__all__ = ["PERTURBATIONS", "DERIVED_NAMES", "SampleJob", "draw_perturbation", "applied_controls",
           "jittered_commands", "lag_share", "perturbed_motors", "stepped_replay", "perturbed_slope", "run_sample",
           "map_samples", "summarize"]

#: name -> (kind, low, high); kind "factor" (uniform), "log" (log-uniform factor) or "value"
PERTURBATIONS = MappingProxyType({
    "friction": ("factor", 0.5, 1.5), "youngs_modulus": ("factor", 0.7, 1.3), "density": ("factor", 0.9, 1.1),
    "payload_mass": ("factor", 0.85, 1.15), "contact_stiffness": ("log", 0.5, 2.0),
    "cable_stiffness": ("log", 0.5, 2.0), "motor_lag_s": ("value", 0.0, 0.1),
    "motor_speed": ("factor", 0.6, 1.4), "timing_jitter_s": ("value", 0.0, 0.010),
    "slope_deg": ("value", 0.0, 10.0), "slope_direction_deg": ("value", 0.0, 360.0),
    "stall_torque": ("factor", 0.8, 1.2)})        # drawn last: the other draws of a seed are as before

#: the perturbations that scale the robot's physical parameters (``friction``: its contact law's friction
#: parameter; :func:`soft_envs.envs.scale_parameters`)
PHYSICAL_FACTORS = ("youngs_modulus", "density", "contact_stiffness", "friction", "payload_mass", "cable_stiffness")

#: what the report relates the speed to: the perturbations and the slope along the gait's heading
DERIVED_NAMES = (*PERTURBATIONS, "slope_along_heading_deg")


def draw_perturbation(seed: int, index: int) -> dict[str, float]:
    """The perturbation of sample ``index`` (its own generator ``default_rng([seed, index])``)."""
    rng = np.random.default_rng([seed, index])
    out = {}
    for name, (kind, lo, hi) in PERTURBATIONS.items():
        out[name] = float(math.exp(rng.uniform(math.log(lo), math.log(hi))) if kind == "log" else rng.uniform(lo, hi))
    return out


@dataclass(frozen=True)
class SampleJob:
    """Everything one replay needs (picklable: a robot spec, arrays and numbers)."""

    robot: str
    u: np.ndarray
    dt: float
    n_prep: int
    n_cycle: int
    heading_deg: float
    incline_deg: float
    seed: int
    index: int
    perturbation: dict | None = None          # None: the nominal replay
    contact: str | None = None                # the gait's contact law (None: the robot file's)
    substeps: int | None = None               # the gait's physics steps per control step (None: the law's)
    motor_model: str = "speed"                # the motors' law the gait was made under
    ground: Any = None                        # the task's ground (a HeightField; None: the robot file's)
    box: Any = None                           # the task's box (carry, push; None: none)


def perturbed_slope(incline_deg: float, uphill_deg: float, slope_deg: float, direction_deg: float
                    ) -> tuple[float, float]:
    """``(incline_deg, uphill_deg)`` of the nominal slope tilted by ``slope_deg`` more, rising
    towards ``direction_deg`` (degrees from +x towards +z): gravity rotated about the horizontal
    axis ``y x d``, then read back as a slope and the direction it rises towards."""
    from scipy.spatial.transform import Rotation

    def down(a, h):
        a, h = math.radians(a), math.radians(h)
        return -np.array([math.sin(a) * math.cos(h), math.cos(a), math.sin(a) * math.sin(h)])
    d = np.array([math.cos(math.radians(direction_deg)), 0.0, math.sin(math.radians(direction_deg))])
    tilt = Rotation.from_rotvec(math.radians(slope_deg) * np.cross([0.0, 1.0, 0.0], d))
    g = tilt.apply(down(incline_deg, uphill_deg))
    incline = math.degrees(math.acos(min(1.0, -g[1])))
    horizontal = -g[[0, 2]]
    uphill = math.degrees(math.atan2(horizontal[1], horizontal[0])) if np.hypot(*horizontal) > 1e-12 else 0.0
    return incline, uphill


def jittered_commands(u: np.ndarray, dt: float, p: dict, rng: np.random.Generator) -> np.ndarray:
    """The commanded controls ``u`` (K, M) sampled at times jittered by ``p["timing_jitter_s"]``."""
    K = len(u)
    t = dt * np.arange(K)
    tj = np.clip(t + rng.uniform(-p["timing_jitter_s"], p["timing_jitter_s"], size=K), 0.0, t[-1])
    return np.stack([np.interp(tj, t, u[:, m]) for m in range(u.shape[1])], axis=1)


def lag_share(dt: float, p: dict) -> float:
    """The share ``1 - exp(-h / tau)`` of the way to its command a lagged motor goes in a step."""
    return 1.0 - math.exp(-dt / p["motor_lag_s"]) if p["motor_lag_s"] > 0 else 1.0


def applied_controls(u: np.ndarray, dt: float, u_start: np.ndarray, bounds: np.ndarray, max_speed: np.ndarray,
                     p: dict, rng: np.random.Generator) -> np.ndarray:
    """The contractions the motors apply (module docstring) for commanded ``u`` (K, M);
    ``max_speed`` (M,) is the nominal contraction speed limit [m/s] (``robot.max_contraction_speed``),
    scaled by ``p["motor_speed"]``."""
    cmd = jittered_commands(u, dt, p, rng)
    alpha = lag_share(dt, p)
    du_max = p["motor_speed"] * np.asarray(max_speed, dtype=np.float64) * dt
    out = np.empty_like(cmd)
    prev = np.asarray(u_start, dtype=np.float64)
    for k in range(len(cmd)):
        prev = prev + np.clip(alpha * (cmd[k] - prev), -du_max, du_max)
        out[k] = prev
    return np.clip(out, bounds[:, 0], bounds[:, 1])


def perturbed_motors(robot: Any, p: dict) -> Any:
    """``robot`` with each motor's no-load speed scaled by ``p["motor_speed"]`` and its stall
    torque by ``p["stall_torque"]``."""
    import dataclasses
    motors = tuple(dataclasses.replace(m, max_speed_rpm=m.max_speed_rpm * p["motor_speed"],
                                       stall_torque=m.stall_torque * p["stall_torque"]) for m in robot.motors)
    return robot.replace(motors=motors)


class _Replayed:
    """The states of a stepped replay as :func:`~trajopt.evaluation.measure_gait` reads them."""

    def __init__(self, x: list[np.ndarray], com: list[np.ndarray]):
        self.x, self.com = np.array(x), np.array(com)


def stepped_replay(env: Any, cmd: np.ndarray, alpha: float) -> _Replayed:
    """Step ``env`` (its motors' law, from its reset state) towards the lagged commands: each
    step's target is ``u + alpha (cmd_k - u)`` from the applied contraction ``u``; a failed step
    raises SimulationError."""
    state = env.get_state()
    u, xs, coms = state["u"], [state["x"]], [env.com()]
    for row in cmd:
        _, _, _, _, info = env.step(env.control_to_action(u + alpha * (row - u)))
        if "sim_failure" in info:
            raise SimulationError(info["sim_failure"])
        u = info["u"]
        xs.append(env.get_state()["x"])
        coms.append(env.com())
    return _Replayed(xs, coms)


def run_sample(job: SampleJob) -> dict[str, Any]:
    """Replay one sample (the nominal gait when ``job.perturbation`` is None): speed [BL/min],
    upright, heading drift [deg per cycle], max tilt, or the simulation failure."""
    t0 = time.perf_counter()
    robot = with_contact_law(load_robot(job.robot), job.contact)
    if job.box is not None:                   # the box is perturbed with the robot (its modulus)
        robot = with_box(robot, job.box)
    u, incline, uphill = np.asarray(job.u, dtype=np.float64), job.incline_deg, job.heading_deg
    p = job.perturbation
    line = p is not None and job.motor_model == "torque-speed"      # motors that follow their line
    if p is not None:
        robot = scale_parameters(robot, {n: p[n] for n in PHYSICAL_FACTORS})   # "friction": the law's
        incline, uphill = perturbed_slope(job.incline_deg, job.heading_deg, p["slope_deg"], p["slope_direction_deg"])
        rng = np.random.default_rng([job.seed, job.index, 1])
        if line:
            robot = perturbed_motors(robot, {"stall_torque": 1.0, **p})
            u = jittered_commands(u, job.dt, p, rng)
        else:
            u = applied_controls(u, job.dt, robot.u_rest, robot.u_bounds, robot.max_contraction_speed, p, rng)
    out: dict[str, Any] = {"index": job.index, **(p or {})}
    if p is not None:          # the part of the extra slope that the gait climbs (> 0) or descends
        out["slope_along_heading_deg"] = p["slope_deg"] * math.cos(math.radians(p["slope_direction_deg"]
                                                                               - job.heading_deg))
    try:
        if line:
            env = SoftRobotEnv(robot, incline_deg=incline, target_heading_deg=uphill, timestep=job.dt,
                               substeps=job.substeps, reset_noise_scale=0.0, motor_model="torque-speed",
                               terminate_when_unhealthy=False, ground=job.ground)
            env.reset(seed=0)
            traj = stepped_replay(env, u, lag_share(job.dt, p))
        else:
            env = make_gradient_env(robot, incline_deg=incline, heading_deg=uphill, timestep=job.dt,
                                    substeps=job.substeps, ground=job.ground)
            traj = env.rollout(u)
    except SimulationError as err:
        out.update(speed_bl_per_min=float("nan"), upright=False, heading_drift_deg_per_cycle=float("nan"),
                   max_tilt_deg=float("nan"), sim_failure=str(err))
    else:
        m = measure_gait(traj, env, n_prep=job.n_prep, n_cycle=job.n_cycle, heading_deg=job.heading_deg)
        out.update(speed_bl_per_min=m["speed_bl_per_min"], upright=m["upright"], max_tilt_deg=m["max_tilt_deg"],
                   heading_drift_deg_per_cycle=m["heading_change_deg"] / m["cycles"])
    out["wall_time_s"] = time.perf_counter() - t0
    return out


def _ray_backend(workers: int) -> tuple[Any, str]:
    """``(ray module or None, a sentence saying where the samples run)``."""
    import importlib.util
    if workers <= 1:
        return None, "in-process"
    if importlib.util.find_spec("ray") is None:
        return None, f"in-process (--workers {workers} needs Ray, which is not installed)"
    if importlib.util.find_spec("trajopt.sweep") is None:
        return None, f"in-process (--workers {workers} needs trajopt sweep's Ray runner, not in this install)"
    from trajopt.sweep.runner import start_ray
    ray, _ = start_ray(workers)
    return ray, f"on Ray with {workers} workers"


def map_samples(jobs: list[SampleJob], workers: int = 1) -> tuple[Iterator[dict], str]:
    """``(results as they finish, where they run)``: :func:`run_sample` of every job, on Ray
    (``workers`` > 1, Ray and ``trajopt sweep`` installed) or one after another here."""
    ray, where = _ray_backend(workers)
    if ray is None:
        return (run_sample(j) for j in jobs), where
    remote = ray.remote(run_sample)

    def gen():
        pending = [remote.remote(j) for j in jobs]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    return gen(), where


def summarize(nominal: dict, samples: list[dict], n_worst: int = 3) -> dict[str, Any]:
    """The report: speed percentiles, upright fraction, heading drift, worst cases, and the rank
    correlation of the speed with each perturbation."""
    from scipy.stats import spearmanr
    speed = np.array([s["speed_bl_per_min"] for s in samples], dtype=float)
    drift = np.abs([s["heading_drift_deg_per_cycle"] for s in samples])
    ok = np.isfinite(speed)
    pct = lambda a, q: float(np.percentile(a, q)) if a.size else float("nan")      # noqa: E731
    order = np.argsort(np.where(ok, speed, -np.inf), kind="stable")
    worst = [{k: v for k, v in samples[i].items() if k != "wall_time_s"} for i in order[:n_worst]]
    corr = {}
    for name in DERIVED_NAMES:
        x = np.array([s.get(name, np.nan) for s in samples], dtype=float)
        use = ok & np.isfinite(x)
        if use.sum() > 2 and np.ptp(x[use]) > 0 and np.ptp(speed[use]) > 0:
            corr[name] = float(spearmanr(x[use], speed[use]).statistic)
    return {"nominal": {k: nominal[k] for k in ("speed_bl_per_min", "upright", "heading_drift_deg_per_cycle",
                                                "max_tilt_deg") if k in nominal},
            "samples": len(samples), "failed": int((~ok).sum()),
            "speed_bl_per_min": {"median": pct(speed[ok], 50), "p5": pct(speed[ok], 5), "p95": pct(speed[ok], 95)},
            "upright_fraction": float(np.mean([bool(s["upright"]) for s in samples])) if samples else float("nan"),
            "heading_drift_deg_per_cycle": {"median_abs": pct(drift[ok], 50), "p95_abs": pct(drift[ok], 95)},
            "worst": worst, "speed_rank_correlation": corr,
            "ranges": {k: list(v) for k, v in PERTURBATIONS.items()}}

