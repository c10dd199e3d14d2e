"""What "upright" and "height" mean on the ground the robot stands on: :class:`GroundReference`.

The environments' health check (:meth:`~soft_envs.envs.task.LocomotionTask.is_healthy`) compares
the COM's height with its height at rest and the body's up vector with the ground's normal. On
the plane ``y = 0`` (no :class:`~soft_envs.sim.ground.HeightField`, or a gravity-rotated incline
``incline_deg``) those are the COM's ``y`` and ``+y``, exactly as before. On a height field they
are measured against the ground under the COM:

- height: ``com_y - h(com_x, com_z)``, the COM's height above the ground straight below it (at
  rest and now alike), so walking down a slope or into a hollow of rough ground does not read as
  falling;
- tilt: the angle between the body's up vector and the normal of the field's plane part (its
  ``slope``; +y for rough ground, a step or a trench), the rest shape's up being that normal. On a
  sloped field a robot that turns on the slope stays upright; the local relief (bumps, a step's
  edge) is not taken as the ground's orientation, which would swing with every bump.
"""
from __future__ import annotations

import math

import numpy as np

from ..sim.ground import HeightField
from ..sim.kinematics import tilt_deg_of

__all__ = ["GroundReference"]


class GroundReference:
    """Heights and tilts relative to ``ground`` (a :class:`HeightField`, or None: the plane y = 0)."""

    def __init__(self, ground: HeightField | None):
        self.ground = ground
        ax, az = (0.0, 0.0) if ground is None else ground.slope
        self.tilted = (ax, az) != (0.0, 0.0)
        n = np.array([-ax, 1.0, -az])
        self.normal = n / np.linalg.norm(n)          # the plane part's unit normal

    def height_under(self, com: np.ndarray) -> float:
        """The ground's height ``h`` [m] under the point ``com`` (3,) (0 on the plane y = 0; 0
        too when ``com`` is not finite, which the health check refuses anyway)."""
        if self.ground is None or not np.isfinite(com).all():
            return 0.0
        return float(self.ground.derivatives(com[0], com[2])[0])

    def tilt_deg(self, rot: np.ndarray) -> float:
        """The body's tilt [deg]: the angle between its up vector ``rot @ n`` (``rot`` the
        best-fit rotation of the rest shape, whose up is the normal ``n``) and ``n``; on ground
        without a plane slope, :func:`~soft_envs.sim.kinematics.tilt_deg_of` (bit for bit)."""
        if not self.tilted:
            return tilt_deg_of(rot)
        c = float(self.normal @ rot @ self.normal)
        return math.degrees(math.acos(min(1.0, max(-1.0, c))))
