"""The renderer's pinhole camera: where it stands, what it looks at, and world points to pixels.

A :class:`FollowCamera` sits at a fixed offset from its look-at point (``distance`` along the
direction given by ``elevation`` above the horizontal and ``azimuth`` about ``+y``; ``+y`` up)
and projects with a vertical field of view ``fov`` onto an image of ``width`` x ``height``
pixels, row 0 at the top. Points closer than the near plane (``1e-3 distance``) are not
drawable. :class:`soft_envs.render.Renderer` draws with it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FollowCamera"]

_UP = np.array([0.0, 1.0, 0.0])


class FollowCamera:
    """A pinhole camera at a fixed offset from its look-at point (module docstring).

    Args:
        width, height: image size in pixels.
        distance: camera-to-target distance (m).
        elevation: camera angle above the horizontal (degrees).
        azimuth: camera angle about ``+y`` (degrees); 0 looks from ``+z`` towards ``-z``
            (``+x`` to the right), positive swings the camera towards ``+x``.
        fov: vertical field of view (degrees).
    """

    def __init__(self, width: int, height: int, distance: float, elevation: float, azimuth: float,
                 fov: float) -> None:
        self.width, self.height = int(width), int(height)
        self.distance = float(distance)
        el, az = np.radians(elevation), np.radians(azimuth)
        self.offset = self.distance * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        fwd = -self.offset / self.distance
        right = np.cross(fwd, _UP)
        right /= np.linalg.norm(right)
        self.basis = np.stack([right, np.cross(right, fwd), fwd])  # rows: right, up, forward
        #: focal length [pixels]
        self.focal = 0.5 * self.height / np.tan(np.radians(fov) / 2.0)
        self.near = 1e-3 * self.distance

    @staticmethod
    def target(x: np.ndarray) -> np.ndarray:
        """Look-at point: mean node position (non-finite nodes ignored)."""
        x = np.asarray(x, dtype=float)
        ok = np.all(np.isfinite(x), axis=1)
        return x[ok].mean(axis=0) if ok.any() else np.zeros(3)

    def position(self, target: np.ndarray) -> np.ndarray:
        """World position of the camera for a given look-at point."""
        return np.asarray(target, dtype=float) + self.offset

    def project(self, points: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(pixels, depth)`` of world points: ``pixels[..., 0]`` the column and ``pixels[..., 1]``
        the row (0 at the top) as floats; ``depth`` the distance along the view axis (points with
        depth below the near plane are not drawable)."""
        rel = np.asarray(points, dtype=float) - self.position(target)
        cam = rel @ self.basis.T
        depth = cam[..., 2]
        safe = np.where(depth > self.near, depth, self.near)
        col = 0.5 * self.width + self.focal * cam[..., 0] / safe
        row = 0.5 * self.height - self.focal * cam[..., 1] / safe
        return np.stack([col, row], axis=-1), depth

    def drawable(self, pix: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Mask of primitives (axis -2 = vertices) in front of the camera and not fully off-screen."""
        ok = np.all(depth > self.near, axis=-1) & np.all(np.isfinite(pix), axis=(-1, -2))
        margin = 2.0
        off = (np.all(pix[..., 0] < -margin, axis=-1) | np.all(pix[..., 0] > self.width + margin, axis=-1)
               | np.all(pix[..., 1] < -margin, axis=-1) | np.all(pix[..., 1] > self.height + margin, axis=-1))
        return ok & ~off
