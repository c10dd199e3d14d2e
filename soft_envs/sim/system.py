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
from .contact import contact_term
from .contact.box_contact import BoxContact
from .elastic import Elastic
from .gravity import Gravity
from .parameters import MASS_PARAMETERS, check_parameters, node_mass_jacobian
from .terms import EnergyTerm, readonly

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
    they are summed: elastic, cables, contact (the law of ``robot.contact.model``, from
    :data:`~.contact.CONTACT_LAWS`), gravity, and with a box (``robot.box``,
    :mod:`~soft_envs.sim.box`) the contact between the robot and the box last
    (:class:`~.contact.box_contact.BoxContact`; absent otherwise). Terms may keep a history (lagged state
    beyond x_prev, the Coulomb law's stick anchors): the methods take ``history``, a tuple
    aligned with the terms."""

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
        self.contact = contact_term(robot)      # the law registered as [contact] model (on robot.ground)
        masses = [n for n in MASS_PARAMETERS if n != "payload_mass" or robot.payload_nodes.size]
        self._mass_jacobian = dict(zip(masses, node_mass_jacobian(robot, masses).T))
        self.terms: list[EnergyTerm] = [self.elastic, self.cables, self.contact,
                                        Gravity(robot.node_masses, g, self._mass_jacobian)]
        if robot.box is not None:
            self.terms.append(BoxContact(robot))
        blocks = [term.hessian_blocks() for term in self.terms]
        self.pattern, slots, diag_slots = build_pattern(self.n_dof, self.free, [b for bs in blocks for b in bs])
        start = 0
        for term, bs in zip(self.terms, blocks):
            term.bind(slots[start:start + len(bs)], diag_slots)
            start += len(bs)
        self._no_hess = np.zeros(1)          # placeholder for gradient-only assembly

    # ------------------------------------------------------------------ history (lagged state)
    @property
    def has_history(self) -> bool:
        """Whether a term keeps lagged state beyond x_prev (the Coulomb law's stick anchors)."""
        return any(term.has_history for term in self.terms)

    def initial_history(self, x0: np.ndarray) -> tuple:
        """The terms' histories (a tuple aligned with :attr:`terms`, None for the terms without
        one) of a body at rest at ``x0``."""
        x0 = readonly(x0)
        return tuple(term.initial_history(x0) for term in self.terms)

    def next_history(self, x: np.ndarray, x_prev: np.ndarray, history: tuple) -> tuple:
        """The histories after the step from ``x_prev`` to ``x``."""
        x, x_prev = readonly(x), readonly(x_prev)
        return tuple(t.next_history(x, x_prev, h) if t.has_history else None
                     for t, h in zip(self.terms, history))

    def resolve_history(self, history, x_prev: np.ndarray) -> tuple:
        """``history``, or when it is None the history of a body at rest at ``x_prev``."""
        return self.initial_history(x_prev) if history is None else history

    # ------------------------------------------------------------------ E and its derivatives
    def energy(self, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray, history=None) -> float:
        """Potential energy E (no inertia); ``inf`` when an element is inverted. ``history``
        defaults to that of a body at rest at ``x_prev`` (see :meth:`resolve_history`)."""
        x, x_prev = readonly(x), readonly(x_prev)
        history = self.resolve_history(history, x_prev)
        total = 0.0
        for term, h in zip(self.terms, history):
            e = term.energy(x, x_prev, u, h)
            if e == np.inf:
                return np.inf
            total += e
        return total

    def assemble(self, x, x_prev, u, project: bool = False, want_hess: bool = True, history=None):
        """``(E, grad (3n,), hdata (nnz + 1,))`` at ``x``. ``hdata[:nnz]`` are the values of the
        lower-triangular Hessian over the free dofs (see :attr:`pattern`); with
        ``want_hess=False`` hdata is None and only the energy and gradient are computed. With
        ``project`` every term's Hessian is replaced by a positive semi-definite one (the
        elastic term's is projected element by element, :mod:`.psd_projection`)."""
        x, x_prev = readonly(x), readonly(x_prev)
        history = self.resolve_history(history, x_prev)
        grad = np.zeros(self.n_dof)
        hdata = np.zeros(self.pattern.nnz + 1) if want_hess else self._no_hess
        total = 0.0
        for term, h in zip(self.terms, history):
            if project and want_hess:
                e = term.assemble_projected(x, x_prev, u, h, grad, hdata)
            else:
                e = term.assemble(x, x_prev, u, h, grad, hdata, want_hess)
            if e == np.inf:
                return np.inf, grad, (hdata if want_hess else None)
            total += e
        return total, grad, (hdata if want_hess else None)

    def control_jacobian(self, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray, history=None) -> np.ndarray:
        """``d(dE/dx)/du`` (3n, n_motors) (paper eq. 9's right-hand side, per step)."""
        x, x_prev = readonly(x), readonly(x_prev)
        history = self.resolve_history(history, x_prev)
        G = np.zeros((self.n_dof, len(u)))
        for term, h in zip(self.terms, history):
            term.add_control_jacobian(x, x_prev, u, h, G)
        return G

    def prev_product(self, x, x_prev, u, S: np.ndarray, history=None) -> np.ndarray:
        """``d(dE/dx)/dx_prev @ S`` (3n, nz): the lagged terms' part of paper eq. 10's B_k."""
        x, x_prev = readonly(x), readonly(x_prev)
        history = self.resolve_history(history, x_prev)
        out = np.zeros_like(S)
        for term, h in zip(self.terms, history):
            term.add_prev_product(x, x_prev, u, h, S, out)
        return out

    def prev_product_T(self, x, x_prev, u, lam: np.ndarray, out: np.ndarray, history=None) -> None:
        """``out += (d(dE/dx)/dx_prev)^T @ lam`` (the adjoint of :meth:`prev_product`)."""
        x, x_prev = readonly(x), readonly(x_prev)
        history = self.resolve_history(history, x_prev)
        for term, h in zip(self.terms, history):
            term.add_prev_product_T(x, x_prev, u, h, lam, out)

    def history_product(self, x, x_prev, u, history: tuple, P: tuple, out: np.ndarray) -> None:
        """``out (3n, nz) += sum_t d(dE_t/dx)/dhist_t @ P_t`` (``P`` aligned with the terms)."""
        x, x_prev = readonly(x), readonly(x_prev)
        for term, h, p in zip(self.terms, history, P):
            if term.has_history:
                term.add_history_product(x, x_prev, u, h, p, out)

    def history_product_T(self, x, x_prev, u, history: tuple, lam: np.ndarray) -> tuple:
        """Per term ``(d(dE_t/dx)/dhist_t)^T @ lam`` (flattened history; None without one)."""
        x, x_prev = readonly(x), readonly(x_prev)
        out = []
        for term, h in zip(self.terms, history):
            if term.has_history:
                o = np.zeros(h.size)
                term.add_history_product_T(x, x_prev, u, h, lam, o)
                out.append(o)
            else:
                out.append(None)
        return tuple(out)

    def history_tangent_T(self, x, x_prev, history: tuple, m: tuple) -> tuple:
        """Transpose of :meth:`history_tangent` for the adjoints ``m`` of the next histories:
        ``(out_x (3n,), per-term out_h)``."""
        x, x_prev = readonly(x), readonly(x_prev)
        out_x = np.zeros(self.n_dof)
        out_h = []
        for term, h, mt in zip(self.terms, history, m):
            if term.has_history:
                o = np.zeros(h.size)
                term.history_tangent_T(x, x_prev, h, mt, out_x, o)
                out_h.append(o)
            else:
                out_h.append(None)
        return out_x, tuple(out_h)

    def history_tangent(self, x, x_prev, history: tuple, S: np.ndarray, P: tuple) -> tuple:
        """``d next_history / dz`` per term from ``S = dx/dz`` and ``P = dhistory/dz``."""
        x, x_prev = readonly(x), readonly(x_prev)
        return tuple(t.history_tangent(x, x_prev, h, S, p) if t.has_history else None
                     for t, h, p in zip(self.terms, history, P))

    # ------------------------------------------------------------------ physical parameters
    def check_parameters(self, names) -> tuple[str, ...]:
        """``names`` (see :data:`~.parameters.PARAMETERS`) checked against this robot, contact
        law and control mode; a name that no term owns is a ValueError."""
        names = check_parameters(self.robot, names, self.control)
        owned = {n for t in self.terms for n in t.parameters}
        for n in names:
            if n not in owned:
                raise ValueError(f"{self.robot.source}: no energy term depends on parameter {n!r}")
        return names

    def parameter_jacobian(self, x, x_prev, u, names, history=None) -> np.ndarray:
        """``d(dE/dx)/dtheta`` (3n, len(names)): every term's part for the parameters it owns."""
        x, x_prev = readonly(x), readonly(x_prev)
        history = self.resolve_history(history, x_prev)
        out = np.zeros((self.n_dof, len(names)))
        for term, h in zip(self.terms, history):
            if any(n in term.parameters for n in names):
                term.add_parameter_jacobian(x, x_prev, u, h, names, out)
        return out

    def mass_jacobian(self, names) -> np.ndarray:
        """``dm/dtheta`` per dof (3n, len(names)): the diagonal mass matrix's derivative."""
        out = np.zeros((self.n_dof, len(names)))
        for j, n in enumerate(names):
            if n in self._mass_jacobian:
                out[:, j] = np.repeat(self._mass_jacobian[n], 3)
        return out

    def history_parameter_jacobian(self, x, x_prev, history: tuple, names) -> tuple:
        """Per term ``d next_history / dtheta`` at fixed states (None: no dependence)."""
        x, x_prev = readonly(x), readonly(x_prev)
        return tuple(t.history_parameter_jacobian(x, x_prev, h, names) if t.has_history else None
                     for t, h in zip(self.terms, history))

    # ------------------------------------------------------------------ cables
    def cable_deformation(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Gamma = L(x) - alpha(u) per tendon (eq. 2). In tension control alpha = alpha0."""
        return self.cables.deformation(x, u)
