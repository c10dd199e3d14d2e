"""Newton's settings (:class:`NewtonOptions`), what a step reports (:class:`StepInfo`) and the
error a failed step raises (:class:`SimulationError`); the solver is :mod:`.integrator`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SimulationError", "NewtonOptions", "StepInfo"]


class SimulationError(RuntimeError):
    """A simulation step failed. ``step`` is the step index (or None), ``reason`` a short text;
    ``rescuable``: Newton ran out of iterations or of line search, which a second solve with
    longer line searches may mend (:class:`~.integrator.NewtonSolver`)."""

    def __init__(self, reason: str, step: int | None = None, *, rescuable: bool = False):
        self.reason = reason
        self.step = step
        self.rescuable = rescuable
        super().__init__(f"simulation step {step} failed: {reason}" if step is not None else reason)


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings.

    ``tol``: the last step's max-norm [m]; the error of the returned state is below it for
    tol <= 1e-6 (see the module docstring). Sensitivities use a factorisation taken up to
    ``tol`` away from ``x_k``: keep tol <= 1e-6 when Jacobians matter (at 1e-8 they match the
    exact Hessian at x_k to ~1e-12).
    ``max_iter``: iterations per step. ``armijo``: sufficient-decrease constant;
    ``max_backtracks``: halvings of the line search. ``reuse_factor``: keep the last
    factorisation (from this or an earlier step) while it still contracts the step by at least
    ``refactor_ratio`` per iteration (chord iterations cost a gradient and a solve instead of a
    Hessian assembly and a factorisation) and while the predicted number of further chord
    steps stays below ``max_chord``; ``False`` gives plain Newton. ``extrapolation``: 1 = start
    from ``x~`` (constant velocity); 2 = also try the constant-acceleration guess when the
    caller passes ``x_{k-3}`` and keep the one with the lower Phi (see the module docstring).
    ``solver``: "auto", "cholmod" or "lu". ``line_search``: "backtracking" (halving from the
    full step until Armijo holds), "exact" (brackets the minimum of Phi along a Newton step,
    ``line_search_iter`` evaluations at most, until the directional derivative is ``wolfe``
    times its initial value; measured on the Coulomb law's random-action steps: 25 % fewer
    iterations, 30 % fewer factorisations) or "auto": exact for contact laws with stick
    anchors (Coulomb), backtracking for the paper's law (whose results it reproduces bit for
    bit; on it the exact search gains nothing measurable).
    ``rescue_doublings``: a step that fails (too many iterations, a failed line search) is
    solved once more from its start, afresh, with the exact line search allowed to double a
    step that still descends steeply up to this many times (:func:`.line_search.bracketing`):
    where Phi curves downwards (a node on the convex edge of a height field's step, pressed in)
    the modified Hessian's steps are far too short and 50 of them creep (measured: a Tripod
    policy's step on the step task, |dx| growing from 1.3e-6 to 6.2e-6 m over 45 iterations).
    Steps that converge the first time are untouched, bit for bit; 0: no rescue."""

    tol: float = 1e-8
    max_iter: int = 50
    armijo: float = 1e-6
    max_backtracks: int = 40
    reuse_factor: bool = True
    refactor_ratio: float = 0.5
    max_chord: float = 4.0
    extrapolation: int = 2
    solver: str = "auto"
    line_search: str = "auto"
    line_search_iter: int = 8
    wolfe: float = 0.1
    rescue_doublings: int = 30

    def __post_init__(self):
        for name in ("tol", "armijo", "refactor_ratio", "max_chord"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"NewtonOptions.{name} must be positive, got {v!r}")
        if self.refactor_ratio >= 1.0:
            raise ValueError(f"NewtonOptions.refactor_ratio must be < 1, got {self.refactor_ratio!r}")
        for name in ("max_iter", "max_backtracks"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"NewtonOptions.{name} must be >= 1, got {getattr(self, name)!r}")
        if int(self.rescue_doublings) < 0:
            raise ValueError(f"NewtonOptions.rescue_doublings must be >= 0, got {self.rescue_doublings!r}")
        if self.extrapolation not in (1, 2):
            raise ValueError(f"NewtonOptions.extrapolation must be 1 or 2, got {self.extrapolation!r}")
        if self.line_search not in ("auto", "backtracking", "exact"):
            raise ValueError(f"NewtonOptions.line_search must be 'auto', 'backtracking' or 'exact', "
                             f"got {self.line_search!r}")
        if self.solver not in ("auto", "cholmod", "lu"):
            raise ValueError(f"NewtonOptions.solver must be 'auto', 'cholmod' or 'lu', got {self.solver!r}")


@dataclass
class StepInfo:
    iterations: int
    factorizations: int
    fallbacks: int            # factorisations that needed the PSD projection / shift
    solver: object = None     # with need_exact: holds the exact Hessian's factorisation at x_k
