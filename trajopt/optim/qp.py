"""Linear inequality constraints ``G z <= h`` and the dense convex quadratic programs over them.

The programs are solved by cvxopt's interior-point QP solver (``cvxopt.solvers.qp``): a
well-kept library, already a dependency (CHOLMOD), and made for dense problems of this size
(tens of variables, hundreds to a few thousand inequality rows). Interior-point answers meet
the constraints only to the solver's tolerance, so :func:`solve_qp` solves against constraints
tightened by a small margin and :func:`feasible_fraction` shortens a step until it meets the
exact ones (:data:`FEASIBILITY_ATOL`): what this module returns is feasible, not nearly so.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LinearConstraints", "QPError", "solve_qp", "feasible_fraction", "nearest_feasible",
           "FEASIBILITY_ATOL", "MAX_DIAGONAL_SPREAD"]

#: absolute tolerance of ``G z <= h`` (in the units of h): rounding, not slack
FEASIBILITY_ATOL = 1e-13
#: tightening of every constraint in the QP, relative to the scale of its row
_MARGIN = 1e-9
#: the largest ratio of the scaled Hessian's diagonal entries the range scaling is kept for;
#: beyond it the variables are scaled to a unit diagonal (Jacobi)
MAX_DIAGONAL_SPREAD = 1e8


class QPError(ValueError):
    """The QP has no feasible point, or the solver failed."""


@dataclass(frozen=True)
class LinearConstraints:
    """``G z <= h``: G (m, n), h (m,)."""

    G: np.ndarray
    h: np.ndarray

    def __post_init__(self):
        G = np.atleast_2d(np.asarray(self.G, dtype=np.float64))
        h = np.asarray(self.h, dtype=np.float64).reshape(-1)
        if G.shape[0] != h.shape[0]:
            raise ValueError(f"G has {G.shape[0]} rows, h {h.shape[0]} entries")
        object.__setattr__(self, "G", G)
        object.__setattr__(self, "h", h)

    def residual(self, z: np.ndarray) -> np.ndarray:
        """``G z - h`` (positive: violated)."""
        return self.G @ np.asarray(z, dtype=np.float64) - self.h

    def violation(self, z: np.ndarray) -> float:
        """The largest ``G z - h`` (<= 0 when z is feasible)."""
        return float(self.residual(z).max(initial=-np.inf))

    def feasible(self, z: np.ndarray, atol: float = FEASIBILITY_ATOL) -> bool:
        return self.violation(z) <= atol

    @classmethod
    def box(cls, lower: np.ndarray, upper: np.ndarray) -> "LinearConstraints":
        """``lower <= z <= upper`` as rows."""
        n = len(lower)
        return cls(np.vstack([np.eye(n), -np.eye(n)]), np.concatenate([upper, -np.asarray(lower)]))

    def __and__(self, other: "LinearConstraints") -> "LinearConstraints":
        return LinearConstraints(np.vstack([self.G, other.G]), np.concatenate([self.h, other.h]))


def solve_qp(P: np.ndarray, q: np.ndarray, constraints: LinearConstraints, scale: np.ndarray | None = None
             ) -> np.ndarray:
    """``argmin 0.5 x'Px + q'x`` subject to ``G x <= h`` (P symmetric positive definite), by
    ``cvxopt.solvers.qp`` on the variables ``x / scale`` with every row normalised and
    tightened by a relative margin of 1e-9. When the diagonal of ``P`` in those variables spans
    more than :data:`MAX_DIAGONAL_SPREAD` (variables of very different units, such as keyframes
    in metres beside moduli in pascals), the variables are ``x / s`` with ``s = 1/sqrt(diag P)``
    instead, and each row's margin is relative to its own ``h``: the solver's tolerances are
    relative to the largest entry, and the small ones would otherwise be lost (measured on
    co-design's joint step: "optimal" answers 16 mm from the optimum, worse than no step).
    Raises :class:`QPError` when the program is infeasible or the solver fails."""
    from cvxopt import matrix, solvers

    n = len(q)
    s = np.ones(n) if scale is None else np.asarray(scale, dtype=np.float64)
    diag = np.diag(P) * s * s
    smallest = diag.min(initial=np.inf)
    jacobi = bool(smallest > 0 and diag.max(initial=0.0) > MAX_DIAGONAL_SPREAD * smallest)
    if jacobi:
        s = 1.0 / np.sqrt(np.diag(P))
    Ps = P * np.outer(s, s)
    Ps = 0.5 * (Ps + Ps.T)
    qs = q * s
    Gs = constraints.G * s[None, :]
    norm = np.abs(Gs).max(axis=1)
    keep = norm > 0
    if (constraints.h[~keep] < -FEASIBILITY_ATOL).any():
        raise QPError("a constraint without variables is violated: no feasible point")
    Gs, hs = Gs[keep] / norm[keep, None], constraints.h[keep] / norm[keep]
    # the margin: relative to the largest row's h; in Jacobi's variables a row's h can be of any size
    # (a modulus's bound in pascals), so there each row's own
    hs = hs - _MARGIN * np.maximum(1.0, np.abs(hs) if jacobi else np.abs(hs).max(initial=1.0))
    pscale = max(float(np.abs(Ps).max(initial=0.0)), 1e-300)
    out = solvers.qp(matrix(Ps / pscale), matrix(qs / pscale), matrix(Gs), matrix(hs),
                     options={"show_progress": False, "abstol": 1e-12, "reltol": 1e-11, "feastol": 1e-11,
                              "maxiters": 200})
    if out["status"] not in ("optimal", "unknown") or out["x"] is None:
        raise QPError(f"the QP solver ended with status {out['status']!r}")
    x = np.array(out["x"]).reshape(-1) * s
    if out["status"] == "unknown" and out["primal infeasibility"] is not None and out["primal infeasibility"] > 1e-6:
        raise QPError("the QP has no feasible point (the solver stopped infeasible)")
    return x


def feasible_fraction(constraints: LinearConstraints, z: np.ndarray, dz: np.ndarray,
                      atol: float = FEASIBILITY_ATOL) -> float:
    """The largest ``t`` in [0, 1] with ``G (z + t dz) <= h + atol`` for a feasible ``z``."""
    slack = np.maximum(constraints.h + atol - constraints.G @ z, 0.0)
    rate = constraints.G @ dz
    out = rate > slack          # only these rows stop the full step
    if not out.any():
        return 1.0
    return float(np.clip((slack[out] / rate[out]).min(), 0.0, 1.0))


def nearest_feasible(z: np.ndarray, constraints: LinearConstraints, anchor: np.ndarray | None = None,
                     scale: np.ndarray | None = None) -> np.ndarray:
    """The feasible point nearest to ``z`` in the Euclidean metric (a QP). An interior-point
    answer a rounding outside is pulled towards ``anchor`` (a strictly feasible point) until it
    is feasible."""
    z = np.asarray(z, dtype=np.float64)
    x = z + solve_qp(np.eye(len(z)), np.zeros(len(z)), LinearConstraints(constraints.G, constraints.h
                                                                        - constraints.G @ z), scale)
    if not constraints.feasible(x) and anchor is not None and constraints.feasible(anchor):
        x = anchor + feasible_fraction(constraints, anchor, x - anchor) * (x - anchor)
    if not constraints.feasible(x):
        raise QPError(f"no feasible point found (worst violation {constraints.violation(x):.3g})")
    return x
