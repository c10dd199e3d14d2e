"""The total potential energy of a robot and its assembly into a fixed sparse pattern.

``E(x; u, x_prev) = E_FEM + E_cables + E_contact + E_gravity`` (paper II-D). The Hessian's
sparsity pattern (lower triangle, CSC, free dofs only) and the scatter maps from every
element/tendon/node block into it are built once in :class:`EnergySystem`; each assembly is
then one pass of numba kernels writing into a flat value array. Entries that involve a fixed
dof, or that lie above the diagonal (their mirror image is stored), go to a trash slot at the
end of the value array.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .cables import LENGTH_CONTROL, TENSION_CONTROL, cable_assemble, cable_energy, cable_lengths
from .contact import contact_assemble, contact_energy
from .materials import fem_assemble, fem_energy
from .psd_projection import fem_assemble_projected

__all__ = ["EnergySystem", "Pattern"]


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


def _block_dofs(nodes: np.ndarray) -> np.ndarray:
    """(k, p) node indices -> (k, 3p) dof indices in node-major order."""
    return (3 * nodes[:, :, None] + np.arange(3)).reshape(len(nodes), -1)


class EnergySystem:
    """Static assembly data for one robot. ``gravity`` is a 3-vector [m/s^2]; ``control`` is
    ``"length"`` (u = contracted cable length [m], paper eq. 3) or ``"tension"`` (u = cable
    tension [N] >= 0, paper appendix A)."""

    def __init__(self, robot, gravity=(0.0, -9.81, 0.0), control: str = "length"):
        if control not in ("length", "tension"):
            raise ValueError(f"control must be 'length' or 'tension', got {control!r}")
        g = np.asarray(gravity, dtype=np.float64)
        if g.shape != (3,) or not np.isfinite(g).all():
            raise ValueError(f"gravity must be a finite 3-vector, got {gravity!r}")
        self.robot = robot
        self.control = control
        self.mode = LENGTH_CONTROL if control == "length" else TENSION_CONTROL
        self.gravity = g
        mesh = robot.mesh
        self.n_nodes = mesh.n_nodes
        self.n_dof = 3 * mesh.n_nodes
        self.tets, self.dN, self.vol = mesh.tets, mesh.dN, mesh.volumes
        self.mu, self.lam = robot.element_lame()
        self.mass = np.repeat(robot.node_masses, 3)
        self.f_gravity = (robot.node_masses[:, None] * g[None, :]).ravel()
        cab = robot.cable_data
        self.pt_nodes, self.pt_w, self.ptr = cab.pt_nodes, cab.pt_w, cab.ptr
        self.alpha0, self.k_cable, self.eps_cable = cab.rest_length, cab.stiffness, robot.cable_blend
        self.tendon_motor = cab.tendon_motor
        c = robot.contact
        self.k_n, self.eps_n, self.mu_f = c.stiffness, c.blend, c.friction
        fixed = np.zeros(self.n_nodes, dtype=bool)
        fixed[robot.fixed_nodes] = True
        self.fixed_dof = np.repeat(fixed, 3)
        self.free = np.flatnonzero(~self.fixed_dof)
        self.contact_nodes = np.setdiff1d(mesh.boundary_nodes, robot.fixed_nodes).astype(np.int64)
        self._build_pattern()

    # ------------------------------------------------------------------ pattern
    def _build_pattern(self) -> None:
        full_to_free = -np.ones(self.n_dof, dtype=np.int64)
        full_to_free[self.free] = np.arange(len(self.free))
        fem_dofs = _block_dofs(self.tets)                                   # (m, 12)
        blocks = [(np.repeat(fem_dofs, 12, axis=1), np.tile(fem_dofs, (1, 12)))]
        hptr = [0]
        for t in range(len(self.ptr) - 1):
            d = _block_dofs(self.pt_nodes[self.ptr[t]:self.ptr[t + 1]].reshape(1, -1)).ravel()
            blocks.append((np.repeat(d, len(d))[None], np.tile(d, len(d))[None]))
            hptr.append(hptr[-1] + len(d) ** 2)
        diag = np.arange(self.n_dof)
        blocks.append((diag[None], diag[None]))
        rows = np.concatenate([full_to_free[r.ravel()] for r, _ in blocks])
        cols = np.concatenate([full_to_free[c.ravel()] for _, c in blocks])
        keep = (rows >= 0) & (cols >= 0) & (rows >= cols)
        n = len(self.free)
        keys = cols[keep] * n + rows[keep]
        uniq, inv = np.unique(keys, return_inverse=True)
        slot = np.full(len(rows), len(uniq), dtype=np.int64)              # trash = nnz
        slot[keep] = inv.ravel()
        ucols, urows = np.divmod(uniq, n)
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.add.at(indptr, ucols + 1, 1)
        indptr = np.cumsum(indptr)
        diag_slot = np.full(self.n_dof, len(uniq), dtype=np.int64)
        n_fem = fem_dofs.size * 12
        n_cab = hptr[-1]
        diag_slot[:] = slot[n_fem + n_cab:]
        self.pattern = Pattern(n, indptr, urows.astype(np.int64), ucols.astype(np.int64),
                               diag_slot[self.free])
        self.fem_map = np.ascontiguousarray(slot[:n_fem].reshape(len(self.tets), 144))
        self.cable_map = np.ascontiguousarray(slot[n_fem:n_fem + n_cab])
        self.cable_hptr = np.asarray(hptr, dtype=np.int64)
        self.diag_slot_full = diag_slot                                     # (3n,), trash if fixed
        self.contact_diag = np.ascontiguousarray(diag_slot.reshape(-1, 3)[self.contact_nodes])
        self._no_hess = np.zeros(1)          # placeholder for gradient-only assembly
        self._controls_cache = (None, None)  # (u bytes, result) of tendon_controls' last call

    # ------------------------------------------------------------------ controls
    def tendon_controls(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-tendon ``(rest length alpha, tension)`` for motor controls ``u`` (read-only
        arrays: the last result is reused while ``u`` is unchanged, as within a Newton step)."""
        u = np.asarray(u, dtype=np.float64)
        key = u.tobytes()
        cached_key, cached = self._controls_cache
        if key == cached_key:
            return cached
        uu = np.zeros(len(self.alpha0))
        has = self.tendon_motor >= 0
        uu[has] = u[self.tendon_motor[has]]
        rest = self.alpha0 - uu if self.mode == LENGTH_CONTROL else self.alpha0.copy()
        rest.flags.writeable = False
        uu.flags.writeable = False
        self._controls_cache = (key, (rest, uu))      # one assignment: never a torn pair
        return rest, uu

    # ------------------------------------------------------------------ energy
    def energy(self, x: np.ndarray, x_prev: np.ndarray, u: np.ndarray) -> float:
        """Potential energy E (no inertia); ``inf`` when an element is inverted."""
        e = fem_energy(x, self.tets, self.dN, self.vol, self.mu, self.lam)
        if e == np.inf:
            return np.inf
        rest, tension = self.tendon_controls(u)
        e += cable_energy(x, self.pt_nodes, self.pt_w, self.ptr, rest, self.k_cable,
                          self.eps_cable, self.mode, tension)
        e += contact_energy(x, x_prev, self.contact_nodes, self.k_n, self.eps_n, self.mu_f)
        return e - float(self.f_gravity @ x.ravel())

    def assemble(self, x, x_prev, u, project: bool = False, want_hess: bool = True):
        """``(E, grad (3n,), hdata (nnz + 1,))`` at ``x``. ``hdata[:nnz]`` are the values of the
        lower-triangular Hessian over the free dofs (see :attr:`pattern`); with
        ``want_hess=False`` hdata is None and only the energy and gradient are computed. With
        ``project`` the elastic part of the Hessian is projected element by element onto its
        positive semi-definite part (:mod:`.psd_projection`)."""
        grad = -self.f_gravity.copy()
        hdata = np.zeros(self.pattern.nnz + 1) if want_hess else self._no_hess
        if project and want_hess:      # the Newton solver's fallback (psd_projection)
            e = fem_assemble_projected(x, self.tets, self.dN, self.vol, self.mu, self.lam, grad, hdata,
                                       self.fem_map)
        else:
            e = fem_assemble(x, self.tets, self.dN, self.vol, self.mu, self.lam, grad, hdata,
                             self.fem_map, want_hess)
        if e == np.inf:
            return np.inf, grad, hdata
        rest, tension = self.tendon_controls(u)
        e += cable_assemble(x, self.pt_nodes, self.pt_w, self.ptr, rest, self.k_cable,
                            self.eps_cable, self.mode, tension, grad, hdata, self.cable_map,
                            self.cable_hptr, want_hess)
        e += contact_assemble(x, x_prev, self.contact_nodes, self.k_n, self.eps_n, self.mu_f,
                              grad, hdata, self.contact_diag, want_hess)
        return e - float(self.f_gravity @ x.ravel()), grad, (hdata if want_hess else None)

    def cable_lengths(self, x: np.ndarray) -> np.ndarray:
        return cable_lengths(x, self.pt_nodes, self.pt_w, self.ptr)

    def cable_deformation(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Gamma = L(x) - alpha(u) per tendon (eq. 2). In tension mode alpha = alpha0."""
        rest, _ = self.tendon_controls(u)
        return self.cable_lengths(x) - rest
