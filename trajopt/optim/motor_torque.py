r"""The motors' torque-speed line on a gait's controls: inequalities on z, linearised at
every iterate through the tensions' exact sensitivities.

The law (:mod:`soft_envs.sim.motors`, reached through :mod:`soft_envs.envs`): a motor winding
its cable moves at most ``v_0 h (1 - tau / tau_stall)`` in a step of h seconds, and its load
torque ``tau = r sum_{t in m} Q'(Gamma_t)`` never exceeds its gearbox's ``tau_max``. A gait
obeys it at every control step it plays, for any number of cycles: with the optimised horizon's
K steps k = 0..K-1 (``u_{-1} = u_rest``) these are rest -> prep, within the prep, prep -> cycle,
within cycle 1, cycle 1's last row -> cycle 2's first (the wrap-around, played between any two
cycles) and within cycle 2; a one-cycle horizon adds the wrap-around step after it. Step k goes
from state k to state k+1 (the rollout's ``cable_deformation[k]``, ``[k + 1]``). For every such
step and motor m, normalised by the no-load step ``s_m = v_0 h``:

.. math::
    e^{before}_{k,m} = \frac{\Delta u_{k,m}}{s_m} + \frac{\tau_m(x_k)}{\tau_{stall,m}} - 1 \le 0, \qquad
    e^{after}_{k,m} = \frac{\Delta u_{k,m}}{s_m} + \frac{\tau_m(x_{k+1})}{\tau_{stall,m}} - 1 \le 0

(the motor keeps up all through the step: the torque at its start and at its end), and at every
state k = 1..K ``e^{torque}_{k,m} = tau_m(x_k) / tau_lim,m - 1 <= 0`` with
``tau_lim = min(tau_max, tau_stall)`` (beyond the stall torque the motor would be back-driven,
which is not modelled). Unwinding is held by the speed limit's rows
(:mod:`trajopt.optim.motor_limit`), which hold as they are.

``Delta u_k = D_k z + c_k`` is affine in z (:func:`played_step_maps`); ``tau(x_k(z))`` is not,
and is linearised at the current keyframes z0 by its exact sensitivity
``d tau_m / dz = r_m sum_{t in m} Q''(Gamma_t) dGamma_t / dz`` (the rollout's ``dgammadz``):
``tau(z) ~ tau(z0) + (d tau / dz)(z - z0)``, which makes every condition a row of ``G z <= h``
(:meth:`MotorLine.linearised`). Gauss-Newton takes the rows again after every accepted step
(:func:`trajopt.optim.gauss_newton.gauss_newton`'s ``constraints`` as a function of z) and
refuses a line-search trial whose own rollout breaks a condition by more than
:data:`LINE_TOLERANCE` (1 % of the line: :meth:`MotorLine.worst`), so every accepted iterate
obeys the true conditions within 1 %. :func:`project_into_line` moves a start outside the line
into it (the nearest keyframes of the linearisation, tightened by :data:`PROJECTION_MARGIN`,
taken again until the true conditions hold; else drawn towards rest).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .parameterization import GaitParameterization
from .qp import LinearConstraints, QPError, nearest_feasible

__all__ = ["played_step_maps", "MotorLine", "LineViolation", "project_into_line", "line_settings_entry",
           "motor_load_entry", "LINE_TOLERANCE", "PROJECTION_MARGIN"]

#: the share of the line a line-search trial may exceed it by (normalised excess)
LINE_TOLERANCE = 0.01
#: normalised margin a projection aims inside the linearised line (its curvature then keeps the
#: projected keyframes inside the true one)
PROJECTION_MARGIN = 1e-3


def played_step_maps(param: GaitParameterization) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(D, c, before, after)``: every played step s (module docstring) as its change
    ``D[s] z + c[s]`` ((S, M, nz), (S, M)) from state ``before[s]`` to state ``after[s]`` (S,)
    of the horizon's rollout (-1: beyond it, the wrap-around step of a one-cycle horizon)."""
    dudz, offset = param.dudz(), param.offset()
    K = len(dudz)
    dudz_prev = np.concatenate([np.zeros((1, *dudz.shape[1:])), dudz[:-1]])
    offset_prev = np.concatenate([param.u_rest[None, :], offset[:-1]])
    D, c = dudz - dudz_prev, offset - offset_prev
    before, after = np.arange(K), np.arange(1, K + 1)
    if param.gait.n_cycles < 2:                 # the wrap-around is no step of the horizon
        n = param.n_prep
        D = np.concatenate([D, (dudz[n] - dudz[-1])[None]])
        c = np.concatenate([c, (offset[n] - offset[-1])[None]])
        before, after = np.append(before, K), np.append(after, -1)
    return D, c, before, after


@dataclass(frozen=True)
class LineViolation:
    """The worst condition of a gait: its normalised ``excess`` (> 0: broken), ``kind``
    (``"line_before"``, ``"line_after"`` or ``"torque"``), played ``step`` (for ``"torque"``: the
    state) and ``motor``."""

    excess: float
    kind: str
    step: int
    motor: int

    def describe(self, motor_names: list[str] | None = None) -> str:
        name = motor_names[self.motor] if motor_names else str(self.motor)
        where = f"state {self.step}" if self.kind == "torque" else f"step {self.step}"
        what = {"torque": "its gearbox's torque limit", "line_before": "its torque-speed line (torque before the step)",
                "line_after": "its torque-speed line (torque after the step)"}[self.kind]
        return f"motor {name!r} exceeds {what} by {100 * self.excess:.2f} % at {where}"


class MotorLine:
    """The conditions of the module docstring for ``param``'s gaits under the motors ``law`` (a
    :class:`soft_envs.envs.MotorLaw`) with time step ``dt`` [s]."""

    def __init__(self, param: GaitParameterization, law: Any, dt: float):
        self.param, self.law = param, law
        self.D, self.c, self.before, self.after = played_step_maps(param)
        self.step = np.asarray(law.no_load_speed, dtype=np.float64) * float(dt)        # s_m [m]
        self.stall = np.asarray(law.stall_torque, dtype=np.float64)
        self.limit = np.minimum(np.asarray(law.max_torque, dtype=np.float64), self.stall)
        self._has_after = self.after >= 0

    def changes(self, z: np.ndarray) -> np.ndarray:
        """(S, M) each played step's change of the controls [m]."""
        return np.einsum("smz,z->sm", self.D, np.asarray(z, dtype=np.float64)) + self.c

    def excess(self, z: np.ndarray, gamma: np.ndarray) -> dict[str, np.ndarray]:
        """The normalised excess of every condition of keyframes ``z`` whose rollout has cable
        deformations ``gamma`` (K+1, T): ``line_before`` (S, M), ``line_after`` (S', M) (the steps
        whose after-state is in the rollout), ``torque`` (K, M) (states 1..K)."""
        tau = self.law.torque(np.asarray(gamma, dtype=np.float64))                  # (K+1, M)
        speed = self.changes(z) / self.step
        return {"line_before": speed + tau[self.before] / self.stall - 1.0,
                "line_after": speed[self._has_after] + tau[self.after[self._has_after]] / self.stall - 1.0,
                "torque": tau[1:] / self.limit - 1.0}

    def worst(self, z: np.ndarray, gamma: np.ndarray) -> LineViolation:
        """The condition of ``z`` (rollout deformations ``gamma``) with the largest excess."""
        best = None
        for kind, e in self.excess(z, gamma).items():
            if e.size == 0:
                continue
            k, m = np.unravel_index(int(np.argmax(e)), e.shape)
            step = int(k) + 1 if kind == "torque" else int(np.flatnonzero(self._has_after)[k]
                                                           if kind == "line_after" else k)
            if best is None or e[k, m] > best.excess:
                best = LineViolation(float(e[k, m]), kind, step, int(m))
        return best

    def linearised(self, z0: np.ndarray, gamma: np.ndarray, dgammadz: np.ndarray, margin: float = 0.0,
                   clamp: bool = True, theta0: np.ndarray | None = None,
                   dgammadtheta: np.ndarray | None = None) -> LinearConstraints:
        """``G z <= h``: the conditions linearised at ``z0`` (rollout deformations ``gamma``
        (K+1, T) and their sensitivities ``dgammadz`` (K+1, T, nz)), tightened by ``margin``
        (normalised). With ``clamp``, a condition ``z0`` breaks (a trial accepted within the
        tolerance) is relaxed to where ``z0`` stands: it may not get worse (``z0`` is feasible).
        With ``theta0`` and ``dgammadtheta`` (K+1, T, ntheta), other parameters the tensions
        depend on (co-design: the robot's design), the rows are on ``[z; theta]``, linearised at
        ``[z0; theta0]`` (the speeds depend on z only)."""
        z0 = np.asarray(z0, dtype=np.float64)
        nz = len(z0)
        w0, dgammadw = z0, np.asarray(dgammadz, dtype=np.float64)
        if dgammadtheta is not None:
            w0 = np.concatenate([z0, np.asarray(theta0, dtype=np.float64)])
            dgammadw = np.concatenate([dgammadw, np.asarray(dgammadtheta, dtype=np.float64)], axis=-1)
        nw = len(w0)
        tau = self.law.torque(np.asarray(gamma, dtype=np.float64))                  # (K+1, M)
        J = self.law.torque_jacobian(gamma, dgammadw)                               # (K+1, M, nw)
        tau_fixed = tau - J @ w0                                                    # tau(w) = tau_fixed + J w
        speed_G = np.zeros((*self.D.shape[:2], nw))
        speed_G[:, :, :nz] = self.D / self.step[None, :, None]
        speed_h = 1.0 - self.c / self.step[None, :]
        blocks = [(speed_G + J[self.before] / self.stall[None, :, None],
                   speed_h - tau_fixed[self.before] / self.stall),
                  (speed_G[self._has_after] + J[self.after[self._has_after]] / self.stall[None, :, None],
                   speed_h[self._has_after] - tau_fixed[self.after[self._has_after]] / self.stall),
                  (J[1:] / self.limit[None, :, None], 1.0 - tau_fixed[1:] / self.limit)]
        G = np.concatenate([g.reshape(-1, nw) for g, _ in blocks])
        h = np.concatenate([b.ravel() for _, b in blocks]) - margin
        return LinearConstraints(G, np.maximum(h, G @ w0) if clamp else h)


def project_into_line(z: np.ndarray, line: MotorLine, rollout: Callable[[np.ndarray, bool], Any],
                      base: LinearConstraints, rest: np.ndarray, max_rounds: int = 8
                      ) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``(z, report)``: ``z`` when its rollout obeys the line within :data:`LINE_TOLERANCE` (as an
    accepted iterate does: a result made under the line starts where it ended; report None),
    else keyframes that obey it: the nearest to the current ones in the keyframes' metric within ``base`` (the speed limit
    and the bounds) and the line linearised at them (tightened by :data:`PROJECTION_MARGIN`),
    taken again at the new keyframes until their rollout obeys the line. When that fails within
    ``max_rounds`` rounds (or the linearisation has no feasible point), the keyframes are drawn
    towards ``rest`` (keyframes that hold every motor at rest: no step moves, no load) by
    bisection until they obey it. ``rollout(z, sensitivities)`` returns the rollout of ``z`` (with
    ``dgammadz`` when asked). The report: the worst violation before (normalised) and its kind,
    the rounds, the distance moved (largest keyframe change and RMS [m])."""
    z = z_start = np.asarray(z, dtype=np.float64)
    traj = rollout(z, True)
    first = line.worst(z, traj.cable_deformation)
    if first.excess <= LINE_TOLERANCE:
        return z, None
    lo, hi = line.param.bounds()
    scale = np.where(hi > lo, hi - lo, 1.0)
    rounds, inside = 0, False
    for rounds in range(1, max_rounds + 1):
        lin = line.linearised(z, traj.cable_deformation, traj.dgammadz, margin=PROJECTION_MARGIN, clamp=False)
        try:
            z = np.clip(nearest_feasible(z, lin & base, anchor=rest, scale=scale), lo, hi)
        except QPError:
            break
        traj = rollout(z, True)
        if line.worst(z, traj.cable_deformation).excess <= 0.0:
            inside = True
            break
    if not inside:
        z = _towards_rest(z, line, rollout, np.asarray(rest, dtype=np.float64))
    return z, {"line_violation_before": first.excess, "line_violation_kind": first.kind, "rounds": rounds,
               "moved_max_m": float(np.abs(z - z_start).max()),
               "moved_rms_m": float(np.sqrt(np.mean((z - z_start) ** 2)))}


def _towards_rest(z: np.ndarray, line: MotorLine, rollout: Callable[[np.ndarray, bool], Any], rest: np.ndarray,
                  bisections: int = 10) -> np.ndarray:
    """The keyframes ``z + t (rest - z)`` with the smallest t (to 1/1024) whose rollout obeys the line."""
    def obeys(t: float) -> bool:
        zt = z + t * (rest - z)
        return line.worst(zt, rollout(zt, False).cable_deformation).excess <= 0.0
    if not obeys(1.0):
        raise ValueError("even the keyframes at rest break the motors' torque-speed line (is a motor loaded "
                         "beyond its gearbox's max_torque at rest?)")
    lo, hi = 0.0, 1.0
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if obeys(mid) else (mid, hi)
    return z + hi * (rest - z)


def line_settings_entry(law: Any, dt: float) -> dict[str, Any]:
    """What a result records of the line it was made under: each motor's no-load step [m] and
    speed [m/s], stall and gearbox torques [N m], and the tolerance of an accepted iterate."""
    return {"no_load_step_m": [float(v) * float(dt) for v in law.no_load_speed],
            "no_load_speed_mps": [float(v) for v in law.no_load_speed],
            "stall_torque_nm": [float(v) for v in law.stall_torque],
            "max_torque_nm": [float(v) for v in law.max_torque],
            "tolerance": LINE_TOLERANCE}


def motor_load_entry(line: MotorLine, z: np.ndarray, gamma: np.ndarray) -> dict[str, Any]:
    """What a result records of its motors' load (read by ``trajopt play --dry-run`` without the
    simulator): the load torque of every state of the optimised horizon ``torque_nm`` (K+1, M)
    [N m], each motor's peak torque, and its worst line excess over the played steps (normalised,
    the torque before or after the step; <= 0: under the line)."""
    tau = line.law.torque(np.asarray(gamma, dtype=np.float64))
    e = line.excess(z, gamma)
    worst = np.max(np.vstack([e["line_before"], e["line_after"]]), axis=0)
    return {"torque_nm": tau.tolist(), "peak_torque_nm": tau.max(axis=0).tolist(),
            "worst_line_excess": worst.tolist()}
