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

__all__ = ["plot_com_topdown", "plot_controls", "plot_convergence", "plot_speed_per_cycle",
           "plot_speed_vs_steps"]


def _save(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise ValueError(f"{path}: plots are written as .png, .svg or .pdf")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    return path


def plot_com_topdown(com: np.ndarray, target: np.ndarray | None, path: str | Path, *,
                     body_outline: np.ndarray | None = None, prep_steps: int | None = None) -> Path:
    """Top-down view of the centre-of-mass path against its target (paper Fig. 3): x to the
    right, z downwards (a robot facing +x with +y up has its right side at +z). The prep phase
    is grey; ``body_outline`` (rest node positions) is drawn in yellow at the start."""
    com = np.asarray(com, dtype=np.float64)
    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    if body_outline is not None:
        pts = np.asarray(body_outline)
        ax.scatter(100 * pts[:, 0], 100 * pts[:, 2], s=4, color="gold", label="robot at start")
    if target is not None and len(target):
        t = np.asarray(target)
        ax.plot(100 * t[:, 0], 100 * t[:, 1], "--", color="0.3", label="target")
    k = int(prep_steps or 0)
    if k > 0:
        ax.plot(100 * com[:k + 1, 0], 100 * com[:k + 1, 2], color="0.6", lw=2, label="prep phase")
    ax.plot(100 * com[k:, 0], 100 * com[k:, 2], color="tab:blue", lw=2, label="simulated COM")
    ax.set_xlabel("x [cm]")
    ax.set_ylabel("z [cm]")
    ax.invert_yaxis()
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("centre of mass, top view")
    return _save(fig, path)


def plot_controls(u: np.ndarray, dt: float, motor_names: Sequence[str], path: str | Path, *,
                  n_prep: int | None = None, n_cycle: int | None = None,
                  u_post: np.ndarray | None = None) -> Path:
    """Contraction of every motor over time (paper Fig. 5), phase boundaries dashed; the
    zero-slack controls ``u_post`` as thin dotted lines."""
    u = np.atleast_2d(np.asarray(u, dtype=np.float64))
    if u.shape[1] != len(motor_names):
        raise ValueError(f"u has {u.shape[1]} columns but {len(motor_names)} motor names")
    t = np.arange(len(u)) * dt
    fig = Figure(figsize=(7, 3.5))
    ax = fig.add_subplot()
    colors = [f"C{i % 10}" for i in range(u.shape[1])]
    for m, name in enumerate(motor_names):
        ax.plot(t, 1000 * u[:, m], color=colors[m], label=name)
        if u_post is not None:
            ax.plot(t, 1000 * np.asarray(u_post)[:, m], ":", color=colors[m], lw=1)
    start = n_prep or 0
    if start:
        ax.axvline(start * dt, color="k", ls="--", lw=0.8)
    if n_cycle:
        for c in range(1, (len(u) - start) // n_cycle):
            ax.axvline((start + c * n_cycle) * dt, color="k", ls="--", lw=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("contraction u [mm]")
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    ax.set_title("controls: prep | cycle | cycle")
    return _save(fig, path)


def plot_convergence(history: Sequence[Mapping], path: str | Path) -> Path:
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
    ax.set_title("convergence")
    return _save(fig, path)


def plot_speed_per_cycle(speeds: np.ndarray, path: str | Path, *, reference: float | None = None) -> Path:
    """Speed of every repeated cycle [BL/min]; ``reference`` (e.g. the paper's) as a line."""
    s = np.asarray(speeds, dtype=np.float64)
    fig = Figure(figsize=(5, 3.5))
    ax = fig.add_subplot()
    ax.bar(np.arange(1, len(s) + 1), s, color="tab:green")
    if reference is not None:
        ax.axhline(reference, color="k", ls="--", label=f"paper: {reference:g} BL/min")
        ax.legend(loc="lower right", fontsize=8)
    ax.set_xlabel("cycle")
    ax.set_ylabel("speed [body lengths / min]")
    ax.set_title("speed over repeated cycles")
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
