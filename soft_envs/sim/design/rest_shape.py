r"""Derivatives with respect to the rest shape: moving the rest node positions ``X`` by ``dX``
(n, 3) and the tendons' rest points ``q`` by ``dq`` (what the geometry morphs do: :mod:`.morph`).

Per tet, with ``Dm = [X_1 - X_0, X_2 - X_0, X_3 - X_0]``, ``B = Dm^{-1}`` (the rows of which are
the shape-function gradients ``N_1..N_3``, ``N_0 = -sum``), ``V = det(Dm)/6`` and ``F = Ds B``:

.. math::
    dB = -B\,dDm\,B, \qquad dV = V \operatorname{tr}(B\,dDm) = V \sum_a N_a \cdot dX_a, \qquad
    dF = -F\,dDm\,B .

* Elastic energy (eq. 1) ``E_e = V Psi(F)``: ``dE_e = dV Psi + V P : dF``.
* Elastic gradient ``[g_1 g_2 g_3] = V P B^T`` (``g_0 = -g_1 - g_2 - g_3``): ``d g = dV P B^T +
  V P dB^T + V dP B^T`` with the stress's change along ``dF``, ``dP = mu dF + (mu - lam ln J)
  F^{-T} dF^T F^{-T} + lam tr(F^{-1} dF) F^{-T}`` (the element Hessian of
  :mod:`~soft_envs.sim.materials` applied to the displacement ``dx_a = -F dX_a``, which changes
  F by ``dF``; written batched over the moving tets rather than through the per-element
  kernel, 10x faster).
* Lumped masses ``m_i = rho sum_{e ni i} V_e / 4``: ``dm_i = rho sum_e dV_e / 4``.
* Cable embedding: the barycentric coordinates of ``q`` in its tet satisfy ``sum_a w_a X_a = q``
  and ``sum_a w_a = 1``, so ``dw_a = N_a . (dq - sum_b w_b dX_b)`` and the cable point
  ``p = sum_a w_a x_a`` moves by ``dp = F (dq - sum_b w_b dX_b)``: a rest-shape change acts on
  a cable point like moving its rest position by ``dq - sum_b w_b dX_b``
  (:func:`~.routing.tendon_points_jacobian` without its rest-length part), while the
  assembly length alpha0 follows the rest polyline ``q`` itself.
"""
from __future__ import annotations

import numpy as np

from .routing import (cable_rest_length_jacobian, deformation_point_gradients, rest_length_gradient,
                      tendon_points_jacobian)

__all__ = ["elastic_rest_derivative", "lumped_mass_rest_derivative", "embedding_rest_derivative",
           "cable_rest_derivative", "deformation_rest_derivative", "touched_elements"]


def touched_elements(tets: np.ndarray, dX: np.ndarray) -> np.ndarray:
    """Indices of the tets with a moving rest node."""
    moving = np.abs(dX).max(axis=1) > 0
    return np.flatnonzero(moving[tets].any(axis=1))


def elastic_rest_derivative(elastic, mesh, x: np.ndarray, dX: np.ndarray) -> tuple[float, np.ndarray]:
    """Directional derivatives ``(dE, d(dE/dx))`` (float, (3n,)) of the elastic term at fixed x
    for the rest-node move ``dX`` (n, 3) (module docstring), batched over the tets that move."""
    e = touched_elements(mesh.tets, dX)
    grad = np.zeros(x.size)
    if not e.size:
        return 0.0, grad
    tets, dN, V = mesh.tets[e], mesh.dN[e], mesh.volumes[e]
    mu, lam = elastic.mu[e][:, None, None], elastic.lam[e][:, None, None]
    B = dN[:, 1:]                                                    # (m, 3, 3), rows N_1..N_3
    dXe = dX[tets]
    dDm = np.swapaxes(dXe[:, 1:] - dXe[:, :1], 1, 2)                 # columns dX_j - dX_0
    F = np.einsum("mai,mak->mik", x[tets], dN)
    J = np.linalg.det(F)
    if (J <= 0).any():
        raise ValueError("an element is inverted: the elastic energy has no rest-shape derivative")
    lnJ = np.log(J)[:, None, None]
    FinvT = np.swapaxes(np.linalg.inv(F), 1, 2)
    P = mu * F + (lam * lnJ - mu) * FinvT                           # eq. 1's stress
    BdDm = B @ dDm
    dV = V * np.trace(BdDm, axis1=1, axis2=2)
    dB = -BdDm @ B
    dF = -F @ dDm @ B
    # the stress's change along dF (the element Hessian's action, materials.py):
    # dP = mu dF + (mu - lam ln J) F^-T dF^T F^-T + lam tr(F^-1 dF) F^-T
    trace = np.einsum("mij,mij->m", FinvT, dF)[:, None, None]
    dP = mu * dF + (mu - lam * lnJ) * FinvT @ np.swapaxes(dF, 1, 2) @ FinvT + lam * trace * FinvT
    I1 = np.einsum("mij,mij->m", F, F)
    psi = 0.5 * mu[:, 0, 0] * (I1 - 3.0) - mu[:, 0, 0] * lnJ[:, 0, 0] + 0.5 * lam[:, 0, 0] * lnJ[:, 0, 0] ** 2
    dE = float(np.sum(dV * psi + V * np.einsum("mij,mij->m", P, dF)))
    Bt = np.swapaxes(B, 1, 2)
    dG = (dV[:, None, None] * P @ Bt + V[:, None, None] * (P @ np.swapaxes(dB, 1, 2) + dP @ Bt))
    local = np.empty((len(e), 4, 3))
    local[:, 1:] = np.swapaxes(dG, 1, 2)                             # node a's 3-vector: column a of dG
    local[:, 0] = -local[:, 1:].sum(axis=1)
    np.add.at(grad, (3 * tets[:, :, None] + np.arange(3)).ravel(), local.ravel())
    return dE, grad


def lumped_mass_rest_derivative(mesh, density: float, dX: np.ndarray) -> np.ndarray:
    """``dm`` (n,) of the lumped body masses for the rest-node move ``dX`` (the payload is fixed)."""
    dV = mesh.volumes * np.einsum("eai,eai->e", mesh.dN, dX[mesh.tets])
    dm = np.zeros(mesh.n_nodes)
    np.add.at(dm, mesh.tets.ravel(), np.repeat(density * dV / 4.0, 4))
    return dm


def embedding_rest_derivative(mesh, tet: int, w: np.ndarray, x: np.ndarray, dX: np.ndarray,
                              dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(dw, dp)`` of a cable point with weights ``w`` in tet ``tet`` for the moves ``dX`` of
    the rest nodes and ``dq`` of its rest position: ``dw_a = N_a . delta`` and ``dp = F delta``
    with ``delta = dq - sum_b w_b dX_b``."""
    delta = dq - w @ dX[mesh.tets[tet]]
    return mesh.dN[tet] @ delta, x[mesh.tets[tet]].T @ mesh.dN[tet] @ delta


def _tendon_rest_moves(robot, t: int, dX: np.ndarray, dq: list) -> tuple[np.ndarray, float]:
    """``(delta (P, 3), d alpha0)`` of tendon t for the rest-node move ``dX`` and its points'
    moves ``dq[t]``: each point acts as if its rest position moved by ``delta = dq - sum_b w_b
    dX_b`` (module docstring), its assembly length follows ``dq``."""
    tets, ws = robot._binding[t]
    pts = np.asarray(robot.tendons[t].points)
    delta = dq[t] - np.einsum("sa,sai->si", ws, dX[robot.mesh.tets[tets]])
    return delta, sum(rest_length_gradient(pts, r) @ dq[t][r] for r in range(len(pts)))


def cable_rest_derivative(system, x: np.ndarray, u: np.ndarray, dX: np.ndarray, dq: list) -> np.ndarray:
    """``d(dE_cables/dx)`` (3n,) at fixed x for the rest-node move ``dX`` and the moves ``dq``
    (one (P_t, 3) array per tendon) of the tendons' rest points."""
    out = np.zeros(x.size)
    for t in range(len(system.robot.tendons)):
        delta, dalpha = _tendon_rest_moves(system.robot, t, dX, dq)
        if np.any(delta):
            dofs, J = tendon_points_jacobian(system, x, u, t, rest_length=False)
            np.add.at(out, dofs, J @ delta.ravel())
        if dalpha:
            out -= cable_rest_length_jacobian(system, x, u, t) * dalpha
    return out


def deformation_rest_derivative(system, x: np.ndarray, dX: np.ndarray, dq: list) -> np.ndarray:
    """``dGamma`` (T,) at fixed x for the rest-node move ``dX`` and the moves ``dq`` (one (P_t, 3)
    array per tendon) of the tendons' rest points (a leg morph's points ride with their tets:
    only the assembly lengths move)."""
    out = np.zeros(len(system.robot.tendons))
    for t in range(len(out)):
        delta, dalpha = _tendon_rest_moves(system.robot, t, dX, dq)
        if np.any(delta):
            out[t] += np.einsum("sk,sk->", deformation_point_gradients(system, x, t, rest_length=False), delta)
        out[t] -= dalpha
    return out
