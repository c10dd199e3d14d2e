r"""The body's heading: yaw of the best-fit rotation of all nodes, and its exact derivative.

A soft robot has no rigid torso; its orientation is the proper rotation ``R`` that best maps
the rest shape onto the current one (mass-weighted Kabsch, :class:`soft_envs.envs.BodyFrame`),
and its heading is ``yaw = atan2(R[2, 0], R[0, 0])``, the direction of the forward vector
``R e_x`` in the ground plane, from +x towards +z (positive = a right turn).

Derivative. With ``A = x^T M (q - c_q)`` (3x3, linear in the positions ``x``) the polar
decomposition ``A = R S`` (``S = R^T A`` symmetric) gives, for a change ``dA``, ``dR = R [w]_x``
with ``(tr(S) I - S) w = axial(R^T dA - dA^T R)`` (differentiate ``R^T A = S = S^T``; for
symmetric ``S``, ``[w]_x S + S [w]_x = [(tr(S) I - S) w]_x``). The yaw only needs the first
column ``dR e_x = R (w x e_x)``, so ``d yaw = c . w`` and, with ``b = (tr(S) I - S)^{-T} c``,
``d yaw = <R [b]_x, dA> = <M (q - c_q) (R [b]_x)^T, dx>``: a gradient with respect to every
node's position, which the rollout's sensitivities ``dx/dz`` carry to the gait parameters.
"""
from __future__ import annotations

import numpy as np

from soft_envs.envs import BodyFrame, yaw_of

__all__ = ["HeadingMeasure"]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class HeadingMeasure:
    """Yaw [rad] of the best-fit rotation of ``x_ref`` (n, 3), the rest shape, onto a state,
    with node masses ``masses`` (n,), and its gradient with respect to the node positions."""

    def __init__(self, x_ref: np.ndarray, masses: np.ndarray):
        self.frame = BodyFrame(x_ref, masses)
        x_ref = np.asarray(x_ref, dtype=np.float64)
        m = np.asarray(masses, dtype=np.float64)
        self._mq = m[:, None] * (x_ref - self.frame.com(x_ref))      # (n, 3): A = x^T mq

    def yaw(self, x: np.ndarray) -> float:
        """Heading [rad] of state ``x`` (n, 3), in (-pi, pi]."""
        return yaw_of(self.frame.rotation(x))

    def yaws(self, xs: np.ndarray) -> np.ndarray:
        """Unwrapped headings [rad] of the states ``xs`` (K+1, n, 3) of a trajectory."""
        return np.unwrap([self.yaw(x) for x in xs])

    def yaw_and_gradient(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """``(yaw, d yaw / dx)`` at ``x`` (n, 3); the gradient has the shape of ``x``."""
        x = np.asarray(x, dtype=np.float64)
        R = self.frame.rotation(x)
        S = R.T @ (x.T @ self._mq)
        S = 0.5 * (S + S.T)
        den = R[0, 0] ** 2 + R[2, 0] ** 2
        # d yaw = c . w: dR[:, 0] = R (w x e_x) = R (0, w_2, -w_1)
        c = np.array([0.0, R[2, 0] * R[0, 2] - R[0, 0] * R[2, 2], R[0, 0] * R[2, 1] - R[2, 0] * R[0, 1]]) / den
        b = np.linalg.solve((np.trace(S) * np.eye(3) - S).T, c)
        return yaw_of(R), self._mq @ (R @ _skew(b)).T

    def jacobian(self, xs: np.ndarray, dxdz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(yaws, dyaw/dz)``: unwrapped headings (K+1,) of the states ``xs`` (K+1, n, 3) and
        their derivatives (K+1, nz) through the rollout's sensitivities ``dxdz`` (K+1, 3n, nz)."""
        yaws = np.empty(len(xs))
        jac = np.empty((len(xs), dxdz.shape[-1]))
        for k, x in enumerate(xs):
            yaws[k], g = self.yaw_and_gradient(x)
            jac[k] = g.ravel() @ dxdz[k]
        return np.unwrap(yaws), jac
