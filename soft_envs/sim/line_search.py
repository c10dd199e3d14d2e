"""Line searches along a Newton step of the incremental potential Phi (paper II-D).

Both take ``evaluate(alpha) -> (x, Phi, grad, dPhi/dalpha)`` (the point ``x + alpha dx``, Phi
and its gradient there, and the directional derivative, ``inf`` where Phi is), ``phi0`` and
the initial slope ``slope = dPhi/dalpha(0) < 0``, and return ``(x, Phi, grad, alpha)`` of the
accepted point or None.

* :func:`backtracking`: alpha = 1, 1/2, 1/4 ... until Armijo's sufficient decrease
  ``Phi(alpha) <= phi0 + armijo alpha slope`` holds (``max_halvings`` tries; one try only for a
  chord step, whose overshoot calls for a new factorisation rather than a shorter step).
* :func:`bracketing`: the ``"exact"`` search: brackets the minimum of Phi along the step and
  returns a point where the directional derivative has shrunk to ``wolfe`` times its initial
  value (Illinois regula falsi on it, kept inside the bracket; Armijo still required), so that
  where a contact, a cable or a friction anchor engages part-way along the step the step stops
  there instead of halving past it.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["backtracking", "bracketing"]

Evaluate = Callable[[float], tuple]


def backtracking(evaluate: Evaluate, phi0: float, slope: float, armijo: float, max_halvings: int,
                 full_step_only: bool = False):
    alpha = 1.0
    for _ in range(max_halvings):
        x, phi, grad, _ = evaluate(alpha)
        if phi <= phi0 + armijo * alpha * slope:
            return x, phi, grad, alpha
        if full_step_only:
            return None
        alpha *= 0.5
    return None


def bracketing(evaluate: Evaluate, phi0: float, slope: float, armijo: float, wolfe: float,
               max_iter: int, max_halvings: int, max_doublings: int = 0):
    """None when no point with Phi finite (within ``max_halvings`` halvings) or no point that
    satisfies Armijo was found (the caller then backtracks). ``max_doublings``: while the full
    step still descends steeply (the directional derivative above ``wolfe`` times its initial
    value in size, Armijo holding), double it, up to that many times, before bracketing: a
    step of a modified Hessian where Phi curves downwards (:class:`~.integrator.NewtonSolver`'s
    rescue) is far too short."""
    best = None
    lo, d_lo = 0.0, slope
    hi = 1.0
    for _ in range(max_halvings):            # an upper end where Phi is finite
        x_hi, phi_hi, g_hi, d_hi = evaluate(hi)
        if np.isfinite(phi_hi):
            break
        hi *= 0.5
    else:
        return None
    for _ in range(max_doublings):
        if not (d_hi < 0.0 and abs(d_hi) > -wolfe * slope and phi_hi <= phi0 + armijo * hi * slope):
            break
        if best is None or phi_hi < best[1]:
            best = (x_hi, phi_hi, g_hi, hi)  # the lowest Armijo point so far
        lo, d_lo, hi = hi, d_hi, 2.0 * hi
        x_hi, phi_hi, g_hi, d_hi = evaluate(hi)
    side = 0
    for _ in range(max_iter):
        if phi_hi <= phi0 + armijo * hi * slope and (best is None or phi_hi < best[1]):
            best = (x_hi, phi_hi, g_hi, hi)
        if d_hi <= 0.0 or abs(d_hi) <= -wolfe * slope:
            break                            # still descending at hi, or flat enough
        a = lo - d_lo * (hi - lo) / (d_hi - d_lo)
        a = min(max(a, lo + 0.02 * (hi - lo)), hi - 0.02 * (hi - lo))
        x_a, phi_a, g_a, d_a = evaluate(a)
        if d_a > 0.0 or not np.isfinite(phi_a):
            hi, d_hi, x_hi, phi_hi, g_hi = a, d_a, x_a, phi_a, g_a
            if side == 1:
                d_lo *= 0.5
            side = 1
        else:
            if phi_a <= phi0 + armijo * a * slope and (best is None or phi_a < best[1]):
                best = (x_a, phi_a, g_a, a)
            if abs(d_a) <= -wolfe * slope:
                return best
            lo, d_lo = a, d_a
            if side == -1:
                d_hi *= 0.5
            side = -1
    return best
