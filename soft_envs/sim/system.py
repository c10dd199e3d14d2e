"""The total potential energy as the list of its terms, and its fixed sparse Hessian pattern.

``E(x; u, x_prev) = E_FEM + E_cables + E_contact + E_gravity`` (paper II-D), each an
:class:`~soft_envs.sim.terms.EnergyTerm`. The Hessian's sparsity pattern (lower triangle, CSC,
free dofs only) is built once from the terms' dense blocks plus the diagonal; every term then
writes into one flat value array through its scatter maps. Entries that involve a fixed dof,
or that lie above the diagonal (their mirror image is stored), go to a trash slot at the end
of the value array.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .cables import Cables, CableTensions
from .contact import GroundContact
from .elastic import Elastic
from .gravity import Gravity
from .terms import EnergyTerm

__all__ = ["EnergySystem", "Pattern", "build_pattern"]


@dataclass(frozen=True, eq=False)
class Pattern:
    """Lower-triangular CSC sparsity pattern over the free dofs."""

    n: int                 # number of free dofs
    indptr: np.ndarray
    indices: np.ndarray    # row indices
    cols: np.ndarray       # column index of each stored entry
    diag: np.ndarray       # slot of each diagonal entry (n,)

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def lower(self, data: np.ndarray) -> sp.csc_matrix:
        return sp.csc_matrix((data[: self.nnz], self.indices, self.indptr), shape=(self.n, self.n))

    def full(self, data: np.ndarray) -> sp.csc_matrix:
        """The symmetric matrix ``L + L^T - diag`` as CSC."""
        low = self.lower(data)
        return (low + low.T - sp.diags(low.diagonal())).tocsc()


def build_pattern(n_dof: int, free: np.ndarray, blocks: list[np.ndarray]):
    """``(pattern, slots, diag_slots)`` for dense dof ``blocks`` (arrays (k, p)) plus the
    diagonal: ``slots[i]`` (k, p*p) row-major positions of block array i's entries in the value
    array, ``diag_slots`` (n_dof,); ``pattern.nnz`` (the trash slot) for unstored entries."""
    full_to_free = -np.ones(n_dof, dtype=np.int64)
    full_to_free[free] = np.arange(len(free))
    diag = np.arange(n_dof)
    rows = [np.repeat(b, b.shape[1], axis=1).ravel() for b in blocks] + [diag]
    cols = [np.tile(b, (1, b.shape[1])).ravel() for b in blocks] + [diag]
    sizes = [len(r) for r in rows]
    r = full_to_free[np.concatenate(rows)]
    c = full_to_free[np.concatenate(cols)]
    keep = (r >= 0) & (c >= 0) & (r >= c)
    n = len(free)
    uniq, inv = np.unique(c[keep] * n + r[keep], return_inverse=True)
    slot = np.full(len(r), len(uniq), dtype=np.int64)              # trash = nnz
    slot[keep] = inv.ravel()
    ucols, urows = np.divmod(uniq, n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, ucols + 1, 1)
    indptr = np.cumsum(indptr)
    parts = np.split(slot, np.cumsum(sizes)[:-1])
    slots = [p.reshape(len(b), -1) for p, b in zip(parts[:-1], blocks)]
    diag_slots = parts[-1]
    pattern = Pattern(n, indptr, urows.astype(np.int64), ucols.astype(np.int64), diag_slots[free])
    return pattern, slots, diag_slots


class EnergySystem:
    """The energy terms of one robot and their shared Hessian pattern.

    ``gravity`` is a 3-vector [m/s^2]; ``control`` is ``"length"`` (u = contracted cable length
    [m], paper eq. 3: :class:`~.cables.Cables`) or ``"tension"`` (u = cable tension [N] >= 0,
    paper appendix A: :class:`~.cables.CableTensions`). ``terms`` lists the terms in the order
    they are summed: elastic, cables, contact, gravity."""

    def __init__(self, robot, gravity=(0.0, -9.81, 0.0), control: str = "length"):
        if control not in ("length", "tension"):
            raise ValueError(f"control must be 'length' or 'tension', got {control!r}")
        g = np.asarray(gravity, dtype=np.float64)
        if g.shape != (3,) or not np.isfinite(g).all():
            raise ValueError(f"gravity must be a finite 3-vector, got {gravity!r}")
        self.robot = robot
        self.control = control
        self.gravity = g
        self.n_nodes = robot.mesh.n_nodes
        self.n_dof = 3 * self.n_nodes
        self.mass = np.repeat(robot.node_masses, 3)
        fixed = np.zeros(self.n_nodes, dtype=bool)
        fixed[robot.fixed_nodes] = True
        self.fixed_dof = np.repeat(fixed, 3)
        self.free = np.flatnonzero(~self.fixed_dof)
        self.elastic = Elastic(robot)
        self.cables = (Cables if control == "length" else CableTensions)(robot)
        self.contact = GroundContact(robot)
        self.terms: list[EnergyTerm] = [self.elastic, self.cables, self.contact,
                                        Gravity(robot.node_masses, g)]
        blocks = [term.hessian_blocks() for term in self.terms]
        self.pattern, slots, diag_slots = build_pattern(self.n_dof, self.free, [b for bs in blocks for b in bs])
        start = 0
        for term, bs in zip(self.terms, blocks):
            term.bind(slots[start:start + len(bs)], diag_slots)
            start += len(bs)
        self._no_hess = np.zeros(1)          # placeholder for gradient-only assembly

    # ------------------------------------------------------------------ E and its derivatives
    def energy(self, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray) -> float:
        """Potential energy E (no inertia); ``inf`` when an element is inverted."""
        total = 0.0
        for term in self.terms:
            e = term.energy(x, x_prev, u)
            if e == np.inf:
                return np.inf
            total += e
        return total

    def assemble(self, x, x_prev, u, project: bool = False, want_hess: bool = True):
        """``(E, grad (3n,), hdata (nnz + 1,))`` at ``x``. ``hdata[:nnz]`` are the values of the
        lower-triangular Hessian over the free dofs (see :attr:`pattern`); with
        ``want_hess=False`` hdata is None and only the energy and gradient are computed. With
        ``project`` every term's Hessian is replaced by a positive semi-definite one (the
        elastic term's is projected element by element, :mod:`.psd_projection`)."""
        grad = np.zeros(self.n_dof)
        hdata = np.zeros(self.pattern.nnz + 1) if want_hess else self._no_hess
        total = 0.0
        for term in self.terms:
            if project and want_hess:
                e = term.assemble_projected(x, x_prev, u, grad, hdata)
            else:
                e = term.assemble(x, x_prev, u, grad, hdata, want_hess)
            if e == np.inf:
                return np.inf, grad, (hdata if want_hess else None)
            total += e
        return total, grad, (hdata if want_hess else None)

    def control_jacobian(self, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``d(dE/dx)/du`` (3n, n_motors) (paper eq. 9's right-hand side, per step)."""
        G = np.zeros((self.n_dof, len(u)))
        for term in self.terms:
            term.add_control_jacobian(x, x_prev, u, G)
        return G

    def prev_product(self, x, x_prev, u, S: np.ndarray) -> np.ndarray:
        """``d(dE/dx)/dx_prev @ S`` (3n, nz): the lagged terms' part of paper eq. 10's B_k."""
        out = np.zeros_like(S)
        for term in self.terms:
            term.add_prev_product(x, x_prev, u, S, out)
        return out

    def prev_product_T(self, x, x_prev, u, lam: np.ndarray, out: np.ndarray) -> None:
        """``out += (d(dE/dx)/dx_prev)^T @ lam`` (the adjoint of :meth:`prev_product`)."""
        for term in self.terms:
            term.add_prev_product_T(x, x_prev, u, lam, out)

    # ------------------------------------------------------------------ cables
    def cable_deformation(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Gamma = L(x) - alpha(u) per tendon (eq. 2). In tension control alpha = alpha0."""
        return self.cables.deformation(x, u)
