"""What makes a rendered frame explain itself: a legend (slack cable, centre-of-mass path), a
colour bar of cable tension in newtons and a scale bar in centimetres.

:class:`OverlayLayer` draws them once on a transparent figure of the frame's size (pixel axes:
x the column, y the row growing downwards) and lays the result over every frame of
:class:`soft_envs.render.Renderer` (``legend=True``, ``scale_bar=True``); it is drawn again only
when the colour bar's range changes. Drawing the tick labels, legend and colour bar with every
frame made a frame 2.5 times slower.
"""
from __future__ import annotations

import numpy as np
from matplotlib import patheffects
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Colormap, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

__all__ = ["OverlayLayer", "add_legend", "add_tension_colorbar", "add_scale_bar", "scale_bar_length", "fits", "font_size",
           "LEGEND_LABELS", "TENSION_LABEL", "MIN_SIZE"]

#: legend entries, in order: a grey cable carries no tension; the red line is the COM's path
LEGEND_LABELS = ("slack cable", "COM path")
TENSION_LABEL = "cable tension [N]"
_HALO = [patheffects.withStroke(linewidth=2.5, foreground="white")]


#: smallest frame [px] that gets overlays (below, they would cover the robot)
MIN_SIZE = (240, 180)


def fits(width: int, height: int) -> bool:
    """Whether a ``width`` x ``height`` frame is large enough for the overlays."""
    return width >= MIN_SIZE[0] and height >= MIN_SIZE[1]


def font_size(height: int) -> float:
    """Overlay text size [pt] for an image ``height`` pixels high (7 pt at 360 px)."""
    return float(np.clip(7.0 * height / 360.0, 3.0, 14.0))


def add_legend(ax: Axes, slack_color, trail_color, *, cable_width: float, trail_width: float, fontsize: float):
    """Legend in the top-right corner: a grey line for a slack cable, the red COM path."""
    handles = [Line2D([], [], color=slack_color, lw=cable_width, solid_capstyle="round", label=LEGEND_LABELS[0]),
               Line2D([], [], color=trail_color, lw=trail_width, label=LEGEND_LABELS[1])]
    return ax.legend(handles=handles, loc="upper right", fontsize=fontsize, framealpha=0.85, borderpad=0.4,
                     handlelength=1.8, labelspacing=0.3)


def add_tension_colorbar(fig: Figure, cmap: Colormap, vmax: float, *, fontsize: float) -> ScalarMappable:
    """Horizontal colour bar of cable tension [N] from 0 to ``vmax`` in the bottom-right
    corner; returns its mappable (``set_clim(0, vmax)`` rescales it)."""
    mappable = ScalarMappable(norm=Normalize(vmin=0.0, vmax=vmax), cmap=cmap)
    cax = fig.add_axes((0.60, 0.06, 0.34, 0.03))
    bar = fig.colorbar(mappable, cax=cax, orientation="horizontal")
    cax.set_title(TENSION_LABEL, fontsize=fontsize, pad=2, path_effects=_HALO)   # above; ticks below
    cax.tick_params(labelsize=fontsize, length=2, pad=1)
    for t in cax.get_xticklabels():
        t.set_path_effects(_HALO)
    bar.outline.set_linewidth(0.5)
    return mappable


def scale_bar_length(pixels_per_metre: float, width: int, fraction: float = 0.22) -> float:
    """The longest round length (1, 2 or 5 times a power of ten, in metres) that spans at most
    ``fraction`` of the image width."""
    limit = fraction * width / pixels_per_metre
    exponent = np.floor(np.log10(limit))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0 ** exponent <= limit:
            return float(m * 10.0 ** exponent)
    return float(10.0 ** exponent)                      # pragma: no cover - m = 1 always fits


def add_scale_bar(ax: Axes, pixels_per_metre: float, width: int, height: int, *, fontsize: float) -> float:
    """A scale bar in the bottom-left corner, true at the depth of the camera's look-at point
    (the robot); returns its length [m]."""
    length = scale_bar_length(pixels_per_metre, width)
    x0, y = 0.05 * width, 0.92 * height
    x1 = x0 + length * pixels_per_metre
    tick = 0.015 * height
    style = dict(color="0.1", lw=max(1.5, height / 180.0), solid_capstyle="butt", zorder=6, path_effects=_HALO)
    ax.plot([x0, x1], [y, y], **style)
    ax.plot([x0, x0], [y - tick, y + tick], **style)
    ax.plot([x1, x1], [y - tick, y + tick], **style)
    label = f"{100 * length:g} cm" if length < 1.0 else f"{length:g} m"
    ax.text(0.5 * (x0 + x1), y - 1.6 * tick, label, ha="center", va="bottom", fontsize=fontsize, color="0.1",
            zorder=6, path_effects=_HALO)
    return length


class OverlayLayer:
    """The overlays of a ``width`` x ``height`` frame, drawn once and laid over frames.

    ``legend``: the legend and the tension colour bar (0 to ``tension_max`` N); ``scale_bar``:
    a scale bar for ``pixels_per_metre`` at the look-at point. ``figure`` is the transparent
    figure they are drawn on (for inspection), ``scale_bar_length`` the bar's length [m]."""

    def __init__(self, width: int, height: int, *, legend: bool, scale_bar: bool, pixels_per_metre: float,
                 cmap: Colormap, tension_max: float, slack_color, trail_color, cable_width: float,
                 trail_width: float):
        self.figure = Figure(figsize=(width / 100.0, height / 100.0), dpi=100.0, facecolor=(0.0, 0.0, 0.0, 0.0))
        self._canvas = FigureCanvasAgg(self.figure)
        ax = self.figure.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_axis_off()
        ax.set_xlim(0.0, width)
        ax.set_ylim(height, 0.0)
        ax.autoscale(False)
        fs = font_size(height)
        self.tension_scale: ScalarMappable | None = None
        self.scale_bar_length: float | None = None
        if legend:
            add_legend(ax, slack_color, trail_color, cable_width=cable_width, trail_width=trail_width, fontsize=fs)
            self.tension_scale = add_tension_colorbar(self.figure, cmap, tension_max, fontsize=fs)
        if scale_bar:
            self.scale_bar_length = add_scale_bar(ax, pixels_per_metre, width, height, fontsize=fs)
        self._layer: tuple | None = None      # (colour bar range, pixels, premultiplied rgb, 1 - alpha)

    def set_tension_max(self, tension_max: float) -> None:
        """Rescale the colour bar to 0..``tension_max`` N (redrawn at the next frame)."""
        if self.tension_scale is not None and self.tension_scale.get_clim() != (0.0, tension_max):
            self.tension_scale.set_clim(0.0, tension_max)

    def over(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` (h, w, 3) uint8 with the overlays on top."""
        key = None if self.tension_scale is None else self.tension_scale.get_clim()
        if self._layer is None or self._layer[0] != key:
            self._canvas.draw()
            rgba = np.zeros(frame.shape[:2] + (4,), np.float32)
            drawn = np.asarray(self._canvas.buffer_rgba(), dtype=np.float32) / 255.0
            h, w = min(drawn.shape[0], frame.shape[0]), min(drawn.shape[1], frame.shape[1])
            rgba[:h, :w] = drawn[:h, :w]
            rgba = rgba.reshape(-1, 4)
            where = np.flatnonzero(rgba[:, 3] > 0)               # only the overlays' pixels are blended
            alpha = rgba[where, 3:]
            self._layer = (key, where, 255.0 * rgba[where, :3] * alpha, 1.0 - alpha)
        _, where, rgb, keep = self._layer
        out = frame.copy()
        flat = out.reshape(-1, 3)
        flat[where] = np.rint(rgb + keep * flat[where]).astype(np.uint8)
        return out
