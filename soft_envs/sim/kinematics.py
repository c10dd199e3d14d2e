"""Rigid-body summaries of a deformable body: best-fit rotation (Kabsch), yaw and tilt.

A soft robot has no rigid "torso". Its orientation is defined here as the rotation ``R`` that
best maps the rest shape onto the current shape in the mass-weighted least-squares sense
(Kabsch / orthogonal Procrustes): ``R = argmin_R sum_i m_i |R (q_i - c_q) - (p_i - c_p)|^2``
over proper rotations, with ``q`` the rest positions, ``p`` the current ones and ``c`` the
centres of mass. Its columns are the body's forward (``R e_x``), up (``R e_y``) and right
(``R e_z``) vectors in the world frame (robots face +x with +y up at rest; right is +z).

Headings and yaw are measured in the ground plane from +x towards +z, i.e. clockwise seen from
above: a positive yaw rate is a right turn (left is -z for a robot facing +x with +y up), the
convention of :mod:`trajopt.tasks.targets`. ``yaw = atan2(f_z, f_x)`` for the forward vector ``f``.
Tilt is the angle between the up vector and +y.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["BodyFrame", "yaw_of", "tilt_deg_of", "wrap_angle", "heading_vector"]


class BodyFrame:
    """Best-fit rotation of a body relative to a reference (rest) shape.

    ``x_ref`` (n, 3) reference positions, ``masses`` (n,) node masses [kg]."""

    def __init__(self, x_ref: np.ndarray, masses: np.ndarray):
        x_ref = np.asarray(x_ref, dtype=np.float64)
        m = np.asarray(masses, dtype=np.float64)
        self.weights = m / m.sum()                       # (n,) so that com = weights @ x
        c = self.weights @ x_ref
        # sum_i m_i (p_i - c_p) (q_i - c_q)^T = x^T (m (q - c_q)) since sum_i m_i (q_i - c_q) = 0
        self._mq = np.ascontiguousarray(m[:, None] * (x_ref - c))

    def com(self, x: np.ndarray) -> np.ndarray:
        """Mass-weighted centre of mass (3,)."""
        return self.weights @ x

    def rotation(self, x: np.ndarray) -> np.ndarray:
        """The proper rotation (3, 3) that best maps the reference shape onto ``x`` (n, 3)."""
        return _kabsch(np.ascontiguousarray(x, dtype=np.float64), self._mq)


@njit(cache=True)
def _det3(a):
    return (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
            - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
            + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))


@njit(cache=True)
def _kabsch(x, mq):
    """``R = U diag(1, 1, d) V^T`` from the SVD of ``x^T mq`` (d = +-1 makes det R = +1)."""
    a = x.T @ mq
    u, _, vt = np.linalg.svd(a)
    if _det3(u) * _det3(vt) < 0.0:                      # reflection: flip the weakest axis
        u[:, 2] = -u[:, 2]
    return u @ vt


def yaw_of(rot: np.ndarray) -> float:
    """Heading [rad] of the forward vector ``rot[:, 0]`` in the ground plane, from +x towards +z."""
    return math.atan2(float(rot[2, 0]), float(rot[0, 0]))


def tilt_deg_of(rot: np.ndarray) -> float:
    """Angle [deg] between the body's up vector ``rot[:, 1]`` and +y."""
    return math.degrees(math.acos(min(1.0, max(-1.0, float(rot[1, 1])))))


def wrap_angle(a: float) -> float:
    """``a`` wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def heading_vector(heading_deg: float) -> np.ndarray:
    """Unit vector in the ground plane at ``heading_deg`` from +x towards +z
    (0: +x, 90: +z, the robot's right)."""
    h = math.radians(heading_deg)
    return np.array([math.cos(h), 0.0, math.sin(h)])
