"""The paper's plots of a gait, with matplotlib (PNG or SVG by the file suffix).

Each function takes arrays and an output path, writes the figure, closes it and returns the
path. The figures use :class:`matplotlib.figure.Figure` directly (no pyplot state), so they
work headless and in parallel.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

__all__ = ["plot_com_topdown", "plot_controls", "plot_convergence", "plot_speed_per_cycle",
           "plot_speed_vs_steps", "plot_motor_line", "motor_line_figure", "controls_figure", "motor_groups"]


def _title(what: str, subject: str | None) -> str:
    """A plot's title: what it shows, and on a second line ``subject`` (robot, task, result file)."""
    return what if not subject else f"{what}\n{subject}"


def _save(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise ValueError(f"{path}: plots are written as .png, .svg or .pdf")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    return path


def plot_com_topdown(com: np.ndarray, target: np.ndarray | None, path: str | Path, *,
                     body_outline: np.ndarray | None = None, prep_steps: int | None = None,
                     subject: str | None = None) -> Path:
    """Top-down view of the centre-of-mass path against its target (paper Fig. 3): x to the
    right, z downwards (a robot facing +x with +y up has its right side at +z), an arrow at the
    start pointing forward. The prep phase is grey; ``body_outline`` (rest node positions) is
    drawn in yellow at the start; the target is drawn over the path, so it stays visible where
    the two coincide. ``subject`` (robot, task, result file) goes in the title."""
    com = np.asarray(com, dtype=np.float64)
    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    if body_outline is not None:
        pts = np.asarray(body_outline)
        ax.scatter(100 * pts[:, 0], 100 * pts[:, 2], s=4, color="gold", label="robot at start")
    if target is not None and len(target):
        t = np.asarray(target)
        ax.plot(100 * t[:, 0], 100 * t[:, 1], "--", color="0.3", lw=1.2, zorder=4,
                label="target COM path (tracked, not enforced)")
    k = int(prep_steps or 0)
    if k > 0:
        ax.plot(100 * com[:k + 1, 0], 100 * com[:k + 1, 2], color="0.6", lw=2, label="prep phase")
    ax.plot(100 * com[k:, 0], 100 * com[k:, 2], color="tab:blue", lw=3, alpha=0.6, label="simulated COM")
    if len(com):   # a result saved without its COM path (e.g. an unfinished run) still plots
        span = max(float(np.ptp(100 * com[:, 0])), float(np.ptp(100 * com[:, 2])), 1.0)
        ax.annotate("forward (+x)", xy=(100 * com[0, 0] + 0.25 * span, 100 * com[0, 2]),
                    xytext=(100 * com[0, 0], 100 * com[0, 2]), fontsize=7, color="0.5", va="bottom",
                    arrowprops=dict(arrowstyle="->", color="0.5"))
    ax.set_xlabel("x [cm]")
    ax.set_ylabel("z [cm]")
    ax.invert_yaxis()
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, borderaxespad=0.0)   # off the path
    ax.set_title(_title("centre of mass, top view", subject), fontsize=10)
    return _save(fig, path)


#: what the dotted lines of :func:`plot_controls` are (paper III-B-2)
U_POST_LABEL = ("u_post: zero-slack controls (paper III-B-2), u plus each cable's slack: the same motion, "
                "what the hardware plays")
U_LABEL = "u: optimised contraction"


def motor_groups(n_motors: int, mirror_map: Sequence[int] | None) -> list[list[int]]:
    """Motors per panel of :func:`plot_controls`: each motor with its mirror motor (bilateral
    symmetry), in motor order; all in one panel when no motor has a mirror."""
    if mirror_map is None:
        return [list(range(n_motors))]
    mm = [int(v) for v in mirror_map]
    if len(mm) != n_motors or any(not 0 <= v < n_motors or mm[v] != m for m, v in enumerate(mm)):
        raise ValueError(f"mirror_map {mm} must pair {n_motors} motors (each one's mirror's mirror is itself)")
    if mm == list(range(n_motors)):                     # no pairs
        return [list(range(n_motors))]
    return [[m] + ([mm[m]] if mm[m] != m else []) for m in range(n_motors) if mm[m] >= m]


def plot_controls(u: np.ndarray, dt: float, motor_names: Sequence[str], path: str | Path, *,
                  n_prep: int | None = None, n_cycle: int | None = None,
                  u_post: np.ndarray | None = None, mirror_map: Sequence[int] | None = None,
                  subject: str | None = None) -> Path:
    """:func:`controls_figure` written to ``path``."""
    return _save(controls_figure(u, dt, motor_names, n_prep=n_prep, n_cycle=n_cycle, u_post=u_post,
                                 mirror_map=mirror_map, subject=subject), path)


def controls_figure(u: np.ndarray, dt: float, motor_names: Sequence[str], *, n_prep: int | None = None,
                    n_cycle: int | None = None, u_post: np.ndarray | None = None,
                    mirror_map: Sequence[int] | None = None, subject: str | None = None) -> Figure:
    """Contraction of every motor over time (paper Fig. 5), one colour per motor; phases
    (prep, cycle 1, cycle 2, ...) between dashed lines and named on top; the zero-slack controls
    ``u_post`` (paper III-B-2) as thin dotted lines, visible where a cable would be slack.

    With ``mirror_map`` (``Robot.mirror_map``) each mirror pair gets its own panel, its second
    motor dashed, so that motors playing the same signal do not hide each other. Legends are
    outside the axes: the motors right of each panel, the line styles below."""
    u = np.atleast_2d(np.asarray(u, dtype=np.float64))
    if u.shape[1] != len(motor_names):
        raise ValueError(f"u has {u.shape[1]} columns but {len(motor_names)} motor names")
    if u_post is not None and np.shape(u_post) != u.shape:
        raise ValueError(f"u_post has shape {np.shape(u_post)} but u has {u.shape}")
    groups = motor_groups(u.shape[1], mirror_map)
    paired = mirror_map is not None and [int(v) for v in mirror_map] != list(range(u.shape[1]))   # pair panels
    t = np.arange(len(u)) * dt
    fig = Figure(figsize=(8, 3.0 if len(groups) == 1 else 1.0 + 1.35 * len(groups)), layout="constrained")
    axes = fig.subplots(len(groups), 1, sharex=True, sharey=True, squeeze=False)[:, 0]
    start = n_prep or 0
    bounds = [0] + ([start] if start else [])
    if n_cycle:
        bounds += list(range(start + n_cycle, len(u), n_cycle))
    for ax, group in zip(axes, groups):
        for j, m in enumerate(group):
            style = "--" if paired and j == 1 else "-"
            ax.plot(t, 1000 * u[:, m], style, color=f"C{m % 10}", label=motor_names[m])
            if u_post is not None:
                ax.plot(t, 1000 * np.asarray(u_post)[:, m], ":", color=f"C{m % 10}", lw=1)
        for b in bounds[1:]:
            ax.axvline(b * dt, color="k", ls="--", lw=0.8)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)
        ax.grid(alpha=0.3)
    edges = bounds + [len(u)]
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:]) if (start or n_cycle) else []):
        name = "prep" if (start and i == 0) else (f"cycle {i + (0 if start else 1)}" if n_cycle else "gait")
        axes[0].text(0.5 * (a + b) * dt, 1.02, name, transform=axes[0].get_xaxis_transform(), ha="center",
                     va="bottom", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    if len(groups) == 1:
        axes[0].set_ylabel("contraction u [mm]")
    else:
        fig.supylabel("contraction u [mm]", fontsize=10)
    styles = [Line2D([], [], color="0.3", label=U_LABEL)]
    if paired:
        styles.append(Line2D([], [], color="0.3", ls="--", label="mirror motor (dashed)"))
    if u_post is not None:
        styles.append(Line2D([], [], color="0.3", ls=":", lw=1, label=U_POST_LABEL))
    fig.legend(handles=styles, loc="outside lower center", fontsize=7, ncol=1 if u_post is not None else 2,
               frameon=False)
    fig.suptitle(_title("controls", subject), fontsize=11)
    return fig


def plot_convergence(history: Sequence[Mapping], path: str | Path, *, subject: str | None = None) -> Path:
    """Objective per Gauss-Newton iteration (log scale) and the accepted step size."""
    if not history:
        raise ValueError("history is empty: nothing to plot")
    it = [h["iteration"] for h in history]
    obj = [h.get("objective_after", h["objective"]) for h in history]
    fig = Figure(figsize=(5, 3.5))
    ax = fig.add_subplot()
    ax.semilogy([it[0] - 1] + it, [history[0]["objective"]] + obj, "o-", color="tab:blue")
    ax.set_xlabel("Gauss-Newton iteration")
    ax.set_ylabel("objective", color="tab:blue")
    if any("step" in h for h in history):
        ax2 = ax.twinx()
        ax2.bar(it, [h.get("step", 0.0) * 1000 for h in history], alpha=0.3, color="tab:orange")
        ax2.set_ylabel("step |dz| [mm]", color="tab:orange")
    ax.set_title(_title("convergence", subject), fontsize=10)
    return _save(fig, path)


def plot_speed_per_cycle(speeds: np.ndarray, path: str | Path, *, reference: float | None = None,
                         target: float | None = None, subject: str | None = None) -> Path:
    """Speed of every repeated cycle [BL/min]; the ``target`` speed (of the target COM path the
    optimiser tracked: not a speed it enforced) and a ``reference`` (e.g. the paper's) as lines."""
    s = np.asarray(speeds, dtype=np.float64)
    fig = Figure(figsize=(5, 3.5))
    ax = fig.add_subplot()
    ax.bar(np.arange(1, len(s) + 1), s, color="tab:green")
    if target is not None:
        ax.axhline(target, color="tab:red", ls="-", lw=1.2,
                   label=f"tracking target: {target:g} BL/min (the target COM path's speed; not enforced)")
    if reference is not None:
        ax.axhline(reference, color="k", ls="--", label=f"paper: {reference:g} BL/min")
    if target is not None or reference is not None:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), fontsize=8, frameon=False)   # off the bars
    ax.set_xlabel("cycle")
    ax.set_ylabel("speed [body lengths / min]")
    ax.set_title(_title("speed over repeated cycles", subject), fontsize=10)
    return _save(fig, path)


def plot_turn(t: np.ndarray, heading_deg: np.ndarray, path_speeds: Sequence[float], path: str | Path, *,
              prep_time: float = 0.0, subject: str | None = None) -> Path:
    """A turn: its heading [deg, from the start; + turns right] at every step over time [s], and
    its speed along the COM path [BL/min] in every cycle (the chord from cycle to cycle, which
    leaves out the sway within a stride), where a walk plots its speed along +x."""
    fig = Figure(figsize=(5, 5))
    top, bottom = fig.subplots(2, 1)
    top.plot(np.asarray(t), np.asarray(heading_deg), color="tab:purple")
    if prep_time > 0:
        top.axvspan(0.0, prep_time, color="0.9", label="prep phase")
        top.legend(loc="best", fontsize=8)
    top.set_xlabel("time [s]")
    top.set_ylabel("heading change [deg]")
    s = np.asarray(path_speeds, dtype=np.float64)
    bottom.bar(np.arange(1, len(s) + 1), s, color="tab:green")
    bottom.set_xlabel("cycle")
    bottom.set_ylabel("speed along the path\n[body lengths / min]")
    top.set_title(_title("turn: heading over time and speed along the COM path", subject), fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def plot_speed_vs_steps(curves: Mapping[str, tuple[np.ndarray, np.ndarray]], path: str | Path) -> Path:
    """Speed [BL/min] against simulation steps spent, one curve per method (log x axis)."""
    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    for name, (steps, speed) in curves.items():
        ax.plot(np.asarray(steps), np.asarray(speed), "o-", label=name)
    ax.set_xscale("log")
    ax.set_xlabel("simulation steps")
    ax.set_ylabel("speed [body lengths / min]")
    ax.legend(loc="best")
    ax.set_title("speed vs simulation budget")
    return _save(fig, path)


def plot_motor_line(speed: np.ndarray, torque_before: np.ndarray, torque_after: np.ndarray, no_load_speed: np.ndarray,
                    stall_torque: np.ndarray, max_torque: np.ndarray, motor_names: Sequence[str], path: str | Path, *,
                    subject: str | None = None) -> Path:
    """:func:`motor_line_figure` written to ``path``."""
    return _save(motor_line_figure(speed, torque_before, torque_after, no_load_speed, stall_torque, max_torque,
                                   motor_names, subject=subject), path)


def motor_line_figure(speed: np.ndarray, torque_before: np.ndarray, torque_after: np.ndarray,
                      no_load_speed: np.ndarray, stall_torque: np.ndarray, max_torque: np.ndarray,
                      motor_names: Sequence[str], *, subject: str | None = None) -> Figure:
    """Each motor's torque-speed line (:mod:`soft_envs.sim.motors`) and a gait's steps under it, one
    panel per motor: load torque [N m] across, winding speed [mm/s] up; the line from the
    no-load speed ``v_0`` at zero torque to zero at the stall torque, the gearbox's ``max_torque``
    dashed. Every winding step of the gait (``speed`` (S, M) [m/s] > 0) is a point at the larger
    of its torques before and after the step (``torque_before``, ``torque_after`` (S, M) [N m]):
    a point beyond the line (by more than the optimiser's 1 % tolerance: orange) is a step the
    motor cannot make."""
    speed, tb, ta = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (speed, torque_before, torque_after))
    M = speed.shape[1]
    if tb.shape != speed.shape or ta.shape != speed.shape or len(motor_names) != M:
        raise ValueError(f"speed {speed.shape}, torques {tb.shape} / {ta.shape} and {len(motor_names)} motor names "
                         "must agree")
    cols = min(M, 4)
    rows = -(-M // cols)
    fig = Figure(figsize=(2.6 * cols + 0.6, 2.4 * rows + 0.8), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False, sharex=True, sharey=True).ravel()
    for m in range(M):
        ax = axes[m]
        v0, st, mx = float(no_load_speed[m]), float(stall_torque[m]), float(max_torque[m])
        ax.plot([0.0, st], [1e3 * v0, 0.0], color="k", lw=1.5, label="torque-speed line")
        ax.axvline(mx, color="tab:red", ls="--", lw=1, label="max_torque (gearbox)")
        winding = speed[:, m] > 0
        tau = np.maximum(tb[:, m], ta[:, m])[winding]
        v = 1e3 * speed[winding, m]
        above = v / (1e3 * v0) + tau / st - 1 > 0.01
        ax.scatter(tau[~above], v[~above], s=8, color="tab:blue", label="winding step (under the line, to 1 %)")
        if above.any():
            ax.scatter(tau[above], v[above], s=10, color="tab:orange", label="winding step beyond the line")
        ax.set_title(motor_names[m], fontsize=9)
        ax.grid(alpha=0.3)
        ax.set_xlim(0.0, 1.05 * max(st, mx))
        ax.set_ylim(0.0, 1.1e3 * v0)
    for ax in axes[M:]:
        ax.set_visible(False)
    fig.supxlabel("load torque [N m] (the larger of before and after the step)", fontsize=9)
    fig.supylabel("winding speed [mm/s]", fontsize=9)
    axes[0].legend(loc="upper right", fontsize=6)          # above the line: where no step should be
    fig.suptitle(_title("motors: torque-speed line and the gait's steps", subject), fontsize=10)
    return fig
