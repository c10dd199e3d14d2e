"""Target centre-of-mass paths in the ground plane (paper eq. 5, Fig. 3).

A target is a (K+1, 2) array of horizontal COM positions (x, z) [m], one per state of a
rollout (index 0 = the start). Headings are measured in degrees from +x towards +z (so a
positive heading and a right turn go to +z: left is -z for a robot facing +x with +y up).
"""
from __future__ import annotations

import numpy as np

from soft_envs.envs import heading_vector

__all__ = ["straight_line", "quarter_circle", "quarter_circle_heading", "from_array", "bl_per_min_to_mps"]


def bl_per_min_to_mps(speed_bl_per_min: float, body_length: float) -> float:
    """Body lengths per minute -> metres per second."""
    return float(speed_bl_per_min) * float(body_length) / 60.0


def _unit(heading_deg: float) -> np.ndarray:
    """(x, z) unit vector of a heading (:func:`soft_envs.envs.heading_vector` in the ground plane)."""
    return heading_vector(heading_deg)[[0, 2]]


def straight_line(start, n_steps: int, dt: float, speed: float, heading_deg: float = 0.0) -> np.ndarray:
    """COM moving at constant ``speed`` [m/s] along ``heading_deg`` from ``start`` (x, z)."""
    t = np.arange(n_steps + 1) * dt
    return np.asarray(start, dtype=np.float64)[None, :] + speed * t[:, None] * _unit(heading_deg)[None, :]


def quarter_circle(start, n_steps: int, dt: float, speed: float, heading_deg: float = 0.0,
                   direction: str = "right", radius: float | None = None) -> np.ndarray:
    """COM moving at ``speed`` along a circular arc that starts tangent to ``heading_deg`` and
    turns ``direction`` ("right" or "left"). By default the radius makes the arc exactly a
    quarter circle over the horizon: ``R = 2 speed T / pi``."""
    sgn, theta, R = _arc_angles(n_steps, dt, speed, direction, radius)
    fwd = _unit(heading_deg)
    side = sgn * np.array([-fwd[1], fwd[0]])                # +90 degrees towards +z for "right"
    pts = R * np.sin(theta)[:, None] * fwd[None, :] + R * (1 - np.cos(theta))[:, None] * side[None, :]
    return np.asarray(start, dtype=np.float64)[None, :] + pts


def _arc_angles(n_steps: int, dt: float, speed: float, direction: str, radius: float | None):
    """``(sign, theta, R)``: +1 for a right turn (towards +z), -1 for a left one; the angle
    (K+1,) [rad] swept along the arc at each state; the radius [m]."""
    if direction not in ("right", "left"):
        raise ValueError(f"direction must be 'right' or 'left', got {direction!r}")
    T = n_steps * dt
    R = 2.0 * speed * T / np.pi if radius is None else float(radius)
    if not R > 0:
        raise ValueError("the turning radius must be positive (speed > 0)")
    return (1.0 if direction == "right" else -1.0), speed * np.arange(n_steps + 1) * dt / R, R


def quarter_circle_heading(n_steps: int, dt: float, speed: float, heading_deg: float = 0.0,
                           direction: str = "right", radius: float | None = None) -> np.ndarray:
    """Heading [rad] (K+1,) of the tangent of :func:`quarter_circle` (same arguments) at each
    state, from +x towards +z: ``heading_deg`` turning by ``speed t / R`` to ``direction``."""
    sgn, theta, _ = _arc_angles(n_steps, dt, speed, direction, radius)
    return np.radians(heading_deg) + sgn * theta


def from_array(target, n_steps: int) -> np.ndarray:
    """Validate a user target: (n_steps + 1, 2) finite horizontal positions."""
    arr = np.asarray(target, dtype=np.float64)
    if arr.shape != (n_steps + 1, 2):
        raise ValueError(f"target must have shape ({n_steps + 1}, 2) (x, z per state), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("target contains NaN or inf")
    return arr
