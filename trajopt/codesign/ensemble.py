r"""The co-design problem on an ensemble of physics: gait and design asked to walk at several
physics steps at once, the analogue for :class:`~trajopt.codesign.problem.CodesignProblem` of
:class:`trajopt.optim.ensemble.EnsembleProblem` for a gait alone.

The members are the same problem (keyframes z, design theta, target, weights, constraints) with
the default physics' ``n_0`` physics steps per control step and with each count of ``substeps``
(e.g. 8: 2x finer steps); their residuals stack, scaled so that the ensemble's objective is the
members' mean,

.. math::
    O(w) = \frac1n \sum_i \tfrac12 |r_i(w)|^2, \qquad J = [J_1; \dots; J_n] / \sqrt n,

and each member's Jacobian ``[dr_i/dz, dr_i/dtheta]`` is its own forward recurrence over its
physics steps (:func:`soft_envs.envs.design.design_rollout`, paper eqs. 8-11 with the design's
parameter block). The members share the design block: the default member moves it to every
point where Gauss-Newton asks for a Jacobian (:meth:`CodesignProblem.move_to`) and the others
take it from there, so they linearise at the same design. Trial points: a design that breaks the
clearance or the mass floor is refused by the default member; a trial whose rollout at any
member's physics breaks the motors' torque-speed line is refused too. The constraints are the
default member's (:meth:`CodesignProblem.linearised_constraints`) and every other member's
torque-speed rows on w, linearised on its own rollout.

Simulation steps are counted in steps of the default physics (a member with ``n`` physics steps
per control step counts ``n / n_0`` per control step) and added to the default member's
``sim_steps``, the counter the co-design reports.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..optim.ensemble import ensemble_substeps, member_env
from ..optim.qp import LinearConstraints
from .problem import CodesignProblem

__all__ = ["CodesignEnsemble"]


class CodesignEnsemble:
    """``(r, J, info) = ensemble(w, need_jac)`` over ``w = [z; theta]`` (module docstring): the
    problem ``base`` at its own physics and at each count of ``substeps`` physics steps per
    control step (``base``'s own count is left out)."""

    stops_above = False

    def __init__(self, base: CodesignProblem, substeps: Sequence[int]):
        self.base = base
        counts = ensemble_substeps(base.env, substeps)[1:]
        self.members = [base] + [self._member(base, n) for n in counts]
        self._scale = 1.0 / math.sqrt(len(self.members))
        self._weight = [n / base.substeps for n in self.substeps]

    @staticmethod
    def _member(base: CodesignProblem, n: int) -> CodesignProblem:
        m = CodesignProblem(member_env(base.env, n), base.shipped, base.gait, base.speed, base.weights, base.max_step,
                            newton=base.newton, trust=base.trust, motor_model=base.motor_model)
        m.min_clearance, m.min_mass = base.min_clearance, base.min_mass
        return m

    @property
    def substeps(self) -> list[int]:
        return [m.substeps for m in self.members]

    def __call__(self, w: np.ndarray, need_jac: bool = True):
        base = self.base
        rs, Js, terms = [], [], {}
        for i, m in enumerate(self.members):
            if i:                      # the design and target (CodesignProblem.set_target) of the default member
                m.block, m.anchor, m.speed, m.offsets = base.block, base.anchor, base.speed, base.offsets
                before = m.sim_steps
            r, J, info = m(w, need_jac)
            if i:
                base.sim_steps += int(round(self._weight[i] * (m.sim_steps - before)))
            rs.append(r)
            Js.append(J)
            for k, v in info["terms"].items():
                terms[k] = terms.get(k, 0.0) + v / len(self.members)
        r = self._scale * np.concatenate(rs)
        return r, (self._scale * np.vstack(Js) if need_jac else None), {"terms": terms}

    def linearised_constraints(self, w: np.ndarray, trust: bool = True) -> LinearConstraints:
        """The default member's constraints and every other member's torque-speed rows (module
        docstring; call after ``self(w, True)``)."""
        rows = self.base.linearised_constraints(w, trust)
        for m in self.members[1:]:
            if m.line is not None:
                rows = rows & m.line_constraints(w)
        return rows
