"""Sparse symmetric solvers for the Newton Hessian on a fixed pattern.

:class:`CholmodSolver` (CHOLMOD through cvxopt's bundled SuiteSparse) does the symbolic
analysis once per pattern and only a numeric factorisation per Newton iteration. It needs a
positive definite matrix: :meth:`factorize` returns False otherwise, and the caller falls back.
:class:`LUSolver` (SuperLU through scipy, with the symmetric-mode options that were fastest on
these matrices) works for any non-singular matrix; it is the fallback and the default when
cvxopt is not installed.

Both count their factorisations (``generation``, incremented by every :meth:`factorize` call,
successful or not), so that a caller that wants to reuse a factorisation later can tell
whether it is still the one it made (:class:`FactorCache`).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as sla

from .system import Pattern

try:  # pragma: no cover - exercised implicitly
    from cvxopt import cholmod as _cholmod
    from cvxopt import matrix as _cvx_matrix
    from cvxopt import spmatrix as _cvx_spmatrix
    HAVE_CHOLMOD = True
except ImportError:  # pragma: no cover
    HAVE_CHOLMOD = False

__all__ = ["CholmodSolver", "LUSolver", "FactorCache", "make_solver", "HAVE_CHOLMOD"]


class LUSolver:
    """SuperLU on the full symmetric matrix.

    ``factorize(data)`` reports, like Cholesky, whether the matrix is positive definite: with
    symmetric-mode diagonal pivoting the signs of U's diagonal are those of the pivots of an
    LDL^T factorisation (Sylvester's law of inertia). ``require_pd=False`` accepts any
    non-singular matrix (for the exact Hessian the sensitivities need)."""

    def __init__(self, pattern: Pattern):
        self.pattern = pattern
        self.generation = 0
        self._lu = None

    def factorize(self, data: np.ndarray, require_pd: bool = True) -> bool:
        self.generation += 1
        try:
            lu = sla.splu(self.pattern.full(data), permc_spec="MMD_AT_PLUS_A",
                          diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError:   # exactly singular
            self._lu = None
            return False
        if require_pd and not (lu.U.diagonal() > 0).all():
            self._lu = None
            return False
        self._lu = lu
        return True

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=np.float64))


class CholmodSolver:
    """CHOLMOD Cholesky with the symbolic analysis of the pattern done once.

    Not thread-safe: values and 1-D right-hand sides pass through buffers owned by the solver
    (use one solver per thread; the environments' vector modes use processes)."""

    def __init__(self, pattern: Pattern):
        self.pattern = pattern
        self.generation = 0
        n = pattern.n
        # cvxopt keeps CSC entries sorted by column then row: the same order as the pattern.
        self._A = _cvx_spmatrix(np.arange(1, pattern.nnz + 1, dtype=np.float64).tolist(),
                                pattern.indices.tolist(), pattern.cols.tolist(), (n, n))
        if not np.array_equal(np.array(self._A.V).ravel(), np.arange(1, pattern.nnz + 1)):
            raise RuntimeError("cvxopt reordered the sparse pattern")
        _cholmod.options["postorder"] = True
        self._F = _cholmod.symbolic(self._A, uplo="L")
        # Reused cvxopt buffers with numpy views of their memory (buffer protocol): filling a
        # view is cheaper than building a cvxopt matrix per call (measured: 14 -> 5 us per
        # factorisation of the Tripod's 9k values, 38 -> 35 us per solve).
        self._V = _cvx_matrix(np.zeros(pattern.nnz))
        self._V_view = np.asarray(self._V)[:, 0]
        self._b = _cvx_matrix(np.zeros(n))
        self._b_view = np.asarray(self._b)[:, 0]

    def factorize(self, data: np.ndarray) -> bool:
        if len(data) < self.pattern.nnz:
            raise ValueError(f"need {self.pattern.nnz} Hessian values, got {len(data)}")
        self.generation += 1
        self._V_view[:] = data[: self.pattern.nnz]
        self._A.V = self._V          # copies the values into the sparse matrix
        try:
            _cholmod.numeric(self._A, self._F)
        except ArithmeticError:   # not positive definite
            return False
        return True

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^{-1} b`` for a vector ``(n,)`` or a block of columns ``(n, k)``; a new array."""
        if np.iscomplexobj(b):
            raise TypeError("CholmodSolver.solve needs a real right-hand side")
        if np.ndim(b) == 1:
            if len(b) != self.pattern.n:
                raise ValueError(f"right-hand side must have length {self.pattern.n}, got {len(b)}")
            self._b_view[:] = b
            _cholmod.solve(self._F, self._b)
            return self._b_view.copy()
        B = _cvx_matrix(np.asarray(b, dtype=np.float64))
        _cholmod.solve(self._F, B)
        return np.array(B).reshape(np.shape(b))


def make_solver(pattern: Pattern, kind: str = "auto"):
    """``"cholmod"``, ``"lu"`` or ``"auto"`` (CHOLMOD when cvxopt is importable)."""
    if kind == "auto":
        kind = "cholmod" if HAVE_CHOLMOD else "lu"
    if kind == "cholmod":
        if not HAVE_CHOLMOD:
            raise ImportError("solver='cholmod' needs cvxopt (pip install cvxopt)")
        return CholmodSolver(pattern)
    if kind == "lu":
        return LUSolver(pattern)
    raise ValueError(f"solver must be 'auto', 'cholmod' or 'lu', got {kind!r}")


class FactorCache:
    """Which factorisation of a :class:`NewtonSolver` a sequence of steps may reuse (chord
    iterations). Owned by the caller that strings steps together: a rollout makes one, an
    environment step with frame skip makes one for its sub-steps. It trusts the solver's
    factorisation only while the solver has not factorised anything else since (generation
    counter), so interleaved users can never reuse each other's factors."""

    __slots__ = ("generation", "exact")

    def __init__(self):
        self.generation = -1
        self.exact = False

    def holds(self, solver) -> bool:
        return self.generation == solver.generation

    def keep(self, solver, exact: bool) -> None:
        self.generation, self.exact = solver.generation, exact

    def drop(self) -> None:
        self.generation = -1
