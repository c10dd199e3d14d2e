"""Checks that a result's arrays are what its own keyframes and robot make them, so that what
``trajopt evaluate`` scores (the keyframes, re-expanded) is what ``trajopt play`` streams (the
file's ``u_post``).

:func:`check_controls` runs in :meth:`trajopt.results.Result.validate` (so on every load and
before every save) for results with keyframes; it needs no simulator:

* ``u`` must be the keyframes re-expanded as the optimiser does
  (:class:`~trajopt.optim.parameterization.GaitParameterization`: the prep phase easing from the rest
  contraction into the cycle, then ``n_cycles`` cycles of the Hermite spline), to
  :data:`CONTROL_ATOL`; its length must be the gait's;
* a result made under the motors' speed limit (``settings["motor_limit"]``) obeys it at every
  step of ``u``, from rest and across the wrap-around (:mod:`trajopt.optim.motor_limit`); one
  made under their torque-speed line (``settings["motor_line"]``) obeys it within its tolerance
  at every step of ``u`` under the load torques it records (``evaluation["motor_load"]``,
  :mod:`trajopt.optim.motor_torque`);
* ``u_post`` adds slack only: ``u <= u_post``, and ``u_post <= u_max``;
* with a robot fingerprint (which carries the robot's normalised ``robot.toml``), the motor
  names must be its motors in its order, the rest contraction is the robot's (otherwise one
  rest point common to every prep step), the keyframes must lie in the motor ranges and ``z``
  must be the free motors' keyframes.

:func:`check_zero_slack` (used by :func:`trajopt.evaluation.evaluate_result`, which has the
simulation) checks ``u_post`` against the zero-slack controls of the rollout of ``u``.
Every mismatch is a ValueError naming the file and the array.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..optim.gait import GaitSpec
from ..optim.motor_limit import STEP_ATOL, worst_step
from ..optim.parameterization import GaitParameterization, cycle_basis, prep_ease

__all__ = ["check_controls", "check_zero_slack", "motors_of_fingerprint", "CONTROL_ATOL", "ZERO_SLACK_ATOL"]

#: [m] re-expanded keyframes against the stored u: the same float64 arithmetic, so rounding only
CONTROL_ATOL = 1e-12
#: [m] stored u_post against the zero-slack controls of a new rollout: 30 times the sub-stepped
#: solver's tolerance (soft_envs.sim.substeps.SUBSTEP_TOLERANCE, 1e-6 m per physics step). A
#: replay's plain Newton path and the optimiser's (exact Hessians at every step) part by up to
#: tens of times the tolerance where a foot sticks or slips: 1.7e-6 m for the shipped results
#: (made at 1e-7) replayed at 1e-6, 1.2e-5 m for a co-designed robot written and reloaded; an
#: edit that matters moves a contraction (millimetres) by far more.
ZERO_SLACK_ATOL = 3e-5
#: normalised rounding allowed beyond a recorded line's tolerance (the JSON round trip of its numbers)
LINE_ATOL = 1e-9


def motors_of_fingerprint(fingerprint: dict[str, Any]) -> tuple[list[str], np.ndarray, np.ndarray] | None:
    """``(names, u_bounds (M, 2), mirror_map (M,))`` of the robot.toml recorded in a fingerprint,
    None when it records none (robots built in Python)."""
    motors = (fingerprint or {}).get("toml", {}).get("motors") if isinstance(fingerprint, dict) else None
    if not isinstance(motors, list) or not motors or not all(isinstance(m, dict) for m in motors):
        return None
    try:
        names = [str(m["name"]) for m in motors]
        bounds = np.array([[float(m.get("u_min", 0.0)), float(m["u_max"])] for m in motors])
        mirror = np.array([names.index(m["mirror"]) if m.get("mirror") else i for i, m in enumerate(motors)])
    except (KeyError, TypeError, ValueError):
        return None
    return names, bounds, mirror


def _worst(a: np.ndarray, b: np.ndarray) -> str:
    d = np.abs(a - b)
    k, m = np.unravel_index(int(np.argmax(d)), d.shape)
    return f"step {k}, motor {m}: {a[k, m]:.9g} m stored, {b[k, m]:.9g} m expected"


def check_controls(res: Any, src: str) -> None:
    """Raise ValueError naming ``src`` and the array when ``res`` (a Result with keyframes in
    its settings, already shape-checked) has controls its keyframes do not make."""
    s = res.settings
    spec = GaitSpec.from_settings(s)
    kf = np.asarray(s["keyframes"], dtype=np.float64)          # (M, n_keyframes)
    M = len(res.motor_names)
    robot = motors_of_fingerprint(res.robot_fingerprint)
    rest = None
    if robot is not None:
        names, bounds, mirror = robot
        if list(res.motor_names) != names:
            raise ValueError(f"{src}: field 'motor_names' {list(res.motor_names)} is not the motors of the robot it "
                             f"records (robot_fingerprint: {names})")
        param = GaitParameterization(bounds, mirror, np.clip(0.0, bounds[:, 0], bounds[:, 1]), spec)
        rest = param.u_rest
        lo, hi = bounds[:, 0:1] - CONTROL_ATOL, bounds[:, 1:2] + CONTROL_ATOL
        if ((kf < lo) | (kf > hi)).any():
            raise ValueError(f"{src}: settings field 'keyframes' leaves the motor ranges of its robot")
        if res.z.shape != (param.nz,) or not np.allclose(res.z, param.z_from_keyframes(kf), rtol=0,
                                                          atol=CONTROL_ATOL):
            raise ValueError(f"{src}: field 'z' is not the keyframes of its free motors")
    K = spec.n_steps()
    if len(res.u) != K:
        raise ValueError(f"{src}: field 'u' has {len(res.u)} steps, its gait has {K} (prep {spec.n_prep} + "
                         f"{spec.n_cycles} cycles of {spec.n_cycle})")
    ease = prep_ease(spec.n_prep)
    if rest is None and spec.n_prep and ease[0] < 1.0:         # the rest point the prep starts from
        rest = (res.u[0] - ease[0] * kf[:, 0]) / (1.0 - ease[0])
    rest = np.zeros(M) if rest is None else rest
    cycle = cycle_basis(spec) @ kf.T           # (n_cycle, M)
    prep = ease[:, None] * kf[:, 0][None, :] + (1.0 - ease)[:, None] * rest[None, :]
    expected = np.concatenate([prep, *[cycle] * spec.n_cycles])
    if not np.allclose(res.u, expected, rtol=0, atol=CONTROL_ATOL):
        raise ValueError(f"{src}: field 'u' is not what its keyframes make ({_worst(res.u, expected)}): the "
                         "file was edited; evaluate would score the keyframes, play would stream something else")
    _check_motor_limit(res, rest, spec, src)
    _check_motor_line(res, rest, src)
    if (res.u_post < res.u - CONTROL_ATOL).any():
        k, m = np.argwhere(res.u_post < res.u - CONTROL_ATOL)[0]
        raise ValueError(f"{src}: field 'u_post' is below u at step {k}, motor {m} (zero-slack controls only "
                         "reel cable in)")
    if robot is not None and (res.u_post > robot[1][:, 1] + CONTROL_ATOL).any():
        k, m = np.argwhere(res.u_post > robot[1][:, 1] + CONTROL_ATOL)[0]
        raise ValueError(f"{src}: field 'u_post' leaves the range of motor {res.motor_names[m]!r} at step {k}")


def _check_motor_limit(res: Any, rest: np.ndarray, spec: GaitSpec, src: str) -> None:
    """A result that records the motors' speed limit it was made under (``settings["motor_limit"]``,
    :mod:`trajopt.optim.motor_limit`) obeys it at every step of ``u`` as played, to :data:`STEP_ATOL`."""
    limit = res.settings.get("motor_limit")
    if not isinstance(limit, dict):
        return               # made without the limit, or before it was recorded
    try:
        max_step = np.array([np.inf if v is None else float(v) for v in limit["max_step_m"]])
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{src}: settings field 'motor_limit' has no list 'max_step_m'") from None
    if max_step.shape != (len(res.motor_names),):
        raise ValueError(f"{src}: settings field 'motor_limit' has {max_step.size} motors, the result "
                         f"{len(res.motor_names)}")
    excess, k, m, d = worst_step(res.u, rest, spec.n_prep, spec.n_cycle, max_step)
    if excess > STEP_ATOL:
        raise ValueError(f"{src}: field 'u' moves motor {res.motor_names[m]!r} by {1e3 * abs(d):.4f} mm in step {k} "
                         f"(0: from rest; the last: the wrap-around), beyond the limit it was made under "
                         f"({1e3 * max_step[m]:.4f} mm, settings 'motor_limit')")


def _check_motor_line(res: Any, rest: np.ndarray, src: str) -> None:
    """A result made under the motors' torque-speed line, with the load torques of its states
    recorded, obeys the line at every step of ``u`` (the torque before and after it) and the
    gearbox limit at every state, within the tolerance it records (plus rounding)."""
    line = res.settings.get("motor_line")
    load = (res.evaluation or {}).get("motor_load")
    if not isinstance(line, dict) or not isinstance(load, dict) or "torque_nm" not in load:
        return                 # made under another model, or a checkpoint (no load recorded yet)
    try:
        step = np.array(line["no_load_step_m"], dtype=np.float64)
        stall = np.array(line["stall_torque_nm"], dtype=np.float64)
        limit = np.minimum(np.array(line["max_torque_nm"], dtype=np.float64), stall)
        tol = float(line["tolerance"])
        tau = np.array(load["torque_nm"], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{src}: settings field 'motor_line' or evaluation field 'motor_load' is malformed") from None
    M = len(res.motor_names)
    if step.shape != (M,) or stall.shape != (M,) or tau.shape != (len(res.u) + 1, M):
        raise ValueError(f"{src}: settings field 'motor_line' or evaluation field 'motor_load' does not fit "
                         f"{M} motors and {len(res.u)} steps")
    du = np.diff(np.vstack([rest, res.u]), axis=0) / step
    excess = np.maximum(du + tau[:-1] / stall, du + tau[1:] / stall) - 1.0
    worst = max(float(excess.max()), float((tau[1:] / limit).max() - 1.0))
    if worst > tol + LINE_ATOL:
        k, m = np.unravel_index(int(np.argmax(excess)), excess.shape)
        raise ValueError(f"{src}: field 'u' breaks the motors' torque-speed line it was made under by "
                         f"{100 * worst:.2f} % (motor {res.motor_names[m]!r}, step {k}; tolerance "
                         f"{100 * tol:g} %, settings 'motor_line', evaluation 'motor_load')")


def check_zero_slack(u_post: np.ndarray, expected: np.ndarray, src: str) -> None:
    """Raise ValueError naming ``src`` when the stored ``u_post`` is not ``expected``, the
    zero-slack controls of a new rollout of ``u``."""
    if u_post.shape != expected.shape or not np.allclose(u_post, expected, rtol=0, atol=ZERO_SLACK_ATOL):
        where = _worst(u_post, expected) if u_post.shape == expected.shape else f"shape {u_post.shape}"
        raise ValueError(f"{src}: field 'u_post' is not the zero-slack controls of its u ({where}): the file was "
                         "edited; play would stream controls that evaluate does not score")
