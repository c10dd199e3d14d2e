"""Check a robot description: load it (every error names the file and field), summarise it and
draw its mesh with the tendons and payload nodes (``trajopt check``).

:func:`check_robot` returns a :class:`RobotCheck` (the robot, summary rows, warnings);
:func:`draw_robot` renders three views (3/4 front, side, top) with :class:`soft_envs.render.Renderer`
and draws the tendons (one colour per motor) and payload nodes on top, with a legend strip.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .meshing import MeshQuality, tet_quality
from .render import Renderer
from .sim.robot import Robot
from .sim.robot_file import load_robot

__all__ = ["RobotCheck", "check_robot", "draw_robot", "RobotPicture", "VIEWS", "MOTOR_COLOURS",
           "PAYLOAD_COLOUR"]

#: (title, elevation, azimuth) of the three views; azimuth 0 looks at the robot's right side
VIEWS = (("3/4 front-right", 25.0, 35.0), ("right side (facing right)", 6.0, 0.0), ("top", 89.0, 0.0))
#: tendon colours, one per motor (no blues: the body is blue)
MOTOR_COLOURS = ("#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#ffbf00",
                 "#17becf", "#7f0000")
PAYLOAD_COLOUR = (0.0, 0.0, 0.0)


@dataclass
class RobotCheck:
    """A loaded robot, its summary (label, value) rows, mesh quality and warnings."""

    robot: Robot
    rows: list[tuple[str, str]]
    quality: MeshQuality
    warnings: list[str] = field(default_factory=list)


def contact_row(robot: Robot) -> str:
    """The contact law in use (the robot file's ``[contact] model``, or the default when it names
    none) and the parameters that law reads, with their units (not the other laws')."""
    c = robot.contact
    named = False
    try:
        with open(robot.source, "rb") as fh:
            named = "model" in tomllib.load(fh).get("contact", {})
    except (OSError, TypeError, ValueError, AttributeError):
        pass
    figures = ", ".join(f"{p.name} {getattr(c, p.name):g}{' ' + p.unit if p.unit else ''}"
                        for p in c.law.contact_parameters)
    where = "the robot file's [contact] model" if named else "the default: the robot file names none"
    return f"{c.model} law ({where}; the commands' --contact switches it): {figures}"


def check_robot(name_or_path: str | Path) -> RobotCheck:
    """Load and summarise a robot (a shipped name or a robot.toml); raises ``ValueError`` naming
    the file and the field for a description that cannot be simulated."""
    robot = load_robot(name_or_path)
    mesh = robot.mesh
    q = tet_quality(mesh.points, mesh.tets)
    ext = np.ptp(mesh.points, axis=0)
    mm = lambda v: f"{1e3 * v:.1f} mm"   # noqa: E731
    rows = [("file", robot.source),
            ("mesh", f"{mesh.n_nodes} nodes, {mesh.n_tets} tets, {len(mesh.boundary_nodes)} surface nodes "
                     f"({mesh.source})"),
            ("size", f"{mm(ext[0])} long, {mm(ext[1])} high, {mm(ext[2])} wide; body_length {mm(robot.body_length)}"),
            ("mass", f"body {1e3 * robot.body_mass:.1f} g + payload {1e3 * robot.payload_mass:.1f} g on "
                     f"{len(robot.payload_nodes)} top nodes = {1e3 * robot.total_mass:.1f} g"),
            ("material", f"E {robot.youngs_modulus:.4g} Pa, nu {robot.poisson_ratio:g}, "
                         f"density {robot.density:.4g} kg/m^3"),
            ("contact", contact_row(robot)),
            ("fixed nodes", str(len(robot.fixed_nodes))),
            *q.rows()]
    rest = dict(zip(robot.tendon_names, robot.cable_data.rest_length))
    tendons = {t.name: t for t in robot.tendons}
    warnings = q.warnings()
    for m in robot.motors:
        cables = ", ".join(f"{t} ({len(tendons[t].points)} points, {mm(rest[t])})" for t in m.tendons)
        rows.append((f"motor {m.name}", f"u {mm(m.u_min)} .. {mm(m.u_max)}, spool radius {mm(m.spool_radius)}"
                                        + (f", mirror {m.mirror}" if m.mirror else "") + f"; tendons {cables}"))
        shortest = min(rest[t] for t in m.tendons)
        if m.u_max > 0.6 * shortest:
            warnings.append(f"motor {m.name}: u_max {mm(m.u_max)} is more than 60 % of its tendon's rest length "
                            f"{mm(shortest)}; the elements along it will be crushed")
    for t, mi in zip(robot.tendons, robot.tendon_motor):
        if mi < 0:
            rows.append((f"tendon {t.name}", f"passive, {len(t.points)} points, rest length {mm(rest[t.name])}"))
    if not robot.motors:
        warnings.append("no motors: the robot cannot move (add [[tendons]] and [[motors]])")
    return RobotCheck(robot, rows, q, warnings)


@dataclass
class RobotPicture:
    """The picture of a robot: ``image`` (H, W, 3) uint8 and, per view ``v``, the pixel positions
    (column, row) in ``image`` of the nodes, ``node_pixels[v]`` (n_nodes, 2), and of each
    tendon's points, ``tendon_pixels[v][i]`` (p, 2)."""

    image: np.ndarray
    node_pixels: list[np.ndarray]
    tendon_pixels: list[list[np.ndarray]]


def draw_robot(robot: Robot, path: str | Path | None = None, size: tuple[int, int] = (400, 300),
               title: str | None = None) -> RobotPicture:
    """Three views of the rest mesh, tendons drawn on top (x-ray, one colour per motor, passive
    tendons grey, dashed) and payload nodes as black dots; a legend strip below. Writes a PNG
    when ``path`` is given."""
    w, h = size
    x = np.asarray(robot.mesh.points)
    motor_of = robot.tendon_motor
    n_rows = int(np.ceil((robot.n_motors + 2) / 4))
    strip = 30 + 16 * n_rows
    W, H = w * len(VIEWS), h + strip
    fig = Figure(figsize=(W / 100, H / 100), dpi=100, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    node_pixels, tendon_pixels = [], []
    for i, (name, elevation, azimuth) in enumerate(VIEWS):
        r = Renderer(robot.mesh.surface, width=w, height=h, body_length=robot.body_length,
                     elevation=elevation, azimuth=azimuth)
        img = r.render(x)
        target = r.camera_target(x)
        ax = fig.add_axes((i * w / W, strip / H, w / W, h / H))
        ax.set_axis_off()
        ax.imshow(img, extent=(0, w, h, 0), interpolation="nearest")
        ax.set_xlim(0, w)
        ax.set_ylim(h, 0)
        offset = np.array([i * w, 0.0])
        tendon_pixels.append([])
        for ti, t in enumerate(robot.tendons):
            pix, _ = r.project(np.asarray(t.points), target)
            tendon_pixels[-1].append(pix + offset)
            mi = motor_of[ti]
            colour = MOTOR_COLOURS[mi % len(MOTOR_COLOURS)] if mi >= 0 else "0.4"
            ax.plot(pix[:, 0], pix[:, 1], color=colour, lw=2.0, ls="-" if mi >= 0 else "--",
                    solid_capstyle="round", zorder=3)
        if len(robot.payload_nodes):
            pp, _ = r.project(x[robot.payload_nodes], target)
            ax.scatter(pp[:, 0], pp[:, 1], s=9, color=PAYLOAD_COLOUR, edgecolors="none", zorder=4)
        ax.text(6, 16, name, fontsize=9, color="0.1", zorder=5)
        pix, _ = r.project(x, target)
        node_pixels.append(pix + offset)
    handles = [Line2D([], [], color=MOTOR_COLOURS[i % len(MOTOR_COLOURS)], lw=2, label=m.name)
               for i, m in enumerate(robot.motors)]
    handles.append(Line2D([], [], color=PAYLOAD_COLOUR, marker="o", ls="", ms=4,
                          label=f"payload nodes ({len(robot.payload_nodes)})"))
    if (motor_of < 0).any():
        handles.append(Line2D([], [], color="0.4", lw=2, ls="--", label="passive tendon"))
    legend_ax = fig.add_axes((0, 0, 1, strip / H))
    legend_ax.set_axis_off()
    legend_ax.legend(handles=handles, loc="upper center", ncol=4, fontsize=8, frameon=False,
                     title=title or robot.summary(), title_fontsize=9)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    if path is not None:
        from PIL import Image

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
        Image.fromarray(image).save(tmp)
        tmp.replace(path)
    return RobotPicture(image, node_pixels, tendon_pixels)
