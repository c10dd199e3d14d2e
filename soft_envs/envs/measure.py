"""Measurements of robot states, shared by the environments, ``trajopt``, rendering and export.

The body-frame functions are those of :mod:`soft_envs.sim.kinematics` (re-exported here, the
one way for ``trajopt`` to reach them): :class:`BodyFrame` (centre of mass and the best-fit
rotation of the rest shape onto a state), :func:`yaw_of`, :func:`tilt_deg_of`,
:func:`wrap_angle` and :func:`heading_vector` (degrees from +x towards +z -> unit vector in the
ground plane; the one home of that conversion). Added here: the points of the cable polylines
and the strain energy density of every element, for pictures and ParaView files.
"""
from __future__ import annotations

import numpy as np

from ..sim import Robot
from ..sim.kinematics import BodyFrame, heading_vector, tilt_deg_of, wrap_angle, yaw_of
from ..sim.materials import fem_energy_density

__all__ = ["BodyFrame", "yaw_of", "tilt_deg_of", "wrap_angle", "heading_vector", "cable_points",
           "strain_energy_density"]


def cable_points(robot: Robot, x: np.ndarray) -> list[np.ndarray]:
    """The points of every tendon's polyline at node positions ``x`` (..., n, 3): one array
    (..., p_t, 3) per tendon, in ``robot.tendons`` order (each point is bound to a tet by
    barycentric weights, so it moves with the body)."""
    cd = robot.cable_data
    x = np.asarray(x, dtype=np.float64)
    pts = np.einsum("pa,...pai->...pi", cd.pt_w, x[..., cd.pt_nodes, :])
    return [pts[..., cd.ptr[t]:cd.ptr[t + 1], :] for t in range(len(cd.ptr) - 1)]


def strain_energy_density(robot: Robot, x: np.ndarray) -> np.ndarray:
    """Strain energy density Psi(F) [J/m^3] of every tet (paper eq. 1) at node positions ``x``
    (n, 3), or (K, n, 3) for K states: shape (n_tets,) or (K, n_tets); inf where inverted."""
    x = np.asarray(x, dtype=np.float64)
    mu, lam = robot.element_lame()
    mesh = robot.mesh
    if x.ndim == 2:
        return fem_energy_density(x, mesh.tets, mesh.dN, mu, lam)
    return np.stack([fem_energy_density(xk, mesh.tets, mesh.dN, mu, lam) for xk in x])
