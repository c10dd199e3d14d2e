"""The motors' speed limit on a gait's controls.

A motor's contraction moves at most ``v_max h`` in a simulation step of h seconds, ``v_max =
max_speed_rpm * 2 pi / 60 * spool_radius`` (:attr:`soft_envs.sim.Robot.max_contraction_speed`).
An optimised gait obeys it at every step of its controls as played for any number of cycles:

* from rest into the prep phase (``u_rest -> u[0]``), within the prep phase, from the prep
  phase into the cycle,
* within the cycle, and from the cycle's last step to its first (the wrap-around, played
  between cycles).

The controls are affine in the keyframes z (:class:`~trajopt.optim.parameterization.GaitParameterization`:
``u = offset + dudz z``), so each step's change is too, and the limit is a set of linear
inequalities ``G z <= h``: for every such step k -> k+1 and motor m,
``+-((dudz[k+1, m] - dudz[k, m]) z + offset[k+1, m] - offset[k, m]) <= max_step[m]``,
evaluated from the parameterisation's own affine map (so they are exact for whatever it
does: the prep ease, cycles, symmetry, tendon pairs). Rows that repeat (mirror motors play
the same steps half a cycle later) are kept once. :mod:`trajopt.optim.gauss_newton` keeps its
iterates inside; :func:`project_start` moves an infeasible start (a warm start made without
the limit) to the nearest feasible keyframes.

A result records the limit it was made under in ``settings["motor_limit"]`` (:func:`settings_entry`;
None: made without) and :func:`worst_step` measures a control sequence against it.

The motor models (:data:`MOTOR_MODELS`, the names of :data:`soft_envs.envs.MOTOR_MODELS`, written
here too because this module is read without the simulator): ``"torque-speed"`` adds the
torque-speed line to this limit (:mod:`trajopt.optim.motor_torque`), ``"speed"`` is this limit
alone, ``"ideal"`` none. :func:`choose_motor_model` picks an optimisation's, :func:`motor_model_of`
reads a result's (older results: ``"speed"`` when they record the limit, else ``"ideal"``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .parameterization import GaitParameterization
from .qp import LinearConstraints, nearest_feasible

__all__ = ["speed_limit_constraints", "gait_constraints", "played_steps", "worst_step", "max_step_of_env",
           "describe_projection", "max_step_of_fingerprint", "playback_note", "rest_keyframes",
           "settings_entry", "project_start", "STEP_ATOL", "MOTOR_MODELS", "TORQUE_SPEED", "SPEED", "IDEAL",
           "choose_motor_model", "motor_model_of"]

#: [m] what a recorded limit allows beyond ``max_step`` when a result is checked (rounding only)
STEP_ATOL = 1e-9
TORQUE_SPEED, SPEED, IDEAL = "torque-speed", "speed", "ideal"
#: the motor models, the default first (module docstring)
MOTOR_MODELS = (TORQUE_SPEED, SPEED, IDEAL)


def choose_motor_model(env: Any, motor_model: str | None, motor_limit: bool = True) -> str:
    """The motor model of an optimisation: ``motor_model``, else the environment's
    (``env.motor_model``; :data:`TORQUE_SPEED` for one without); ``motor_limit=False`` (the
    flag of before the line) is :data:`IDEAL`. ValueError for an unknown name or a contradiction."""
    if motor_model is not None and motor_model not in MOTOR_MODELS:
        raise ValueError(f"motor_model must be one of {', '.join(map(repr, MOTOR_MODELS))}, got {motor_model!r}")
    if not motor_limit:
        if motor_model not in (None, IDEAL):
            raise ValueError(f"motor_limit=False (no limit) contradicts motor_model={motor_model!r}")
        return IDEAL
    return motor_model if motor_model is not None else getattr(env, "motor_model", TORQUE_SPEED)


def motor_model_of(settings: dict[str, Any]) -> str:
    """The motor model a result was made under (``settings["motor_model"]``; results of before
    it: :data:`SPEED` when they record the speed limit, else :data:`IDEAL`)."""
    model = settings.get("motor_model")
    if model is None:
        return SPEED if settings.get("motor_limit") else IDEAL
    return str(model)


def max_step_of_env(env: Any) -> np.ndarray:
    """(M,) the largest change of each motor's contraction in one of ``env``'s simulation steps [m]:
    the environment's motors (``motor_speed``: the robot's limit, or the env's ``motor_speed_rpm``
    override; inf: no limit), else the robot's."""
    speed = getattr(env, "motor_speed", None)
    if speed is None:
        speed = env.robot.max_contraction_speed
    return np.asarray(speed, dtype=np.float64) * float(env.timestep)


def _step_maps(param: GaitParameterization) -> tuple[np.ndarray, np.ndarray]:
    """``(D, c)``: (S, M, nz) and (S, M) with the change of step s, ``D[s] z + c[s]``, over
    the S = n_prep + n_cycle + 1 steps of rest -> prep -> one cycle -> its first step again."""
    n = param.n_prep + param.n_cycle + 1
    dudz = param.dudz(n_cycles=2)[:n]                      # prep, cycle 1, first step of cycle 2
    offset = param.offset(n_cycles=2)[:n]
    dudz = np.concatenate([np.zeros((1, *dudz.shape[1:])), dudz])          # rest: no parameters ...
    offset = np.concatenate([param.u_rest[None, :], offset])                # ... at u_rest
    return np.diff(dudz, axis=0), np.diff(offset, axis=0)


def speed_limit_constraints(param: GaitParameterization, max_step: np.ndarray) -> LinearConstraints:
    """``G z <= h`` with every step of the controls as played (module docstring) moving each
    motor m at most ``max_step[m]`` [m]; motors with an infinite ``max_step`` are free."""
    max_step = np.asarray(max_step, dtype=np.float64).reshape(-1)
    if max_step.shape != (param.n_motors,) or (max_step <= 0).any() or np.isnan(max_step).any():
        raise ValueError(f"max_step must be {param.n_motors} positive numbers [m], got {max_step}")
    D, c = _step_maps(param)
    limited = np.isfinite(max_step)
    D, c = D[:, limited], c[:, limited]
    bound = np.broadcast_to(max_step[limited], c.shape)
    G = np.concatenate([D.reshape(-1, param.nz), -D.reshape(-1, param.nz)])
    h = np.concatenate([(bound - c).ravel(), (bound + c).ravel()])
    rows = np.unique(np.column_stack([G, h]), axis=0)
    return LinearConstraints(rows[:, :-1], rows[:, -1])


def gait_constraints(param: GaitParameterization, max_step: np.ndarray) -> LinearConstraints:
    """The speed limit and the keyframe bounds together: the feasible set of a start."""
    return speed_limit_constraints(param, max_step) & LinearConstraints.box(*param.bounds())


def played_steps(u: np.ndarray, u_rest: np.ndarray, n_prep: int, n_cycle: int) -> np.ndarray:
    """(S, M) every step's change of the controls ``u`` (prep + cycles) as played for many
    cycles: from ``u_rest`` into ``u[0]``, along ``u``, and from the last cycle's end to its start."""
    u = np.asarray(u, dtype=np.float64)
    wrap = u[n_prep] - u[-1] if len(u) >= n_prep + n_cycle else np.zeros(u.shape[1])
    return np.vstack([u[0] - np.asarray(u_rest, dtype=np.float64), np.diff(u, axis=0), wrap])


def worst_step(u: np.ndarray, u_rest: np.ndarray, n_prep: int, n_cycle: int, max_step: np.ndarray
               ) -> tuple[float, int, int, float]:
    """``(excess, step, motor, change)``: the step of :func:`played_steps` that exceeds its
    motor's ``max_step`` the most (``excess`` = ``|change| - max_step`` [m], <= 0 when none
    does; ``step`` 0 is rest -> u[0], the last is the wrap-around)."""
    d = played_steps(u, u_rest, n_prep, n_cycle)
    over = np.abs(d) - np.asarray(max_step, dtype=np.float64)[None, :]
    k, m = np.unravel_index(int(np.argmax(over)), over.shape)
    return float(over[k, m]), int(k), int(m), float(d[k, m])


def settings_entry(robot: Any, max_step: np.ndarray | None, dt: float) -> dict[str, Any] | None:
    """What a result records of the limit it was made under (None: made without): each motor's
    contraction step limit [m] and speed [m/s], and its rpm (the speed over the spool)."""
    if max_step is None:
        return None
    step = np.asarray(max_step, dtype=np.float64)
    radius = np.array([m.spool_radius for m in robot.motors])
    speed = step / float(dt)
    return {"max_step_m": [float(s) if np.isfinite(s) else None for s in step],
            "max_speed_mps": [float(v) if np.isfinite(v) else None for v in speed],
            "max_speed_rpm": [float(v / (2 * np.pi * r) * 60) if np.isfinite(v) else None
                              for v, r in zip(speed, radius)]}


def rest_keyframes(param: GaitParameterization) -> np.ndarray:
    """Keyframes that hold every motor at rest (no step moves): a point inside the limit."""
    kf = np.repeat(param.u_rest[:, None], param.n_keyframes, axis=1)
    return np.clip(param.z_from_keyframes(kf), *param.bounds())


def project_start(z: np.ndarray, param: GaitParameterization, constraints: LinearConstraints
                  ) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``(z, report)``: ``z`` when it obeys ``constraints`` (the speed limit and the keyframe
    bounds; report None), else the nearest keyframes that do, in the Euclidean metric of the
    keyframes [m] (a QP), with a report: the worst violation before [m] and the distance moved
    (largest keyframe change and RMS [m])."""
    z = np.asarray(z, dtype=np.float64)
    if constraints.feasible(z, atol=0.0):
        return z, None
    before = constraints.violation(z)
    lo, hi = param.bounds()
    p = nearest_feasible(z, constraints, anchor=rest_keyframes(param), scale=np.where(hi > lo, hi - lo, 1.0))
    p = np.clip(p, lo, hi)
    return p, {"violation_before_m": before, "moved_max_m": float(np.abs(p - z).max()),
               "moved_rms_m": float(np.sqrt(np.mean((p - z) ** 2)))}


def describe_projection(report: dict[str, Any], source: str, max_step: np.ndarray) -> str:
    """How far a start was moved into the limit (:func:`project_start`) and into the torque-speed
    line (its ``"line"`` entry, :func:`trajopt.optim.motor_torque.project_into_line`): a line each."""
    lines = []
    if "violation_before_m" in report:
        limit = "/".join(dict.fromkeys(f"{1e3 * s:.3f}" for s in np.asarray(max_step, dtype=np.float64)))
        lines.append(f"{source}: breaks the motors' speed limit ({limit} mm per step) by up to "
                     f"{1e3 * report['violation_before_m']:.3f} mm in a step; projected onto it: keyframes moved by up "
                     f"to {1e3 * report['moved_max_m']:.3f} mm ({1e3 * report['moved_rms_m']:.3f} mm RMS)")
    line = report.get("line")
    if line is not None:
        what = "gearbox torque limit" if line["line_violation_kind"] == "torque" else "torque-speed line"
        lines.append(f"{source}: breaks the motors' {what} by up to {100 * line['line_violation_before']:.2f} %; "
                     f"moved into the line in {line['rounds']} linearisation(s): keyframes moved by up to "
                     f"{1e3 * line['moved_max_m']:.3f} mm ({1e3 * line['moved_rms_m']:.3f} mm RMS)")
    return "\n".join(lines)


def max_step_of_fingerprint(fingerprint: dict[str, Any] | None, dt: float) -> tuple[list[float], np.ndarray] | None:
    """``(rpm, max_step)`` of the motors of the ``robot.toml`` a result's fingerprint records
    (``max_speed_rpm`` default 100, ``spool_radius`` default 5 mm; no simulator needed), None
    when it records none."""
    motors = (fingerprint or {}).get("toml", {}).get("motors") if isinstance(fingerprint, dict) else None
    if not isinstance(motors, list) or not all(isinstance(m, dict) for m in motors):
        return None
    try:
        rpm = [float(m.get("max_speed_rpm", 100.0)) for m in motors]
        radius = np.array([float(m.get("spool_radius", 0.005)) for m in motors])
    except (TypeError, ValueError):
        return None
    return rpm, np.array(rpm) * 2.0 * np.pi / 60.0 * radius * float(dt)


def playback_note(res: Any, loops: int = 1) -> str | None:
    """What ``trajopt play`` says of a result's ``u_post`` (as streamed: sample to sample, and
    from the last to the first when looped) against its robot's motors: each motor's largest
    step as a share of its limit, a warning when beyond it. None without a recorded robot."""
    limit = max_step_of_fingerprint(getattr(res, "robot_fingerprint", None), res.dt)
    u = np.asarray(res.u_post, dtype=np.float64)
    if limit is None or u.ndim != 2 or u.shape[1] != len(limit[0]) or len(u) < 2:
        return None
    rpm, max_step = limit
    steps = np.abs(np.diff(np.vstack([u, u[:1]]) if loops > 1 else u, axis=0)).max(axis=0)
    share = ", ".join(f"{name} {1e3 * s:.3f} mm ({100 * s / m:.0f} %)"
                      for name, s, m in zip(res.motor_names, steps, max_step))
    text = (f"largest step of each motor against its robot's limit (robot.toml max_speed_rpm "
            f"{'/'.join(f'{r:g}' for r in sorted(set(rpm)))} rpm: "
            f"{'/'.join(f'{1e3 * m:.3f}' for m in sorted(set(max_step)))} mm per {res.dt:g} s step): {share}")
    if (steps > max_step + STEP_ATOL).any():
        text = f"warning: {text}; the motors cannot follow the steps beyond 100 %"
    return text
