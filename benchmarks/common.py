"""Shared helpers for the benchmark scripts: a gait-like control and robust timing."""
from __future__ import annotations

import json
import time

import numpy as np


def gait_controls(robot, K: int = 168, dt: float = 0.033, period_steps: int = 72) -> np.ndarray:
    """A smooth periodic control: each motor a raised cosine of amplitude u_max/2 with a phase
    offset, so legs take turns (like an optimised gait, not a constant)."""
    t = np.arange(K) * dt
    u = np.zeros((K, robot.n_motors))
    for m in range(robot.n_motors):
        phase = 2 * np.pi * m / max(robot.n_motors, 1)
        u[:, m] = robot.u_bounds[m, 1] * 0.5 * (1 - np.cos(2 * np.pi * t / (period_steps * dt) + phase))
    return u


def random_controls(robot, K: int, seed: int = 0, rate: float = 0.15) -> np.ndarray:
    """Random targets within the motor ranges, approached at ``rate`` times the range per step
    (a speed limit, like the environments' motors)."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.u_bounds[:, 0], robot.u_bounds[:, 1]
    u = [lo.copy()]
    for _ in range(K - 1):
        u.append(u[-1] + np.clip(rng.uniform(lo, hi) - u[-1], -rate * (hi - lo), rate * (hi - lo)))
    return np.array(u)


def best_of(f, repeat: int = 5, number: int = 1) -> float:
    """Minimum over ``repeat`` runs of the mean time of ``number`` calls (seconds)."""
    f()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            f()
        times.append((time.perf_counter() - t0) / number)
    return min(times)


def report(title: str, rows: list[dict]) -> None:
    """Print rows as an aligned text table followed by the same data as JSON."""
    print(f"\n== {title} ==")
    if rows:
        keys = list(rows[0])
        width = {k: max(len(k), *(len(_fmt(r[k])) for r in rows)) for k in keys}
        print("  ".join(k.ljust(width[k]) for k in keys))
        for r in rows:
            print("  ".join(_fmt(r[k]).ljust(width[k]) for k in keys))
    print(json.dumps({"benchmark": title, "rows": rows}, default=float))


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)
