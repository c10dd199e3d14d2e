"""Offscreen rendering of a deformed soft robot (no display, no OpenGL).

The :class:`Renderer` projects the boundary surface of a tetrahedral mesh with
its own pinhole camera (:mod:`soft_envs.render_camera`) and draws the result as flat 2-D polygons on a single
persistent Matplotlib Agg canvas (painter's algorithm with back-face culling).
This is several times faster than ``mplot3d`` and fully deterministic: the
same input always gives the same pixels.

Conventions: SI units, ground plane ``y = ground_height`` with ``+y`` up, the
robot faces ``+x`` at rest, ``(x, z)`` is the horizontal plane.  Node
positions are ``(n_nodes, 3)`` arrays.

Optional overlays make a frame explain itself (``legend=True``,
``scale_bar=True``; :mod:`soft_envs.render_overlays`): a legend (grey = slack
cable, red = centre-of-mass path on the ground), a colour bar of cable tension
in newtons, and a scale bar in centimetres.

Also provided: :func:`surface_triangles` (outward boundary faces of a tet
mesh) and :func:`write_animation` (GIF via Pillow, MP4 via imageio-ffmpeg; from
:mod:`soft_envs.animation`).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure

from . import render_overlays as overlays
from .animation import write_animation
from .render_ground import SKY as _SKY
from .render_camera import FollowCamera
from .render_ground import Relief, goal_ring, ground_tiles
from .sim.mesh import boundary_faces

__all__ = ["Renderer", "surface_triangles", "write_animation"]

_SHADOW = np.array([0.42, 0.42, 0.42])
_SLACK = (0.55, 0.55, 0.55, 1.0)
_TRAIL = (0.85, 0.2, 0.1, 1.0)
_GOAL = (0.1, 0.6, 0.25, 1.0)
#: the body's colour unless one is given
BODY_COLOUR = (0.45, 0.70, 0.92)
_CABLE_WIDTH, _TRAIL_WIDTH = 2.2, 1.6

#: boundary faces of a tet mesh, outward (the mesh module's function under the name used here)
surface_triangles = boundary_faces


class Renderer:
    """Follow-camera renderer of a soft robot's surface mesh to RGB arrays.

    One Agg figure is created at construction and reused for every frame.
    Drawn back to front: checkered ground (tiles fixed in world coordinates,
    so motion is visible; on a relief, shaded quads on the ground's surface:
    :mod:`soft_envs.render_ground`), the robot's shadow (upward-facing triangles
    projected vertically onto the ground), the COM trail and a goal's ring on the ground, the
    Lambert-shaded surface (back faces culled, depth-sorted), and the cables
    *on top* of the body (x-ray style, so embedded cables stay visible),
    coloured by tension (grey when slack); then the overlays asked for.

    Args:
        surface_tris: ``(m, 3)`` outward-oriented node indices.
        width, height: image size in pixels.
        body_length: robot length (m); sets camera distance, tile size and
            ground extent.
        elevation: camera angle above the horizontal (degrees).
        azimuth: camera angle about ``+y`` (degrees); 0 looks from ``+z``
            towards ``-z`` (``+x`` to the right), positive swings the camera
            towards ``+x`` (3/4 front view).
        distance: camera-to-target distance (m); default ``3 * body_length``.
        fov: vertical field of view (degrees).
        color: RGB body colour in [0, 1], or ``(m, 3)``: one per triangle
            (a second body, such as a box, in its own colour).
        light_dir: direction *towards* the light (world frame).
        tension_max: tension (N) mapped to the top of the colormap; ``None``
            normalises by the largest tension of each frame.
        slack_tension: tensions at or below this are drawn grey (slack).
        cmap: Matplotlib colormap name for cable tension (its 0.15-0.95 part
            is used, so that a taut cable never looks like the grey of a
            slack one).
        edges: draw thin triangle edges.
        backface_culling: skip triangles facing away from the camera.
        legend: draw a legend (grey = slack cable, red = COM path on the
            ground) and a colour bar of cable tension in newtons
            (:mod:`soft_envs.render_overlays`).
        scale_bar: draw a scale bar (a round length in cm), true at the depth
            of the look-at point; its length in metres is
            :attr:`scale_bar_length`. Frames smaller than 240 x 180 pixels
            get neither overlay: it would cover the robot.
    """

    def __init__(
        self,
        surface_tris: np.ndarray,
        *,
        width: int = 480,
        height: int = 360,
        body_length: float = 0.1,
        elevation: float = 25.0,
        azimuth: float = 35.0,
        distance: float | None = None,
        fov: float = 30.0,
        color: Sequence[float] = BODY_COLOUR,
        light_dir: Sequence[float] = (0.3, 1.0, 0.6),
        tension_max: float | None = None,
        slack_tension: float = 1e-6,
        cmap: str = "plasma",
        edges: bool = True,
        backface_culling: bool = True,
        legend: bool = False,
        scale_bar: bool = False,
    ) -> None:
        tris = np.asarray(surface_tris)
        if tris.ndim != 2 or tris.shape[1] != 3 or not np.issubdtype(tris.dtype, np.integer):
            raise ValueError(f"surface_tris must be an (m, 3) integer array, got {tris.dtype} {tris.shape}")
        if tris.size and tris.min() < 0:
            raise ValueError("surface_tris contains negative indices")
        if width < 8 or height < 8:
            raise ValueError("width and height must be >= 8 pixels")
        if not body_length > 0:
            raise ValueError("body_length must be positive")
        if not -89.0 <= elevation <= 89.0:
            raise ValueError("elevation must be within [-89, 89] degrees")
        self.tris = tris.astype(np.int64)
        self.width, self.height = int(width), int(height)
        self.body_length = float(body_length)
        self.distance = float(distance) if distance is not None else 3.0 * self.body_length
        #: the pinhole camera that follows the look-at point (:mod:`soft_envs.render_camera`)
        self.camera = FollowCamera(self.width, self.height, self.distance, elevation, azimuth, fov)
        self.color = np.asarray(color, dtype=float)
        if self.color.shape not in ((3,), (len(tris), 3)):
            raise ValueError(f"color must be one RGB triple or one per triangle ({len(tris)}, 3), got {self.color.shape}")
        light = np.asarray(light_dir, dtype=float)
        self._light = light / np.linalg.norm(light)
        self.tension_max = tension_max
        self.slack_tension = float(slack_tension)
        self._cmap = ListedColormap(colormaps[cmap](np.linspace(0.15, 0.95, 256)), name=f"{cmap}_cables")
        self.legend, self.scale_bar = bool(legend), bool(scale_bar)
        #: length [m] of the scale bar (None without one)
        self.scale_bar_length: float | None = None
        self.edges = edges
        self.backface_culling = backface_culling
        self.tile_size = self.body_length / 2.0
        self.ground_extent = 8.0 * self.body_length
        #: quads per tile side on a relief (:mod:`soft_envs.render_ground`)
        self.ground_subdivisions = 4
        self._relief: Relief | None = None
        self._build_figure()

    # ------------------------------------------------------------------ setup
    def _build_figure(self) -> None:
        dpi = 100.0
        self._fig = Figure(figsize=(self.width / dpi, self.height / dpi), dpi=dpi, facecolor=_SKY)
        self._canvas = FigureCanvasAgg(self._fig)
        ax = self._fig.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_axis_off()
        ax.set_xlim(0.0, self.width)
        ax.set_ylim(self.height, 0.0)  # pixel rows grow downward
        ax.autoscale(False)
        self._ground = PolyCollection([], zorder=0, edgecolors="face", linewidths=0.3)
        self._shadow = PolyCollection([], zorder=1, facecolors=_SHADOW, edgecolors=_SHADOW, linewidths=0.6)
        self._trail = LineCollection([], zorder=2, colors=[_TRAIL], linewidths=_TRAIL_WIDTH)
        self._goal = LineCollection([], zorder=2, colors=[_GOAL], linewidths=_TRAIL_WIDTH)
        self._pole = LineCollection([], zorder=2, colors=[_GOAL], linewidths=_TRAIL_WIDTH)
        self._body = PolyCollection([], zorder=3, linewidths=0.25 if self.edges else 0.5)
        self._cables = LineCollection([], zorder=4, linewidths=_CABLE_WIDTH, capstyle="round")
        for coll in (self._ground, self._shadow, self._trail, self._goal, self._pole, self._body, self._cables):
            ax.add_collection(coll)
        self._gravity = ax.annotate(
            "", xy=(0, 0), xytext=(0, 0), xycoords="axes fraction", textcoords="axes fraction",
            arrowprops=dict(arrowstyle="-|>", lw=2.0, color="0.15"), zorder=5,
        )
        self._gravity_label = ax.text(0.06, 0.9, "g", transform=ax.transAxes, zorder=5, fontsize=10, color="0.15")
        self._title = ax.text(0.5, 0.97, "", transform=ax.transAxes, ha="center", va="top", zorder=5,
                              fontsize=overlays.font_size(self.height) * 10.0 / 7.0, color="0.1")   # 10 pt at 360 px
        self._ax = ax
        self._overlay = None
        if (self.legend or self.scale_bar) and overlays.fits(self.width, self.height):
            self._overlay = overlays.OverlayLayer(
                self.width, self.height, legend=self.legend, scale_bar=self.scale_bar,
                pixels_per_metre=self.camera.focal / self.distance, cmap=self._cmap, tension_max=self.tension_max or 1.0,
                slack_color=_SLACK, trail_color=_TRAIL, cable_width=_CABLE_WIDTH, trail_width=_TRAIL_WIDTH)
            self.scale_bar_length = self._overlay.scale_bar_length

    @property
    def figure(self) -> Figure:
        """The Matplotlib figure the scene is drawn on (for inspection; reused by every
        frame)."""
        return self._fig

    @property
    def overlay_figure(self) -> Figure | None:
        """The transparent figure of the legend, colour bar and scale bar laid over every frame
        (None without overlays)."""
        return None if self._overlay is None else self._overlay.figure

    # ----------------------------------------------------------------- camera
    def camera_target(self, x: np.ndarray) -> np.ndarray:
        """Look-at point: mean node position (non-finite nodes ignored)."""
        return self.camera.target(x)

    def camera_position(self, target: np.ndarray) -> np.ndarray:
        """World position of the camera for a given look-at point."""
        return self.camera.position(target)

    def project(self, points: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points to pixels (:meth:`FollowCamera.project
        <soft_envs.render_camera.FollowCamera.project>`): ``(pixels, depth)``, ``pixels[..., 0]``
        the column and ``pixels[..., 1]`` the row (0 at the top); points with depth below the near
        plane are not drawable."""
        return self.camera.project(points, target)

    def _drawable(self, pix: np.ndarray, depth: np.ndarray) -> np.ndarray:
        return self.camera.drawable(pix, depth)

    # ----------------------------------------------------------------- layers
    def _update_ground(self, target: np.ndarray, gy: float) -> None:
        quads, cols = ground_tiles(target, self.tile_size, self.ground_extent, height=gy, relief=self._relief,
                                   subdivisions=self.ground_subdivisions, light=self._light)
        pix, depth = self.project(quads, target)
        keep = self._drawable(pix, depth)
        order = np.argsort(-depth.mean(axis=1)[keep], kind="stable")
        self._ground.set_verts(pix[keep][order])
        self._ground.set_facecolor(cols[keep][order])

    def _on_ground(self, pts: np.ndarray, gy: float, lift: float) -> np.ndarray:
        """``pts`` (..., 3) moved vertically onto the ground, ``lift`` [m] above it."""
        out = np.array(pts, dtype=float)
        out[..., 1] = (gy if self._relief is None else self._relief.at(out[..., 0], out[..., 2])) + lift
        return out

    def _set_relief(self, ground) -> None:
        """The relief to draw (None: the plane): a new ground gets a new lattice of heights."""
        if ground is None:
            self._relief = None
        elif self._relief is None or self._relief.ground is not ground:
            self._relief = Relief(ground, self.tile_size / self.ground_subdivisions)

    def _update_body(self, x: np.ndarray, target: np.ndarray, gy: float) -> None:
        p = x[self.tris]  # (m, 3, 3)
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        norm = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = normal / np.where(norm > 0, norm, 1.0)
        finite = np.all(np.isfinite(p), axis=(1, 2))
        centroid = p.mean(axis=1)
        facing = np.einsum("ij,ij->i", normal, self.camera_position(target) - centroid)
        # Shadow: vertical projection of upward-facing triangles.
        up = finite & (normal[:, 1] > 0)
        flat = self._on_ground(p[up], gy, 1e-4 * self.body_length)
        spix, sdepth = self.project(flat, target)
        self._shadow.set_verts(spix[self._drawable(spix, sdepth)])
        # Body: Lambert shading, back-face culling, painter's order.
        pix, depth = self.project(p, target)
        keep = finite & self._drawable(pix, depth)
        if self.backface_culling:
            keep &= facing > 0
        normal = normal * np.where(facing >= 0, 1.0, -1.0)[:, None]
        shade = 0.35 + 0.65 * np.clip(normal @ self._light, 0.0, 1.0)
        rgb = np.clip(np.atleast_2d(self.color) * shade[:, None], 0.0, 1.0)
        order = np.argsort(-depth.mean(axis=1)[keep], kind="stable")
        self._body.set_verts(pix[keep][order])
        self._body.set_facecolor(rgb[keep][order])
        self._body.set_edgecolor(rgb[keep][order] * (0.75 if self.edges else 1.0))

    def _segments(self, pts: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drawable 2-D segments of a 3-D polyline and the indices they come from."""
        pix, depth = self.project(pts, target)
        seg, sdep = np.stack([pix[:-1], pix[1:]], axis=1), np.stack([depth[:-1], depth[1:]], axis=1)
        keep = np.flatnonzero(self._drawable(seg, sdep))
        return seg[keep], keep

    def _update_cables(self, cables: Sequence[tuple[np.ndarray, float]] | None, target: np.ndarray) -> None:
        segs, cols = [], []
        if cables:
            tensions = np.array([float(t) for _, t in cables])
            top = self.tension_max if self.tension_max is not None else max(float(tensions.max()), 1e-12)
            norm = Normalize(vmin=0.0, vmax=top, clip=True)
            if self._overlay is not None:
                self._overlay.set_tension_max(top)
            for i, (pts, tension) in enumerate(cables):
                pts = np.asarray(pts, dtype=float)
                if pts.ndim != 2 or pts.shape[1] != 3:
                    raise ValueError(f"cables[{i}] points must be (p, 3), got {pts.shape}")
                if pts.shape[0] < 2:
                    continue
                seg, _ = self._segments(pts, target)
                colour = _SLACK if tensions[i] <= self.slack_tension else self._cmap(norm(tensions[i]))
                segs.append(seg)
                cols.extend([colour] * len(seg))
        self._cables.set_segments(np.concatenate(segs) if segs else [])
        self._cables.set_color(cols if cols else [_SLACK])

    def _update_trail(self, com_trail: np.ndarray | None, target: np.ndarray, gy: float) -> None:
        if com_trail is None or len(com_trail) < 2:
            self._trail.set_segments([])
            return
        trail = np.array(com_trail, dtype=float)
        if trail.ndim != 2 or trail.shape[1] != 3:
            raise ValueError(f"com_trail must be (t, 3), got {trail.shape}")
        trail = self._on_ground(trail, gy, 2e-4 * self.body_length)
        seg, _ = self._segments(trail, target)
        self._trail.set_segments(seg)

    def _update_goal(self, goal, radius: float | None, target: np.ndarray, gy: float) -> None:
        if goal is None:
            self._goal.set_segments([])
            self._pole.set_segments([])
            return
        r = 0.25 * self.body_length if radius is None else float(radius)
        ring, pole = goal_ring(goal, r, 0.5 * self.body_length, height=gy, relief=self._relief,
                               lift=2e-4 * self.body_length)
        self._goal.set_segments(self._segments(ring, target)[0])
        self._pole.set_segments(self._segments(pole, target)[0])
        # painter's order: the pole hides the body when it stands nearer the camera than the body's centre
        self._pole.set_zorder(3.5 if self.project(pole[:1], target)[1][0] < self.distance else 2)

    def _update_gravity(self, gravity: Sequence[float] | None, target: np.ndarray) -> None:
        g = None if gravity is None else np.asarray(gravity, dtype=float).reshape(3)
        visible = g is not None and bool(np.linalg.norm(g) > 0)
        self._gravity.set_visible(visible)
        self._gravity_label.set_visible(visible)
        if not visible:
            return
        pix, _ = self.project(np.stack([target, target + 0.5 * self.body_length * g / np.linalg.norm(g)]), target)
        d = (pix[1] - pix[0]) * np.array([1.0, -1.0])  # to axes-fraction orientation (y up)
        length = float(np.linalg.norm(d))
        d = d / length if length > 1e-9 else np.zeros(2)
        start = np.array([0.08, 0.82])
        self._gravity.set_position(tuple(start))
        self._gravity.xy = tuple(start + 0.1 * d * np.array([self.height / self.width, 1.0]))

    # ----------------------------------------------------------------- render
    def render(
        self,
        x: np.ndarray,
        *,
        cables: Sequence[tuple[np.ndarray, float]] | None = None,
        com_trail: np.ndarray | None = None,
        ground_height: float = 0.0,
        gravity: Sequence[float] | None = None,
        title: str | None = None,
        look_at: np.ndarray | None = None,
        ground=None,
        goal: np.ndarray | None = None,
        goal_radius: float | None = None,
    ) -> np.ndarray:
        """Render one frame.

        Args:
            x: ``(n_nodes, 3)`` deformed node positions (non-finite triangles
                are skipped).
            cables: list of ``(points (p, 3), tension)``; coloured by tension,
                grey when slack.
            com_trail: ``(t, 3)`` centre-of-mass history, drawn on the ground.
            ground_height: ``y`` of the ground plane (without ``ground``).
            gravity: optional gravity vector, shown as an arrow in the top-left
                corner (projected direction).
            title: optional text at the top.
            look_at: override the camera target (default: mean of ``x``).
            ground: a relief to draw instead of the plane: any object with a
                vectorised ``height(x, z)`` [m] (a
                :class:`~soft_envs.sim.ground.HeightField`); the shadow, the
                trail and the goal lie on it.
            goal: a goal position ``(x, y, z)`` [m]: a green ring of
                ``goal_radius`` (default a quarter body length) on the
                ground around ``(x, z)`` and a pole half a body length tall.

        Returns:
            ``(height, width, 3)`` uint8 RGB image.
        """
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"x must be (n_nodes, 3), got {x.shape}")
        if self.tris.size and x.shape[0] <= self.tris.max():
            raise ValueError(f"x has {x.shape[0]} nodes but surface_tris references node {self.tris.max()}")
        target = self.camera_target(x) if look_at is None else np.asarray(look_at, dtype=float).reshape(3)
        gy = float(ground_height)
        self._set_relief(ground)
        self._update_ground(target, gy)
        self._update_body(x, target, gy)
        self._update_trail(com_trail, target, gy)
        self._update_goal(goal, goal_radius, target, gy)
        self._update_cables(cables, target)
        self._update_gravity(gravity, target)
        self._title.set_text(title or "")
        self._title.set_visible(bool(title))
        self._canvas.draw()
        img = np.asarray(self._canvas.buffer_rgba())[..., :3]
        out = np.empty((self.height, self.width, 3), dtype=np.uint8)
        out[...] = (_SKY * 255).astype(np.uint8)
        h, w = min(self.height, img.shape[0]), min(self.width, img.shape[1])
        out[:h, :w] = img[:h, :w]
        return out if self._overlay is None else self._overlay.over(out)
