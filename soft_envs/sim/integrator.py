r"""One implicit-Euler step as Newton minimisation of the incremental potential (paper II-D, eq. 4).

.. math::
    x_k = \arg\min_x \Phi_k(x) = \frac{1}{2h^2}(x - \tilde x)^T M (x - \tilde x) + E(x; u_k, x_{k-1}),
    \qquad \tilde x = 2 x_{k-1} - x_{k-2},

whose stationarity condition ``M (x_k - 2x_{k-1} + x_{k-2}) / h^2 + dE/dx = 0`` is eq. 4.

Newton's method with
  * the exact Hessian, factorised by Cholesky; when it is not positive definite, the
    per-element eigenvalue-projected Hessian, and then a growing diagonal shift;
  * a backtracking (Armijo) line search on Phi that never accepts a state with an inverted
    element (Phi = +inf there); a chord step (reused factorisation) whose full step does not
    decrease Phi is not damped: the Hessian is refreshed at the same point instead (measured:
    5 % fewer factorisations and 14 % fewer gradient evaluations on the gait benchmark);
  * initial guess ``x~`` (constant velocity) or, when ``x_{k-3}`` is known and its Phi is
    lower, ``3 x_{k-1} - 3 x_{k-2} + x_{k-3}`` (constant acceleration: about half the distance
    to x_k on smooth motions); ``x_{k-1}`` if both invert an element;
  * stopping criterion: the step's max-norm is ``<= tol`` [m] (and the step is taken); a
    Newton step with a fresh exact Hessian then ends the iteration, a chord step only when it
    and the step before used the same factorisation, contracted by ``rho < 1/2``, and the
    error left, ``n rho / (1 - rho)``, is ``<= tol`` too. Checked against solves to 1e-14
    along gaits and random actions at tol = 1e-8 and 1e-6: error <= 0.7 tol
    (tests/test_dynamics.py). Coarser tolerances leave the regime where a small step means a
    small error (contacts and cables switch): at 1e-4, errors up to 20 tol were measured.
    With ``need_exact`` (sensitivities) the solver ends holding the exact Hessian factorised
    at ``x_k`` or at most ``tol`` away from it.
  * factorisation reuse across steps is explicit: a :class:`FactorCache`, owned by whoever
    strings steps together (a rollout, an environment step with frame skip), says which
    factorisation of the solver it may reuse; a step given no cache starts afresh, so its
    result depends on its inputs only.
A step that fails for too many iterations or a failed line search is solved once more, afresh,
with a line search that may lengthen a step which still descends steeply
(``NewtonOptions.rescue_doublings``: where Phi curves downwards the modified Hessian's steps
creep); a step that converges the first time is as before, bit for bit.
Failure (no descent, too many iterations, non-finite values) raises :class:`SimulationError`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .line_search import backtracking, bracketing
from .linsolve import FactorCache, make_solver
from .newton_options import NewtonOptions, SimulationError, StepInfo
from .system import EnergySystem

__all__ = ["SimulationError", "NewtonOptions", "StepInfo", "NewtonSolver"]


class _Inputs(NamedTuple):
    """What one step's Phi depends on besides x: ``x~ = 2 x_{k-1} - x_{k-2}``, ``x_{k-1}``,
    the controls and the energy terms' history."""

    xt: np.ndarray
    x_prev: np.ndarray
    u: np.ndarray
    history: tuple


@dataclass
class _Iterate:
    """The state of one step's Newton iteration."""

    x: np.ndarray
    phi: float
    grad: np.ndarray
    fresh: bool = False          # the held factorisation was computed at x
    prev_norm: float = np.inf    # size of the last full step taken
    prev_kind: str | None = None  # its kind: "newton", "chord" or None (fallback or damped)
    iterations: int = 0
    factorizations: int = 0
    fallbacks: int = 0


class NewtonSolver:
    """Solves steps of one :class:`EnergySystem` with time step ``dt`` [s], the one home of a
    simulation's h at run time (:attr:`dt`; the simulator and environments read it)."""

    def __init__(self, system: EnergySystem, dt: float, options: NewtonOptions = NewtonOptions()):
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be positive, got {dt!r}")
        self.system = system
        self._dt = float(dt)
        self.options = options
        self.inertia = system.mass / self._dt**2          # (3n,) diagonal M / h^2
        self._diag_inertia = self.inertia[system.free]
        self.solver = make_solver(system.pattern, options.solver)
        self._fallback = None
        ls = options.line_search
        self._exact_line_search = ls == "exact" or (ls == "auto" and system.has_history)

    @property
    def dt(self) -> float:
        """The time step h [s] (read-only: :attr:`inertia`, ``M / h^2``, is built from it)."""
        return self._dt

    # ------------------------------------------------------------------ Phi and its derivatives
    def phi(self, x, xt, x_prev, u, history=None) -> float:
        d = (x - xt).ravel()
        e = self.system.energy(x, x_prev, u, history)
        return e + 0.5 * float(d @ (self.inertia * d))

    def phi_assemble(self, x, xt, x_prev, u, project=False, want_hess=True, history=None):
        """``(Phi, dPhi/dx (3n,), Hessian values or None)`` at x (``history``: the energy terms'
        lagged state, see :meth:`EnergySystem.initial_history`; default: at rest at x_prev)."""
        e, grad, hdata = self.system.assemble(x, x_prev, u, project, want_hess, history)
        d = (x - xt).ravel()
        f = self.inertia * d
        grad += f
        if want_hess:
            hdata[self.system.pattern.diag] += self._diag_inertia
        return e + 0.5 * float(d @ f), grad, hdata

    def factorize(self, hdata, x, xt, x_prev, u, history=None) -> tuple[bool, int]:
        """Factorise; fall back to the projected Hessian, then to diagonal shifts.
        Returns (exact, number of fallbacks used)."""
        if self.solver.factorize(hdata):
            return True, 0
        _, _, hproj = self.phi_assemble(x, xt, x_prev, u, project=True, history=history)
        diag = self.system.pattern.diag
        shift = 0.0
        base = np.abs(hproj[diag]).mean()
        for attempt in range(1, 30):
            h = hproj.copy()
            h[diag] += shift
            if self.solver.factorize(h):
                return False, attempt
            shift = base * 1e-8 if shift == 0.0 else shift * 10.0
        raise SimulationError("Hessian could not be made positive definite")

    # ------------------------------------------------------------------ one step
    def step(self, x_prev: np.ndarray, x_prev2: np.ndarray, u: np.ndarray, k: int | None = None,
             x_fixed: np.ndarray | None = None, need_exact: bool = False,
             x_prev3: np.ndarray | None = None, cache: FactorCache | None = None,
             history: tuple | None = None) -> tuple[np.ndarray, StepInfo]:
        """Solve for ``x_k`` given ``x_{k-1}``, ``x_{k-2}`` and controls ``u`` (module
        docstring): initial guess, then Newton directions, the stopping test and a line search
        until the test holds. Inputs are not modified. Fixed nodes keep their positions in
        ``x_prev`` (or ``x_fixed``). ``cache`` (optional) is the factorisation this step may
        reuse and leaves for the next. With ``need_exact`` the returned :class:`StepInfo`
        holds the exact Hessian's factorisation at ``x_k`` (for sensitivities). ``x_prev3``
        (``x_{k-3}``, optional) only improves the initial guess. ``history`` is the energy
        terms' lagged state (:meth:`EnergySystem.initial_history`; default: at rest at
        ``x_prev``)."""
        cache = FactorCache() if cache is None else cache
        ctx = _Inputs(2.0 * x_prev - x_prev2, x_prev, u, self.system.resolve_history(history, x_prev))
        fixed_src = x_prev if x_fixed is None else x_fixed
        first = self._start(ctx, x_prev2, x_prev3, fixed_src, k)
        try:
            return self._solve(first, ctx, x_prev2, k, need_exact, cache, rescue=False)
        except SimulationError as err:
            if not self.options.rescue_doublings or not err.rescuable:
                raise
            failure = err
        cache.drop()                      # the rescue starts afresh (module docstring)
        try:
            x, info = self._solve(self._start(ctx, x_prev2, x_prev3, fixed_src, k), ctx, x_prev2, k, need_exact,
                                  cache, rescue=True)
        except SimulationError as err:
            err.__context__ = failure             # the traceback shows both solves' failures, the first first
            raise SimulationError(f"{failure.reason}; solved again with longer line searches: {err.reason}",
                                  failure.step) from err
        return x, dataclasses.replace(info, iterations=info.iterations + first.iterations,   # both solves' work
                                      factorizations=info.factorizations + first.factorizations,
                                      fallbacks=info.fallbacks + first.fallbacks)

    def _solve(self, it: _Iterate, ctx: "_Inputs", x_prev2, k, need_exact: bool, cache: FactorCache,
               rescue: bool) -> tuple[np.ndarray, StepInfo]:
        """:meth:`step`'s Newton iteration from ``it`` (counting its work there); ``rescue``: the
        exact line search with ``rescue_doublings`` (whatever the contact law's search)."""
        opt = self.options
        while it.iterations < opt.max_iter:
            it.iterations += 1
            g, dx, norm, kind = self._direction(it, cache, ctx, k)
            if self._converged(norm, it.prev_norm, kind, it.prev_kind):
                self._move(it.x, dx)
                exact_here = kind == "newton" and norm <= opt.tol
                return it.x, self._info(it, need_exact and not exact_here, need_exact, cache,
                                        it.x, x_prev2, ctx)
            slope = float(g @ dx)
            if norm <= opt.tol or (slope < 0 and -slope <= 1e-12 * (abs(it.phi) + 1e-30)):
                # a step this small needs no line search (or the predicted decrease is at the
                # round-off level of Phi and Newton is in its quadratic regime): take it
                self._move(it.x, dx)
                it.phi, it.grad, _ = self._phi_grad(it.x, ctx)
                it.fresh, it.prev_norm, it.prev_kind = False, norm, kind
                continue
            if slope >= 0:
                if not it.fresh:
                    cache.drop()          # a stale factorisation: refresh it here
                    continue
                raise SimulationError(f"Newton direction is not a descent direction (slope {slope:.3e})", k)
            found = self._line_search(it, dx, slope, ctx, rescue)
            if found is None and not it.fresh:
                cache.drop()              # a reused factorisation overshoots: refresh, not damp
                continue
            if found is None:
                xn = it.x.copy()
                self._move(xn, dx)
                if norm <= 1e3 * opt.tol and self.phi(xn, ctx.xt, ctx.x_prev, ctx.u, ctx.history) <= it.phi:
                    # round-off stalls the line search this close to the solution
                    return xn, self._info(it, need_exact, need_exact, cache, xn, x_prev2, ctx)
                raise SimulationError(f"line search failed (|dx| = {norm:.3e} m)", k, rescuable=True)
            it.x, it.phi, it.grad, alpha = found
            it.prev_kind = kind if alpha == 1.0 else None
            it.fresh, it.prev_norm = False, alpha * norm
        raise SimulationError(f"Newton did not converge in {opt.max_iter} iterations "
                              f"(last |dx| = {norm:.3e} m)", k, rescuable=True)

    def _move(self, x: np.ndarray, dx: np.ndarray) -> None:
        """``x[free dofs] += dx`` in place."""
        sys = self.system
        x.reshape(-1)[sys.free if len(sys.free) < sys.n_dof else slice(None)] += dx

    def _phi_grad(self, x, ctx: "_Inputs"):
        return self.phi_assemble(x, ctx.xt, ctx.x_prev, ctx.u, want_hess=False, history=ctx.history)

    def _start(self, ctx: "_Inputs", x_prev2, x_prev3, fixed_src, k) -> _Iterate:
        """The first iterate: :meth:`_initial_guess`, or ``x_{k-1}`` if the guesses invert an
        element."""
        sys = self.system
        x, phi_x, grad = self._initial_guess(ctx, x_prev2, x_prev3, fixed_src)
        if not np.isfinite(phi_x):
            x = ctx.x_prev.copy()
            if len(sys.free) < sys.n_dof:
                x.reshape(-1)[sys.fixed_dof] = fixed_src.reshape(-1)[sys.fixed_dof]
            phi_x, grad, _ = self._phi_grad(x, ctx)
            if not np.isfinite(phi_x):
                raise SimulationError("the previous state is inverted or non-finite", k)
        return _Iterate(x, phi_x, grad)

    def _direction(self, it: _Iterate, cache: FactorCache, ctx: "_Inputs", k):
        """``(g, dx, |dx|_max, kind)``: the Newton step ``-H^{-1} g`` on the free dofs with the
        held factorisation, refreshed first when there is none to reuse or when the chord
        step it gives contracts too slowly (:meth:`_chord_too_slow`)."""
        if not (self.options.reuse_factor and cache.holds(self.solver)):
            self._refactor(it, cache, ctx)
        sys = self.system
        g = it.grad[sys.free] if len(sys.free) < sys.n_dof else it.grad
        dx = -self.solver.solve(g)
        norm = np.abs(dx).max()
        if not it.fresh and self._chord_too_slow(norm, it.prev_norm):
            self._refactor(it, cache, ctx)
            dx = -self.solver.solve(g)
            norm = np.abs(dx).max()
        if not np.isfinite(dx).all():
            raise SimulationError("non-finite Newton step", k)
        kind = ("newton" if cache.exact else None) if it.fresh else "chord"
        return g, dx, norm, kind

    def _line_search(self, it: _Iterate, dx, slope: float, ctx: "_Inputs", rescue: bool = False):
        """From the full step (:mod:`.line_search`): ``(x, Phi, grad, alpha)`` of the accepted
        point, or None. A chord step (reused factorisation) only tries the full step; a Newton
        step brackets (``"exact"``; in a rescue, with ``rescue_doublings``), falling back to,
        or else, backtracking."""
        opt = self.options
        sys = self.system
        free = sys.free if len(sys.free) < sys.n_dof else slice(None)

        def evaluate(alpha):
            xn = it.x.copy()
            self._move(xn, alpha * dx)
            phi_n, grad_n, _ = self._phi_grad(xn, ctx)
            return xn, phi_n, grad_n, (float(grad_n[free] @ dx) if np.isfinite(phi_n) else np.inf)

        if it.fresh and (self._exact_line_search or rescue):
            found = bracketing(evaluate, it.phi, slope, opt.armijo, opt.wolfe, opt.line_search_iter,
                               opt.max_backtracks, opt.rescue_doublings if rescue else 0)
            if found is not None:
                return found
        return backtracking(evaluate, it.phi, slope, opt.armijo, opt.max_backtracks, full_step_only=not it.fresh)

    def _info(self, it: _Iterate, refactor: bool, need_exact: bool, cache, x, x_prev2, ctx: "_Inputs") -> StepInfo:
        """The :class:`StepInfo` of a finished step; with ``need_exact`` it holds the exact
        Hessian's factorisation at x (the held one when ``refactor`` is False)."""
        solver = None
        if need_exact:
            solver = self.solver
            if refactor:
                solver = self.factorize_exact_at(x, ctx.x_prev, x_prev2, ctx.u, cache, ctx.history)
                it.factorizations += 1
        return StepInfo(it.iterations, it.factorizations, it.fallbacks, solver)

    def _initial_guess(self, ctx: "_Inputs", x_prev2, x_prev3, fixed_src):
        """``(x, Phi, dPhi/dx)`` of ``x~`` or, with ``x_{k-3}`` and ``extrapolation=2``, of the
        constant-acceleration guess if its Phi is lower (after abrupt control changes x~ is
        often the better one). Each candidate's Phi comes with its gradient, so the chosen one
        is not evaluated again."""
        sys = self.system
        x = ctx.xt.copy()
        fixed = len(sys.free) < sys.n_dof
        if fixed:
            x.reshape(-1)[sys.fixed_dof] = fixed_src.reshape(-1)[sys.fixed_dof]
        phi_x, grad, _ = self._phi_grad(x, ctx)
        if x_prev3 is not None and self.options.extrapolation == 2:
            x2 = np.ascontiguousarray(3.0 * (ctx.x_prev - x_prev2) + x_prev3)   # C order: reshape is a view
            if fixed:
                x2.reshape(-1)[sys.fixed_dof] = fixed_src.reshape(-1)[sys.fixed_dof]
            phi_2, grad_2, _ = self._phi_grad(x2, ctx)
            if phi_2 < phi_x:
                return x2, phi_2, grad_2
        return x, phi_x, grad

    def _converged(self, norm: float, prev_norm: float, kind, prev_kind) -> bool:
        """Whether taking the step of size ``norm`` ends the iteration (module docstring).

        ``kind`` is "newton" (fresh exact Hessian), "chord" (reused factorisation) or None
        (a fallback Hessian); ``prev_kind`` is that of the full step of size ``prev_norm``
        before it (None after a damped step). The step itself must be ``<= tol``. A Newton
        step then ends the iteration (quadratic convergence leaves ~C tol^2); any other step
        only when it and the step before are of the same kind with contraction
        ``rho = norm / prev_norm < 1/2`` and the error left, ``norm rho / (1 - rho)``, is
        ``<= tol``: the contraction of a chord step measured against a Newton or a damped step
        says nothing about the next one."""
        tol = self.options.tol
        if norm > tol:
            return False
        if kind == "newton":
            return True
        if kind is None or kind != prev_kind or not (np.isfinite(prev_norm) and prev_norm > 0.0):
            return False
        rho = norm / prev_norm
        return rho < 0.5 and norm * rho / (1.0 - rho) <= tol

    def _chord_too_slow(self, norm: float, prev_norm: float) -> bool:
        """Refresh the factorisation when a chord step contracts by less than
        ``refactor_ratio``, or when the contraction it does achieve would still need more than
        ``max_chord`` further steps to reach the tolerance (a fresh Newton step converges
        quadratically: about two more). A step already below ``tol`` that contracts by 1/2 or
        less (possible when ``refactor_ratio > 1/2``) also refreshes: :meth:`_converged` could
        never accept it."""
        if not np.isfinite(prev_norm) or prev_norm <= 0.0:
            return False
        rho = norm / prev_norm
        if rho > self.options.refactor_ratio:
            return True
        if norm <= self.options.tol:
            return rho >= 0.5       # the stopping rule cannot certify such a contraction
        if rho <= 1e-3:
            return False
        return np.log(self.options.tol / norm) / np.log(rho) > self.options.max_chord

    def _refactor(self, it: _Iterate, cache: FactorCache, ctx: "_Inputs") -> None:
        """Assemble and factorise the Hessian at the current iterate; the cache keeps it."""
        cache.drop()                       # until this factorisation has succeeded
        _, _, hdata = self.phi_assemble(it.x, ctx.xt, ctx.x_prev, ctx.u, history=ctx.history)
        exact, nf = self.factorize(hdata, it.x, ctx.xt, ctx.x_prev, ctx.u, ctx.history)
        cache.keep(self.solver, exact)
        it.fresh = True
        it.factorizations += 1
        it.fallbacks += nf

    def factorize_exact_at(self, x, x_prev, x_prev2, u, cache: FactorCache | None = None, history=None):
        """Factorise the exact Hessian of Phi at ``x`` (Cholesky, or LU if indefinite) and return
        the solver object that holds it; ``cache`` (optional) then holds it for reuse."""
        xt = 2.0 * x_prev - x_prev2
        _, _, hdata = self.phi_assemble(x, xt, x_prev, u, history=history)
        if cache is not None:
            cache.drop()
        if self.solver.factorize(hdata):
            if cache is not None:
                cache.keep(self.solver, True)
            return self.solver
        from .linsolve import LUSolver
        if self._fallback is None:
            self._fallback = LUSolver(self.system.pattern)
        if not self._fallback.factorize(hdata, require_pd=False):
            raise SimulationError("the Hessian at the converged state is singular")
        return self._fallback
