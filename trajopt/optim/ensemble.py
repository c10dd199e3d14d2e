"""Credible gaits: one gait optimised on an ensemble of physics, judged by its slowest member.

A gait optimised on one physics is free to exploit whatever that physics gets wrong (docs/fidelity.md:
the fastest gaits of 33 ms walked at speeds that belonged to the step). An ensemble is the same
task on several physics at once: the default (``env``'s physics steps per control step) and
``factors`` times finer (default: 2x). Each member is a :class:`~trajopt.optim.optimize.GaitProblem`
of the same keyframes, target and weights; their residuals stack, scaled by ``1/sqrt(n)`` so that
the ensemble's objective is the members' mean,

    O(z) = (1/n) sum_i 0.5 |r_i(z)|^2,    J = [J_1; ...; J_n] / sqrt(n),

and each member's Jacobian is its own sensitivity analysis (paper eqs. 10-11 over its physics
steps). A line-search trial is refused when any member breaks the motors' torque-speed line, and
the line's rows are linearised on every member's rollout: the gait obeys the motors at every
physics step of each. Simulation steps are counted in steps of the default physics (a member
with n physics steps per control step counts n / n_default per control step): the budget of ``--speed max`` is the same
currency with or without an ensemble.

What is reported is the *credible speed*: the slowest member's (:func:`credible_speed`), the
speed the gait keeps when the physics is resolved more finely.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from soft_envs.envs import make_gradient_env

__all__ = ["DEFAULT_ENSEMBLE", "EnsembleProblem", "member_env", "credible_speed", "ensemble_substeps"]

#: ``--ensemble`` without a value: the members besides the default physics (4 steps of 8.25 ms
#: per control step): 2x coarser and 2x finer steps
DEFAULT_ENSEMBLE = (2, 8)


def member_env(env: Any, substeps: int):
    """A bare environment like ``env`` (robot, slope, heading, control step, contact law, motor
    model) with ``substeps`` physics steps per control step."""
    h = np.asarray(env._heading, dtype=np.float64)
    return make_gradient_env(env.robot, incline_deg=float(env.incline_deg),
                             heading_deg=math.degrees(math.atan2(h[2], h[0])), timestep=env.timestep,
                             contact=env.contact_model, substeps=int(substeps),
                             motor_model=env.motor_model)


def ensemble_substeps(env: Any, ensemble) -> list[int]:
    """The members' physics steps per control step, the default (``env``'s) first: ``ensemble``'s
    other counts in increasing order (a ValueError names a count that is not a positive integer)."""
    own = int(env.substeps)
    counts = []
    for n in ensemble:
        if isinstance(n, bool) or int(n) != n or int(n) < 1:
            raise ValueError(f"ensemble: physics steps per control step must be positive integers, got {n!r}")
        counts.append(int(n))
    return [own] + sorted(set(counts) - {own})


def credible_speed(evaluations: list[dict]) -> float:
    """The slowest of the members' speeds [BL/min]; NaN when one failed or fell."""
    speeds = [float(ev.get("speed_bl_per_min", float("nan"))) for ev in evaluations]
    if not all(ev.get("upright", False) for ev in evaluations) or not np.isfinite(speeds).all():
        return float("nan")
    return float(min(speeds))


class EnsembleProblem:
    """The members' problems as one (module docstring): the first is the default physics, whose
    environment, parameterisation, target and motors the ensemble shares (its rollout is the
    one results record)."""

    stops_above = True

    def __init__(self, members: list):
        if not members:
            raise ValueError("an ensemble needs at least one member")
        self.members = list(members)
        base = self.members[0]
        for name in ("env", "param", "target", "weights", "heading", "max_step", "motor_model", "speed_limit",
                     "law", "line", "dudz", "u_offset"):
            setattr(self, name, getattr(base, name))
        self._scale = 1.0 / math.sqrt(len(self.members))
        self._weight = [int(m.env.substeps) / int(base.env.substeps) for m in self.members]

    @property
    def substeps(self) -> list[int]:
        return [int(m.env.substeps) for m in self.members]

    @property
    def sim_steps(self) -> int:
        """Simulation steps, counted in steps of the default physics."""
        return int(round(sum(w * m.sim_steps for w, m in zip(self._weight, self.members))))

    @property
    def rollouts(self) -> int:
        return sum(m.rollouts for m in self.members)

    @property
    def refused_trials(self) -> int:
        return sum(m.refused_trials for m in self.members)

    @property
    def last_traj(self):
        return self.members[0].last_traj

    def controls(self, z: np.ndarray) -> np.ndarray:
        return self.members[0].controls(z)

    def rollout(self, z: np.ndarray, sensitivities: bool = False, store_dxdz: bool = False, stop=None):
        """The default member's rollout."""
        return self.members[0].rollout(z, sensitivities, store_dxdz, stop)

    def __call__(self, z: np.ndarray, need_jac: bool = True, bound: float | None = None):
        return self.evaluate(z, need_jac, bound=bound)

    def evaluate(self, z: np.ndarray, need_jac: bool = True, check: bool = True, bound: float | None = None):
        """``(r, J, info)`` stacked over the members (module docstring); ``check`` and ``bound``
        as :meth:`GaitProblem.evaluate` (a member's rollout stops once the members so far make
        the mean objective exceed ``bound``)."""
        n = len(self.members)
        rs, Js, terms = [], [], {}
        spent = 0.0
        for m in self.members:
            b = None if bound is None or not np.isfinite(bound) else n * bound - spent
            r, J, info = m.evaluate(z, need_jac, check, bound=b)
            spent += 0.5 * float(r @ r)
            rs.append(r)
            Js.append(J)
            for k, v in (info.get("terms") or {}).items():
                terms[k] = terms.get(k, 0.0) + v / n
        r = self._scale * np.concatenate(rs)
        J = self._scale * np.vstack(Js) if need_jac else None
        return r, J, {"terms": terms}

    def linearised_constraints(self, z: np.ndarray):
        """The speed limit's rows and every member's line, linearised at ``z`` on its own rollout
        (call after ``self(z, True)``)."""
        rows = self.speed_limit
        for m in self.members:
            traj = m.last_traj
            rows = rows & m.line.linearised(z, traj.cable_deformation, traj.dgammadz)
        return rows

    @property
    def constraints(self):
        return self.linearised_constraints if self.line is not None else self.speed_limit
