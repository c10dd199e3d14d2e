"""Projected Gauss-Newton (Levenberg-Marquardt damped) for bound-constrained least squares.

Minimises ``O(z) = 0.5 |r(z)|^2`` subject to ``lower <= z <= upper``, where ``fun(z, need_jac)``
returns ``(r, J, info)`` and may raise :class:`~soft_envs.envs.SimulationError` (a trial point
whose rollout fails counts as ``O = inf``: a rejected step, not a crash).

Each iteration
  1. evaluates r and J at z (one rollout with sensitivities);
  2. freezes the variables at a bound whose gradient pushes outwards (active set);
  3. solves ``(J_f^T J_f + lambda diag(J_f^T J_f) + lambda mu I) dz_f = -J_f^T r`` on the free
     variables (Levenberg-Marquardt, Marquardt scaling, mu = mean of the diagonal);
  4. backtracks ``z_new = clip(z + alpha dz)`` with alpha = 1, 1/2, ... 1/64 until the Armijo
     condition ``O(z_new) <= O(z) + c alpha g . dz`` holds (one rollout per trial). The gait
     objectives are strongly curved along the Gauss-Newton direction (Tripod walk: a decrease
     only below ~2 % of the step, with the Jacobian exact there), so six halvings are allowed:
     with three, Gauss-Newton stalled at the seeds of the Tripod walk and after one step of
     the Puppy turn (heading +42 instead of +56 deg over 10 cycles);
  5. decreases lambda after a full step, increases it after a backtracked or rejected one.

With ``constraints`` (linear inequalities ``G z <= h``, :class:`~trajopt.optim.qp.LinearConstraints`:
the motors' speed limit, :mod:`trajopt.optim.motor_limit`) the iterates stay feasible. Step 3's
direction is kept when every trial point of step 4 obeys them (so a run the constraints never
bind is the unconstrained run, bit for bit). Otherwise the step is the solution of the
Gauss-Newton subproblem as a QP, ``min 0.5 dz'(J'J + lambda (diag(J'J) + mu I)) dz + g'dz``
subject to ``G (z + dz) <= h`` and the bounds (cvxopt's interior-point solver,
:func:`trajopt.optim.qp.solve_qp`, shortened until it is exactly feasible), and step 4 backtracks
along ``z + alpha dz``: convex combinations of two feasible points, so every trial is feasible.
The start must be feasible (:func:`trajopt.optim.motor_limit.project_start`). ``constraints`` may
also be a function of z returning the linear inequalities to keep from z on: the linearisation
of nonlinear constraints (co-design's clearance and mass floor, :mod:`trajopt.codesign`), taken
again after every accepted step (after ``fun(z, True)``); ``fun`` then refuses trial points that
break the nonlinear constraints themselves (raises :class:`~soft_envs.envs.SimulationError`: a
rejected trial).

Stopping criteria: all are tested in one place, before every iteration (``_stop_reason``), in
this order; the first that holds ends the run and ``status`` in the result names it:
  * ``"callback"``: the callback returned True after the last iteration;
  * ``"ftol"``: the last iteration's step was accepted and decreased O by less than ``ftol * O``;
  * ``"xtol"``: the last iteration's step was accepted and moved every variable by less than
    ``xtol`` times its range ``upper - lower``;
  * ``"stalled"``: ``max_rejections`` iterations in a row found no decrease (a resumed run counts
    the rejections it is given);
  * ``"max_iter"``: this call made ``max_iter`` iterations (0: none, the start is only evaluated);
  * ``"gtol"``: the projected gradient's max-norm, each component times its variable's range,
    is below ``gtol`` (a local minimum on the bounds).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from soft_envs.envs import RolloutStopped, SimulationError

from .qp import LinearConstraints, feasible_fraction, solve_qp

__all__ = ["GaussNewtonOptions", "GaussNewtonResult", "gauss_newton"]


@dataclass(frozen=True)
class GaussNewtonOptions:
    max_iter: int = 10
    ftol: float = 1e-4
    gtol: float = 1e-10
    xtol: float = 1e-5
    lambda0: float = 1e-4
    lambda_decrease: float = 0.3
    lambda_increase: float = 10.0
    armijo: float = 1e-4
    max_backtracks: int = 6
    max_rejections: int = 3


@dataclass
class GaussNewtonResult:
    z: np.ndarray
    objective: float
    status: str
    history: list[dict] = field(default_factory=list)
    lam: float = 0.0
    info: dict = field(default_factory=dict)


def _evaluate(fun, z, need_jac, bound: float | None = None):
    """``(O, r, J, info)`` at ``z``; O = inf for a failed simulation and, when ``fun`` takes a
    ``bound`` (its attribute ``stops_above``), for a trial it stopped because its objective was
    already above ``bound`` (:class:`~soft_envs.envs.RolloutStopped`): a rejected trial either way."""
    try:
        if bound is not None and getattr(fun, "stops_above", False):
            r, J, info = fun(z, need_jac, bound=bound)
        else:
            r, J, info = fun(z, need_jac)
    except SimulationError as err:
        return np.inf, None, None, {"sim_failure": str(err)}
    except RolloutStopped as stopped:
        return np.inf, None, None, {"stopped_at_step": stopped.k}
    if not np.isfinite(r).all():
        return np.inf, None, None, {"sim_failure": "non-finite residual"}
    return 0.5 * float(r @ r), r, J, info


def _active_set(g: np.ndarray, z: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Step 2: the free variables (not held at a bound that the gradient ``g`` pushes outwards)."""
    at_lo = (z <= lower) & (g > 0)
    at_hi = (z >= upper) & (g < 0)
    return ~(at_lo | at_hi)


def _direction(J: np.ndarray, g: np.ndarray, free: np.ndarray, lam: float) -> np.ndarray:
    """Step 3: the Levenberg-Marquardt step on the free variables (zero on the others)."""
    Jf = J[:, free]
    A = Jf.T @ Jf
    d = np.diag(A).copy()
    mu = d.mean() if d.size else 1.0
    A[np.diag_indices_from(A)] += lam * (d + mu)
    dz = np.zeros_like(g)
    dz[free] = np.linalg.solve(A, -g[free])
    return dz


def _trial_alphas(opt: GaussNewtonOptions) -> np.ndarray:
    return 0.5 ** np.arange(opt.max_backtracks + 1)


def _constrained_direction(J: np.ndarray, g: np.ndarray, z: np.ndarray, lam: float, lower: np.ndarray,
                           upper: np.ndarray, constraints: LinearConstraints) -> np.ndarray:
    """The Levenberg-Marquardt step as a QP over the constraints and the bounds, exactly feasible."""
    A = J.T @ J
    d = np.diag(A).copy()
    A[np.diag_indices_from(A)] += lam * (d + (d.mean() if d.size else 1.0))
    box = LinearConstraints.box(lower, upper)
    feasible = constraints & box
    shifted = LinearConstraints(feasible.G, feasible.h - feasible.G @ z)     # in dz
    dz = solve_qp(A, g, shifted, scale=np.where(upper > lower, upper - lower, 1.0))
    return feasible_fraction(feasible, z, dz) * dz


def _line_search(fun: Callable, z: np.ndarray, dz: np.ndarray, g: np.ndarray, f: float, lower: np.ndarray,
                 upper: np.ndarray, opt: GaussNewtonOptions) -> tuple[bool, float, np.ndarray, int, dict]:
    """Step 4: ``(accepted, alpha, z_try, trials, info)``: backtrack along the clipped step
    until the Armijo condition holds (one rollout without sensitivities per trial; a problem that
    can stop a rollout once its objective is above the condition's bound does, which decides
    nothing differently)."""
    alpha, trials, info = 1.0, 0, {}
    for _ in range(opt.max_backtracks + 1):
        trials += 1
        z_try = np.clip(z + alpha * dz, lower, upper)
        bound = f + opt.armijo * min(float(g @ (z_try - z)), 0.0)       # slope of the clipped step
        f_try, _, _, info = _evaluate(fun, z_try, False, bound)
        if f_try <= bound:
            return True, alpha, z_try, trials, info
        alpha *= 0.5
    return False, alpha, z_try, trials, info


def _require_feasible(constraints: LinearConstraints | None, z: np.ndarray) -> None:
    if constraints is not None and not constraints.feasible(z):
        raise ValueError(f"the start breaks the constraints (worst G z - h = {constraints.violation(z):.3g}); "
                         "project it first (trajopt.optim.motor_limit.project_start)")


@dataclass
class _Iterate:
    """Where the solver stands: the point ``z`` and what was evaluated there (objective ``f``,
    residual ``r``, Jacobian ``J``, the problem's ``info``), the damping ``lam``, the rejected steps
    in a row, and the linear inequalities kept from ``z`` on (None: none)."""

    z: np.ndarray
    f: float
    r: np.ndarray
    J: np.ndarray
    info: dict
    lam: float
    rejections: int
    constraints: LinearConstraints | None


@dataclass(frozen=True)
class _StepOutcome:
    """What the stopping rule reads of the last iteration: whether its step was accepted, the
    objective before it, the step taken (None when rejected), and whether the callback asked to
    stop."""

    accepted: bool
    f_before: float
    step: np.ndarray | None
    stop_requested: bool


def _stop_reason(opt: GaussNewtonOptions, x: _Iterate, last: _StepOutcome | None, iterations: int,
                 g: np.ndarray, free: np.ndarray, scale: np.ndarray) -> str | None:
    """The stopping rule: the status of the first stopping criterion that holds (module
    docstring, in its order), None: iterate on. ``last``: the iteration just made (None before
    the first); ``iterations``: how many this call made; ``g``, ``free``: the gradient and the
    free variables at ``x``; ``scale``: each variable's range."""
    if last is not None:
        if last.stop_requested:
            return "callback"
        if last.accepted and last.f_before - x.f < opt.ftol * last.f_before:
            return "ftol"
        if last.accepted and np.abs(last.step / scale).max() < opt.xtol:
            return "xtol"
        if x.rejections >= opt.max_rejections:
            return "stalled"
    if iterations >= opt.max_iter:
        return "max_iter"
    if np.abs(np.where(free, g, 0.0) * scale).max() < opt.gtol:
        return "gtol"
    return None


def _step(fun: Callable, x: _Iterate, g: np.ndarray, free: np.ndarray, lower: np.ndarray, upper: np.ndarray,
          opt: GaussNewtonOptions, linearise: Callable[[np.ndarray], LinearConstraints] | None
          ) -> tuple[dict, np.ndarray | None]:
    """Steps 3-5 of one iteration from ``x`` (updated in place): the direction (the QP's when the
    unconstrained trials would leave the feasible set), the line search, the damping, and at an
    accepted point the Jacobian rollout (and the constraints linearised again). Returns the
    history entry (without its iteration number and time) and the step taken (None: rejected)."""
    f_before, lam = x.f, x.lam
    dz = _direction(x.J, g, free, lam)
    qp_step = x.constraints is not None and not all(
        x.constraints.feasible(np.clip(x.z + a * dz, lower, upper)) for a in _trial_alphas(opt))
    if qp_step:                  # the unconstrained trials would leave the feasible set
        dz = _constrained_direction(x.J, g, x.z, lam, lower, upper, x.constraints)
    accepted, alpha, z_try, trials, info_try = _line_search(fun, x.z, dz, g, f_before, lower, upper, opt)
    entry = {"objective": f_before, "accepted": accepted, "alpha": alpha if accepted else 0.0,
             "step": float(np.abs(z_try - x.z).max()) if accepted else 0.0, "lambda": lam,
             "trials": trials, "terms": x.info.get("terms", {})}
    if x.constraints is not None:
        entry["qp_step"] = bool(qp_step)
    if not accepted:
        x.lam = lam * opt.lambda_increase
        x.rejections += 1
        entry.update(objective_after=x.f, sim_failure=info_try.get("sim_failure"))
        return entry, None
    step = z_try - x.z                  # step 5: less damping after a full step
    x.lam = max(lam * (opt.lambda_decrease if alpha == 1.0 else opt.lambda_increase), 1e-12)
    x.rejections = 0
    f, r, J, info = _evaluate(fun, z_try, True)
    if not np.isfinite(f):              # cannot happen: z_try was just simulated
        raise SimulationError(f"re-evaluation failed: {info['sim_failure']}")
    x.z, x.f, x.r, x.J, x.info = z_try, f, r, J, info
    if linearise is not None:
        x.constraints = linearise(x.z)
    entry.update(objective_after=f, terms_after=info.get("terms", {}))
    return entry, step


def gauss_newton(fun: Callable, z0: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 options: GaussNewtonOptions = GaussNewtonOptions(), *,
                 callback: Callable[[dict], bool | None] | None = None,
                 lam: float | None = None, first_iteration: int = 1,
                 rejections: int = 0,
                 constraints: LinearConstraints | Callable[[np.ndarray], LinearConstraints] | None = None
                 ) -> GaussNewtonResult:
    """Run the solver from ``z0`` (projected onto the bounds) until a stopping criterion holds
    (module docstring; :func:`_stop_reason` tests them all before every iteration). ``callback(entry)``
    is called after every iteration with its history entry (plus ``"z"`` and ``"lam"``, after the
    step); returning True stops. ``lam``, ``first_iteration`` and ``rejections`` (consecutive
    rejected steps so far) let an interrupted run resume where it stopped. ``constraints``: linear
    inequalities the iterates keep (module docstring); ``z0`` must obey them (ValueError
    otherwise). History entries then say whether the step was the QP's (``"qp_step"``). Raises
    :class:`~soft_envs.envs.SimulationError` when ``z0`` cannot be simulated."""
    opt = options
    lower = np.asarray(lower, dtype=np.float64)
    upper = np.asarray(upper, dtype=np.float64)
    z = np.clip(np.asarray(z0, dtype=np.float64), lower, upper)
    linearise = constraints if callable(constraints) else None
    if linearise is None:
        _require_feasible(constraints, z)
    f, r, J, info = _evaluate(fun, z, True)
    if not np.isfinite(f):
        raise SimulationError(f"the starting point cannot be simulated: {info['sim_failure']}")
    if linearise is not None:
        constraints = linearise(z)
        _require_feasible(constraints, z)
    x = _Iterate(z, f, r, J, info, opt.lambda0 if lam is None else float(lam), int(rejections), constraints)
    scale = np.where(upper > lower, upper - lower, 1.0)
    history: list[dict] = []
    last: _StepOutcome | None = None
    it = first_iteration - 1            # the last iteration made
    while True:
        t0 = time.perf_counter()
        g = x.J.T @ x.r
        free = _active_set(g, x.z, lower, upper)
        status = _stop_reason(opt, x, last, it - first_iteration + 1, g, free, scale)
        if status is not None:
            break
        it += 1
        f_before = x.f
        entry, step = _step(fun, x, g, free, lower, upper, opt, linearise)
        entry = {"iteration": it, **entry, "time": time.perf_counter() - t0}
        history.append(entry)
        stop = callback({**entry, "z": x.z.copy(), "lam": x.lam}) if callback else False
        last = _StepOutcome(step is not None, f_before, step, bool(stop))
    if status == "gtol":                # the iteration that found the gradient vanished counts as begun
        it += 1
    return GaussNewtonResult(z=x.z, objective=x.f, status=status, history=history, lam=x.lam,
                             info={**x.info, "last_iteration": it})
