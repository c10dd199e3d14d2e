"""The co-design report: the old and the new robot side by side, and the
markdown report of speed before and after, every design change and the constraint checks.

:func:`plot_robots_side_by_side` draws the shipped and the co-designed robot in a 2x2 figure
(columns: the robots, each rest shape set on the ground; rows: the side view, forward to the
right and up, and the front view, lateral to the right and up), with the same axis limits in each
row: the rest mesh's boundary edges, every tendon as a polyline through its via points (the
fixed last point, where the tendon leaves the body to its motor, as a square; a motor's tendons,
the leader and its followers, in one colour), and, when a robot's moduli are not uniform, its
boundary faces coloured by their tet's Young's modulus over the fitted one (one colour bar for
both, logarithmic, 1 in the middle).

:func:`write_codesign_report` writes the markdown file atomically (:mod:`trajopt.results.files`).
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .checks import DesignCheck, boundary_triangles, format_checks
from ..results.files import atomic_write_bytes, atomic_write_png

__all__ = ["plot_robots_side_by_side", "write_codesign_report", "RESULT_ROWS"]

#: the rows of the speed table: (key of the before/after dicts, label, unit)
RESULT_ROWS = (("speed_bl_per_min", "speed", "BL/min"),
               ("slowest_bl_per_min", "credible speed: slowest over the physics steps", "BL/min"),
               ("spread", "spread (max - min) / slowest", ""), ("holds", "holds within 5 %", ""),
               ("n_cycle", "cycle steps", ""),
               ("n_keyframes", "keyframes", ""), ("upright", "upright", ""),
               ("total_sim_steps", "simulation steps", ""), ("wall_time_s", "wall time", "s"))
_ALIASES = {"cycle_steps": "n_cycle", "keyframes": "n_keyframes", "simulation_steps": "total_sim_steps",
            "sim_steps": "total_sim_steps", "wall_time": "wall_time_s", "speed": "speed_bl_per_min"}


def _robot(robot_or_path):
    if hasattr(robot_or_path, "mesh") and hasattr(robot_or_path, "tendons"):
        return robot_or_path
    from soft_envs.envs import load_robot
    folder = Path(robot_or_path)
    return load_robot(folder / "robot.toml" if folder.is_dir() else robot_or_path)


def _views(robot) -> dict[str, np.ndarray]:
    """Projection matrices (3, 2) of the side view (forward, up) and the front view (lateral, up)
    and the depth axis of each (away from the viewer)."""
    f, u = np.asarray(robot.forward_axis, float), np.asarray(robot.up_axis, float)
    lat = np.cross(f, u)
    return {"side view": (np.column_stack([f, u]), lat), "front view": (np.column_stack([lat, u]), -f)}


def plot_robots_side_by_side(old_robot, new_robot, path: str | os.PathLike,
                             titles: Sequence[str] = ("shipped", "co-designed"), *, dpi: int = 120,
                             speeds: tuple[float, float] | None = None) -> Path:
    """Draw ``old_robot`` and ``new_robot`` (Robots, names, robot.toml paths or folders) side by
    side at rest (module docstring) into the PNG ``path`` (written atomically); returns the path.
    ``speeds``: (baseline, new) [BL/min], stated in the title with their ratio (the gain)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import LogNorm

    robots = [_robot(old_robot), _robot(new_robot)]
    factors = [np.asarray(r.element_modulus_scale, float) for r in robots]
    graded = any(np.ptp(f) > 1e-12 for f in factors)
    lo, hi = min(f.min() for f in factors), max(f.max() for f in factors)
    span = max(hi, 1.0 / lo, 1.01)
    norm = LogNorm(vmin=1.0 / span, vmax=span)              # the fitted modulus (1) in the middle
    cmap = plt.get_cmap("coolwarm")
    motor_colours = plt.get_cmap("tab10")

    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), squeeze=False, layout="constrained")
    handles = {}
    views = list(_views(robots[0]))
    for row, view in enumerate(views):
        boxes = []
        for col, robot in enumerate(robots):
            P, depth_axis = _views(robot)[view]
            ax = axes[row, col]
            ground = float((np.asarray(robot.mesh.points, float) @ robot.up_axis).min())
            lift = -ground * np.asarray(robot.up_axis, float)     # set on the ground, as the rest relaxation starts
            pts = np.asarray(robot.mesh.points, float) + lift
            faces, owner = boundary_triangles(robot.mesh.tets)
            xy = pts @ P
            if graded:
                order = np.argsort(-(pts[faces].mean(axis=1) @ depth_axis))     # far faces first
                ax.add_collection(PolyCollection(xy[faces[order]], facecolors=cmap(norm(factors[col][owner[order]])),
                                                 edgecolors="none", alpha=0.55, zorder=1))
            edges = np.unique(np.sort(faces[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1), axis=0)
            ax.add_collection(LineCollection(xy[edges], colors="0.55", linewidths=0.4, zorder=2))
            motor = np.asarray(robot.tendon_motor)
            tendons = [np.asarray(t.points, float) + lift for t in robot.tendons]
            for t in sorted(range(len(tendons)), key=lambda t: -float(tendons[t].mean(axis=0) @ depth_axis)):
                q = tendons[t] @ P
                m = int(motor[t])
                colour = motor_colours(m % 10) if m >= 0 else "k"
                line, = ax.plot(q[:, 0], q[:, 1], "-", color=colour, lw=1.4, zorder=3)
                handles.setdefault(robot.motors[m].name if m >= 0 else "passive", line)
                ax.plot(q[:-1, 0], q[:-1, 1], "o", ms=4, mfc=colour, mec="k", mew=0.4, zorder=4)
                ax.plot(q[-1:, 0], q[-1:, 1], "s", ms=5, mfc="w", mec=colour, mew=1.2, zorder=4)
            boxes.append(np.vstack([xy] + [q @ P for q in tendons]))
            ax.set_title(f"{titles[col]} ({robot.name}): {view}", fontsize=10)
            ax.set_xlabel("forward [m]" if view == "side view" else "lateral [m]")
            ax.set_ylabel("up [m]")
        allp = np.vstack(boxes)
        lo_xy, hi_xy = allp.min(axis=0), allp.max(axis=0)
        pad = 0.06 * float(np.max(hi_xy - lo_xy))
        for ax in axes[row]:
            ax.set_xlim(lo_xy[0] - pad, hi_xy[0] + pad)
            ax.set_ylim(lo_xy[1] - pad, hi_xy[1] + pad)
            ax.set_aspect("equal")
            ax.grid(alpha=0.2)
    if graded:
        sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
        bar = fig.colorbar(sm, ax=axes.ravel().tolist(), shrink=0.8, label="Young's modulus / fitted modulus")
        ticks = sorted({1.0 / span, 1.0, span} | {t for t in (0.3, 0.5, 2.0, 3.0) if 1.0 / span < t < span})
        bar.set_ticks(ticks, labels=[f"{t:.3g}" for t in ticks])
        bar.ax.minorticks_off()
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncol=min(len(handles), 8),
                   fontsize=8, title="tendons by motor", title_fontsize=8)
    what = "rest shapes, tendons (circles: via points, squares: where they leave to the motor)"
    if speeds is not None:
        before, after = (float(v) for v in speeds)
        ratio = f"x {after / before:.2f}" if before > 0 else "the baseline does not move"
        what = (f"speed {before:.2f} -> {after:.2f} BL/min ({ratio}): {titles[0]} vs {titles[1]}, the gait "
                f"optimised on each\n{what}")
    fig.suptitle(what, fontsize=10)
    return atomic_write_png(fig, path, dpi=dpi)


def _value(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return f"{int(v):,}"
    if isinstance(v, (float, np.floating)):
        return "-" if not math.isfinite(v) else f"{float(v):.6g}"
    return str(v).replace("|", "/")


def _normalised(d: dict | None) -> dict:
    return {} if d is None else {_ALIASES.get(k, k): v for k, v in d.items()}


def _speed(d: dict, what: str) -> float:
    if "speed_bl_per_min" not in d:
        raise ValueError(f"write_codesign_report: {what} has no speed_bl_per_min (keys: {sorted(d)})")
    return float(d["speed_bl_per_min"])


def write_codesign_report(path: str | os.PathLike, *, robot_name: str, before: dict, after: dict,
                          reoptimised: dict | None, changes: list[dict], checks: list[DesignCheck] | str,
                          picture: str | os.PathLike, settings: dict) -> str:
    """Write the co-design report of ``robot_name`` as markdown to ``path`` (atomically) and
    return its text.

    ``before`` / ``after`` / ``reoptimised``: the fastest gait of the shipped design, the
    co-designed gait, and the gait optimised from scratch on the written robot (None: not run),
    each a dict with ``speed_bl_per_min`` and optionally the other keys of :data:`RESULT_ROWS`
    (any further keys are listed too); ``changes``: dicts ``name``, ``before``, ``after``,
    ``unit``; ``checks``: :func:`~trajopt.codesign.checks.check_designed_robot`'s list (or its
    table); ``picture``: the PNG of :func:`plot_robots_side_by_side` (linked relative to the
    report); ``settings``: the run's settings."""
    path = Path(path)
    cols = [("shipped design", _normalised(before)), ("co-designed", _normalised(after))]
    if reoptimised is not None:
        cols.append(("co-designed, gait re-optimised from scratch", _normalised(reoptimised)))
    v0 = _speed(cols[0][1], "before")
    speeds = [_speed(d, name) for name, d in cols]
    lines = [f"# Co-design of the {robot_name}", ""]
    ratio = speeds[1] / v0 if v0 > 0 else float("nan")
    if all("slowest_bl_per_min" in d for _, d in cols):      # the credible speeds first
        slow = [float(d["slowest_bl_per_min"]) for _, d in cols]
        names = ["co-designed", "re-optimised from the written files"]
        for name, v in zip(names, slow[1:]):
            lines.append(f"**Credible speed ratio, {name} / shipped: {v / slow[0] if slow[0] > 0 else float('nan'):.3f}x** "
                         f"({v:.3f} / {slow[0]:.3f} BL/min, the slowest over the physics steps replayed)\n")
        lines.append("At the own physics:\n")
    lines.append(f"**Speed ratio co-designed / shipped: {ratio:.3f}x** ({speeds[1]:.3f} / {v0:.3f} BL/min)")
    if reoptimised is not None:
        lines.append(f"\n**Re-optimised from the written files / shipped: {speeds[2] / v0 if v0 > 0 else float('nan'):.3f}x** "
                     f"({speeds[2]:.3f} / {v0:.3f} BL/min)")
    lines += ["", "## Speed", "", "| | " + " | ".join(n for n, _ in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    known = [k for k, _, _ in RESULT_ROWS]
    extra = [k for _, d in cols for k in d if k not in known]
    for key, label, unit in [*RESULT_ROWS, *((k, k, "") for k in dict.fromkeys(extra))]:
        if any(key in d for _, d in cols):
            name = f"{label} [{unit}]" if unit else label
            lines.append(f"| {name} | " + " | ".join(_value(d.get(key)) for _, d in cols) + " |")
    ratio_row = ["1", f"{ratio:.3f}"] + ([f"{speeds[2] / v0:.3f}" if v0 > 0 else "-"] if reoptimised is not None else [])
    lines.append("| speed / shipped | " + " | ".join(ratio_row) + " |")

    lines += ["", f"## Design changes ({len(changes)})", ""]
    if changes:
        lines += ["| parameter | before | after | change | unit |", "|---|---|---|---|---|"]
        for c in changes:
            b, a = c.get("before"), c.get("after")
            delta = a - b if isinstance(a, (int, float)) and isinstance(b, (int, float)) else None
            lines.append(f"| {_value(c['name'])} | {_value(b)} | {_value(a)} | {_value(delta)} | {_value(c.get('unit', ''))} |")
    else:
        lines.append("No design parameter changed.")

    table = checks if isinstance(checks, str) else format_checks(list(checks))
    failed = [] if isinstance(checks, str) else [c.name for c in checks if not c.passed]
    verdict = "every constraint holds in the written files" if not failed else f"FAILED: {', '.join(failed)}"
    lines += ["", "## Constraint checks (from the written files)", "", verdict, "", table.rstrip("\n")]

    pic = Path(picture)
    try:
        link = os.path.relpath(pic.resolve(), path.resolve().parent)
    except ValueError:          # another drive (Windows)
        link = str(pic)
    lines += ["", "## The robots", "", f"![shipped and co-designed robot]({Path(link).as_posix()})"]

    lines += ["", "## Settings", "", "| setting | value |", "|---|---|"]
    lines += [f"| {k} | {_value(v)} |" for k, v in settings.items()]
    text = "\n".join(lines) + "\n"
    atomic_write_bytes(path, text.encode("utf-8"))
    return text
