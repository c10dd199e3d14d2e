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

Stopping criteria (the first that holds; ``status`` in the result names it):
  * ``"max_iter"``: ``max_iter`` iterations done;
  * ``"ftol"``: an accepted step decreased O by less than ``ftol * O``;
  * ``"gtol"``: the projected gradient's max-norm is below ``gtol``;
  * ``"xtol"``: the accepted step's max-norm is below ``xtol * (upper - lower)``;
  * ``"stalled"``: ``max_rejections`` consecutive iterations found no decrease;
  * ``"callback"``: the callback returned True.
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


def gauss_newton(fun: Callable, z0: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 options: GaussNewtonOptions = GaussNewtonOptions(), *,
                 callback: Callable[[dict], bool | None] | None = None,
                 lam: float | None = None, first_iteration: int = 1,
                 rejections: int = 0,
                 constraints: LinearConstraints | Callable[[np.ndarray], LinearConstraints] | None = None
                 ) -> GaussNewtonResult:
    """Run the solver from ``z0`` (projected onto the bounds). ``callback(entry)`` is called
    after every iteration with its history entry (plus ``"z"``); returning True stops.
    ``lam``, ``first_iteration`` and ``rejections`` (consecutive rejected steps so far) let an
    interrupted run resume where it stopped. ``constraints``: linear inequalities the iterates
    keep (module docstring); ``z0`` must obey them (ValueError otherwise). History entries then
    say whether the step was the QP's (``"qp_step"``)."""
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
    scale = np.where(upper > lower, upper - lower, 1.0)
    lam = opt.lambda0 if lam is None else float(lam)
    history: list[dict] = []
    status = "max_iter"
    rejections = int(rejections)
    it = first_iteration - 1
    for it in range(first_iteration, first_iteration + opt.max_iter):
        t0 = time.perf_counter()
        g = J.T @ r
        free = _active_set(g, z, lower, upper)
        if np.abs(np.where(free, g, 0.0) * scale).max() < opt.gtol:
            status = "gtol"
            break
        dz = _direction(J, g, free, lam)
        qp_step = constraints is not None and not all(
            constraints.feasible(np.clip(z + a * dz, lower, upper)) for a in _trial_alphas(opt))
        if qp_step:                  # the unconstrained trials would leave the feasible set
            dz = _constrained_direction(J, g, z, lam, lower, upper, constraints)
        accepted, alpha, z_try, trials, info_try = _line_search(fun, z, dz, g, f, lower, upper, opt)
        entry = {"iteration": it, "objective": f, "accepted": accepted, "alpha": alpha if accepted else 0.0,
                 "step": float(np.abs(z_try - z).max()) if accepted else 0.0, "lambda": lam,
                 "trials": trials, "terms": info.get("terms", {})}
        if constraints is not None:
            entry["qp_step"] = bool(qp_step)
        if accepted:                        # step 5: less damping after a full step
            step = z_try - z
            f_old = f
            z = z_try
            lam = max(lam * (opt.lambda_decrease if alpha == 1.0 else opt.lambda_increase), 1e-12)
            rejections = 0
            f, r, J, info = _evaluate(fun, z, True)
            if not np.isfinite(f):          # cannot happen: z_try was just simulated
                raise SimulationError(f"re-evaluation failed: {info['sim_failure']}")
            if linearise is not None:
                constraints = linearise(z)
            entry.update(objective_after=f, terms_after=info.get("terms", {}))
        else:
            lam *= opt.lambda_increase
            rejections += 1
            entry.update(objective_after=f, sim_failure=info_try.get("sim_failure"))
        entry["time"] = time.perf_counter() - t0
        history.append(entry)
        stop = callback({**entry, "z": z.copy(), "lam": lam}) if callback else False
        if stop:
            status = "callback"
            break
        if accepted and f_old - f < opt.ftol * f_old:
            status = "ftol"
            break
        if accepted and np.abs(step / scale).max() < opt.xtol:
            status = "xtol"
            break
        if rejections >= opt.max_rejections:
            status = "stalled"
            break
    return GaussNewtonResult(z=z, objective=f, status=status, history=history, lam=lam,
                             info={**info, "last_iteration": it})
