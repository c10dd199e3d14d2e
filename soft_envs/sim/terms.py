r"""The potential energy as a list of terms (paper II-D): ``E(x; u, x_prev, h) = sum_terms E_t``.

Every term sees the same explicit inputs of a step: positions ``x`` (n, 3), the previous
step's positions ``x_prev`` (lagged quantities such as the normal force of the friction law),
the motor controls ``u`` (n_motors,) and its own *history* ``hist``: lagged state that the
previous positions do not determine (the stick anchors of Coulomb friction; ``None`` for the
terms that have none). Static data (mesh, material, cables, contact parameters) is bound when
the term is built; nothing changes between calls. A term gives

* ``assemble(x, x_prev, u, hist, grad, hdata, want_hess)``: adds dE_t/dx into ``grad`` (3n,)
  and d2E_t/dx2 into ``hdata`` (the values of the shared lower-triangular sparsity pattern,
  through the slots it was given by :meth:`EnergyTerm.bind`), returns E_t;
* ``energy(x, x_prev, u, hist)``: E_t alone (``inf`` outside the energy's domain);
* the products the sensitivities need (paper III-A, eqs. 9-11):
  ``add_control_jacobian`` adds ``d(dE_t/dx)/du`` (3n, n_motors), ``add_prev_product`` /
  ``add_prev_product_T`` add ``d(dE_t/dx)/dx_prev @ S`` and its transpose product;
* for terms with history: ``initial_history(x0)`` (at rest), ``next_history(x, x_prev, hist)``
  (after a step), and the derivatives of both: ``add_history_product`` (``d(dE_t/dx)/dhist @
  P``), ``history_tangent`` (``d next_history / dz`` from ``S = dx/dz`` and ``P = dhist/dz``)
  and their transposes for the adjoint;
* the derivative with respect to the physical parameters the term owns (:attr:`parameters`,
  names of :data:`soft_envs.sim.parameters.PARAMETERS`): ``add_parameter_jacobian`` adds
  ``d(dE_t/dx)/dtheta`` at fixed x, x_prev and history (calibration, the parameter block of
  :class:`~soft_envs.sim.sensitivity.ForwardSensitivities`), and for terms whose history update
  depends on a parameter, ``history_parameter_jacobian``. A term that owns no parameter needs
  neither.

The pattern is built once from every term's :meth:`hessian_blocks` (dense blocks of dofs
that a term couples) plus the full diagonal. A new physical effect (another contact law, a
spring, an external load) is one new subclass added to the list in
:class:`soft_envs.sim.system.EnergySystem`; its derivatives are checked against central
finite differences by ``tests/test_energy_derivatives.py`` for every term in the list.
"""
from __future__ import annotations

import numpy as np

__all__ = ["EnergyTerm", "readonly"]


def readonly(a: np.ndarray) -> np.ndarray:
    """``a`` as a read-only view (itself when it is read-only already). The system hands the
    terms their positions this way: the states' arrays are read-only, and numba compiles a
    kernel again for each new argument type, writeable arrays being another type, so a kernel
    met by a Newton iterate and by a state's positions would otherwise be compiled twice (the
    box's sensitivity kernels: about a fifth of the simulator's compile time)."""
    if a.flags.writeable:
        a = a.view()
        a.flags.writeable = False
    return a


class EnergyTerm:
    """Interface of an energy term (defaults: no Hessian blocks, no dependence on u, x_prev or
    a history)."""

    #: short name used in messages and tests
    name = "term"
    #: whether the term keeps lagged state of its own (see the module docstring)
    has_history = False
    #: the physical parameters its gradient depends on (names of ``parameters.PARAMETERS``)
    parameters: tuple[str, ...] = ()

    def hessian_blocks(self) -> list[np.ndarray]:
        """Arrays ``(k, p)`` of dof indices: each row is a dense block of ``p`` dofs whose
        ``p x p`` Hessian entries the term writes. Diagonal-only terms return ``[]`` and use
        :attr:`diag_slots` after :meth:`bind`."""
        return []

    def bind(self, slots: list[np.ndarray], diag_slots: np.ndarray) -> None:
        """Receive the scatter maps: ``slots[i]`` (k, p*p) gives, row-major, the position in
        the Hessian values of every entry of block array i (``nnz`` for entries that are not
        stored: upper triangle or fixed dofs); ``diag_slots`` (3n,) the slot of each diagonal
        entry (``nnz`` for fixed dofs)."""
        self.diag_slots = diag_slots

    def energy(self, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray, hist=None) -> float:
        raise NotImplementedError

    def assemble(self, x, x_prev, u, hist, grad: np.ndarray, hdata: np.ndarray, want_hess: bool) -> float:
        raise NotImplementedError

    def assemble_projected(self, x, x_prev, u, hist, grad, hdata) -> float:
        """Like :meth:`assemble` with the Hessian replaced by a positive semi-definite one
        (the Newton solver's fallback when the exact Hessian is not positive definite).
        Default: the exact Hessian, right for terms that are convex in x."""
        return self.assemble(x, x_prev, u, hist, grad, hdata, True)

    def add_control_jacobian(self, x, x_prev, u, hist, G: np.ndarray) -> None:
        """``G (3n, n_motors) += d(dE_t/dx)/du``."""

    def add_prev_product(self, x, x_prev, u, hist, S: np.ndarray, out: np.ndarray) -> None:
        """``out (3n, nz) += d(dE_t/dx)/dx_prev @ S``."""

    def add_prev_product_T(self, x, x_prev, u, hist, lam: np.ndarray, out: np.ndarray) -> None:
        """``out (3n,) += (d(dE_t/dx)/dx_prev)^T @ lam``."""

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out: np.ndarray) -> None:
        """``out[:, j] (3n,) += d(dE_t/dx)/dtheta_j`` for every ``names[j]`` in
        :attr:`parameters` (x, x_prev, u and the history held fixed; lagged quantities such as
        the normal force N_{k-1} included through their explicit parameter dependence)."""

    # ------------------------------------------------------------------ history (lagged state)
    def initial_history(self, x0: np.ndarray):
        """The history of a body at rest at ``x0`` (None for terms without one)."""
        return None

    def next_history(self, x: np.ndarray, x_prev: np.ndarray, hist):
        """The history after the step from ``x_prev`` to ``x`` started with ``hist``."""
        return None

    def add_history_product(self, x, x_prev, u, hist, P: np.ndarray, out: np.ndarray) -> None:
        """``out (3n, nz) += d(dE_t/dx)/dhist @ P`` for ``P = dhist/dz`` (flattened history)."""

    def add_history_product_T(self, x, x_prev, u, hist, lam: np.ndarray, out: np.ndarray) -> None:
        """``out (len(hist.ravel()),) += (d(dE_t/dx)/dhist)^T @ lam``."""

    def history_tangent(self, x, x_prev, hist, S: np.ndarray, P: np.ndarray) -> np.ndarray:
        """``d next_history / dz`` (flattened history, nz) from ``S = dx/dz`` (3n, nz) and
        ``P = dhist/dz`` (the derivative through x_prev vanishes wherever it exists)."""
        raise NotImplementedError

    def history_parameter_jacobian(self, x, x_prev, hist, names) -> np.ndarray | None:
        """``d next_history / dtheta`` at fixed x, x_prev and hist (flattened history,
        len(names)), or None when the update does not depend on the parameters."""
        return None

    def history_tangent_T(self, x, x_prev, hist, m: np.ndarray, out_x: np.ndarray, out_h: np.ndarray) -> None:
        """Transpose of :meth:`history_tangent`: ``out_x (3n,) += (d next/dx)^T m`` and
        ``out_h += (d next/dhist)^T m``."""
        raise NotImplementedError
