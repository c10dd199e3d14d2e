"""The ground under a rendered robot: checkered tiles on a plane or on a relief, and a goal marker.

:class:`soft_envs.render.Renderer` draws what this module builds, in world coordinates (metres,
``+y`` up, ``(x, z)`` horizontal):

* :func:`ground_tiles`: square tiles of side ``tile`` fixed in the world (so that motion is
  visible), alternating two colours, within ``extent`` of the look-at point, fading into the sky
  with the squared distance. On a plane (``relief`` None) each tile is one quad at ``y = height``.
  On a relief (any ground with a vectorised ``height(x, z)``, such as
  :class:`soft_envs.sim.ground.HeightField`) each tile is split into ``subdivisions`` x
  ``subdivisions`` quads whose corners lie on the ground, each shaded by Lambert's law relative
  to a horizontal quad (``(a + b n.l) / (a + b l_y)``, ``a = 0.6, b = 0.4``), so that a flat part
  of a relief has the plane's colours and a slope facing the light is brighter, one facing away
  darker: steps, trenches and rough ground are visible as such.
* :class:`Relief`: the ground's heights on the tiles' lattice, computed once per lattice point
  (a :class:`~soft_envs.sim.ground.HeightField` evaluates its B-spline point by point) and
  interpolated bilinearly between them for the shadow, the COM trail and the goal marker, which
  lie on the ground.
* :func:`goal_ring`: a circle of the goal's radius on the ground, and the pole above its centre
  (half a body length tall).
"""
from __future__ import annotations

import numpy as np

__all__ = ["Relief", "ground_tiles", "goal_ring", "TILE_A", "TILE_B", "SKY"]

SKY = np.array([0.93, 0.95, 0.98])
TILE_A = np.array([0.80, 0.80, 0.78])
TILE_B = np.array([0.68, 0.68, 0.66])
_AMBIENT, _DIFFUSE = 0.6, 0.4
_CORNERS = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])


class Relief:
    """Heights of ``ground`` (``ground.height(x, z)`` on arrays, metres) on the square lattice of
    spacing ``spacing`` [m] (point ``(i, k)`` at ``(i spacing, k spacing)``), each point evaluated
    once, and bilinear interpolation between them (:meth:`at`)."""

    def __init__(self, ground, spacing: float):
        if not callable(getattr(ground, "height", None)):
            raise ValueError(f"ground must have a height(x, z) method (a HeightField), got {type(ground).__name__}")
        if not spacing > 0:
            raise ValueError(f"the relief's lattice spacing must be positive, got {spacing!r}")
        self.ground = ground
        self.spacing = float(spacing)
        self._known: dict[tuple[int, int], float] = {}

    def lattice(self, i: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Heights (len(i), len(k)) [m] at the lattice points ``i x k`` (integer arrays)."""
        ii, kk = (a.ravel() for a in np.meshgrid(np.asarray(i, dtype=np.int64), np.asarray(k, dtype=np.int64),
                                                 indexing="ij"))
        keys = list(zip(ii.tolist(), kk.tolist()))
        self.lattice_points(keys)
        return np.array([self._known[key] for key in keys]).reshape(len(i), len(k))

    def at(self, x, z) -> np.ndarray:
        """The ground's height [m] at the points ``(x, z)`` (arrays of one shape), bilinear
        between the lattice points around each (exact on the lattice)."""
        x, z = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(z, dtype=np.float64))
        u, w = x.ravel() / self.spacing, z.ravel() / self.spacing
        i0, k0 = np.floor(u).astype(np.int64), np.floor(w).astype(np.int64)
        fu, fw = u - i0, w - k0
        out = np.zeros(u.shape)
        for di, dk, weight in ((0, 0, (1 - fu) * (1 - fw)), (1, 0, fu * (1 - fw)),
                               (0, 1, (1 - fu) * fw), (1, 1, fu * fw)):
            keys = list(zip((i0 + di).tolist(), (k0 + dk).tolist()))
            self.lattice_points(keys)
            out += weight * np.array([self._known[key] for key in keys])
        return out.reshape(x.shape)

    def lattice_points(self, keys: list[tuple[int, int]]) -> None:
        """Evaluate the ground at the lattice points ``keys`` not yet known."""
        new = [key for key in dict.fromkeys(keys) if key not in self._known]
        if new:
            m = np.array(new, dtype=np.float64) * self.spacing
            h = np.asarray(self.ground.height(m[:, 0], m[:, 1]), dtype=np.float64).reshape(-1)
            self._known.update(zip(new, h.tolist()))


def ground_tiles(target: np.ndarray, tile: float, extent: float, *, height: float = 0.0,
                 relief: Relief | None = None, subdivisions: int = 4,
                 light: np.ndarray = np.array([0.0, 1.0, 0.0])) -> tuple[np.ndarray, np.ndarray]:
    """``(quads (q, 4, 3), colours (q, 3))`` of the checkered ground within ``extent`` [m] of
    ``target`` (module docstring): on the plane ``y = height`` without a ``relief``, else
    ``subdivisions`` x ``subdivisions`` quads per tile on the relief (whose lattice spacing must
    be ``tile / subdivisions``). ``light``: unit direction towards the light."""
    target = np.asarray(target, dtype=np.float64)
    n = 1 if relief is None else int(subdivisions)
    if n < 1:
        raise ValueError(f"subdivisions must be a positive integer, got {subdivisions!r}")
    s = tile / n
    if relief is not None and not np.isclose(relief.spacing, s):
        raise ValueError(f"the relief's lattice spacing {relief.spacing:g} m is not tile / subdivisions = {s:g} m")
    i = np.arange(np.floor((target[0] - extent) / tile) * n, np.ceil((target[0] + extent) / tile) * n, dtype=np.int64)
    k = np.arange(np.floor((target[2] - extent) / tile) * n, np.ceil((target[2] + extent) / tile) * n, dtype=np.int64)
    ii, kk = (a.ravel() for a in np.meshgrid(i, k, indexing="ij"))
    xs = (ii[:, None] + _CORNERS[None, :, 0]) * s
    zs = (kk[:, None] + _CORNERS[None, :, 1]) * s
    if relief is None:
        ys = np.full_like(xs, float(height))
    else:
        lat = relief.lattice(np.arange(i[0], i[-1] + 2), np.arange(k[0], k[-1] + 2))
        ys = lat[(ii - i[0])[:, None] + _CORNERS[None, :, 0], (kk - k[0])[:, None] + _CORNERS[None, :, 1]]
    quads = np.stack([xs, ys, zs], axis=-1)
    parity = (np.floor_divide(ii, n) + np.floor_divide(kk, n)) % 2
    colours = np.where(parity[:, None] == 0, TILE_A, TILE_B)
    if relief is not None:
        normal = np.cross(quads[:, 2] - quads[:, 0], quads[:, 1] - quads[:, 3])      # upward for a flat quad
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        light = np.asarray(light, dtype=np.float64)
        shade = (_AMBIENT + _DIFFUSE * np.clip(normal @ light, 0.0, 1.0)) / (_AMBIENT + _DIFFUSE * max(light[1], 0.0))
        colours = np.clip(colours * shade[:, None], 0.0, 1.0)
    centre = quads.mean(axis=1)
    fade = np.clip(np.hypot(centre[:, 0] - target[0], centre[:, 2] - target[2]) / extent, 0.0, 1.0)[:, None] ** 2
    return quads, (1.0 - fade) * colours + fade * SKY


def goal_ring(goal, radius: float, pole: float, *, height: float = 0.0, relief: Relief | None = None,
              segments: int = 48, lift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(ring (segments + 1, 3), pole (2, 3))``: the circle of ``radius`` [m] around the goal
    ``(x, ., z)`` on the ground (``lift`` [m] above it) and a vertical segment ``pole`` [m] tall
    from the ground at its centre."""
    g = np.asarray(goal, dtype=np.float64).reshape(-1)
    if g.shape != (3,) or not np.isfinite(g).all():
        raise ValueError(f"goal must be a finite (x, y, z) position, got {goal!r}")
    if not (radius > 0 and pole > 0):
        raise ValueError(f"the goal's radius and pole must be positive, got {radius!r} and {pole!r}")
    t = np.linspace(0.0, 2.0 * np.pi, int(segments) + 1)
    x, z = g[0] + radius * np.cos(t), g[2] + radius * np.sin(t)
    ground = (lambda a, b: relief.at(a, b)) if relief is not None else (lambda a, b: np.full(np.shape(a), height))
    ring = np.stack([x, ground(x, z) + lift, z], axis=1)
    base = float(ground(np.array([g[0]]), np.array([g[2]]))[0])
    return ring, np.array([[g[0], base, g[2]], [g[0], base + pole, g[2]]])
