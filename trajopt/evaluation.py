"""Evaluating a gait: play prep + N cycles and measure speed in body lengths per minute.

The paper's unit (Table I). The speed is the mean velocity of the centre of mass along the
target direction over the repeated cycles (from the end of the prep phase to the end of the
last cycle); per-cycle speeds show whether the gait is periodic. "Upright" means the body's
up axis never tilts more than ``max_tilt_deg`` from vertical and the COM never drops below
half of its rest height.
"""
from __future__ import annotations

import numpy as np

from soft_envs.sim import SimulationError
from soft_envs.sim.kinematics import BodyFrame, tilt_deg_of, yaw_of

__all__ = ["evaluate_controls", "zero_slack_controls", "mps_to_bl_per_min"]


def mps_to_bl_per_min(v: float, body_length: float) -> float:
    return float(v) * 60.0 / float(body_length)


def zero_slack_controls(u: np.ndarray, gamma: np.ndarray, tendon_motor: np.ndarray,
                        u_bounds: np.ndarray) -> np.ndarray:
    """Paper III-B-2: ``u_post = u + s`` with ``s = |min(Gamma, 0)|``.

    ``gamma`` (K+1, T) are the cable deformations of the rollout of ``u`` (state k+1 follows
    control k). A motor drives a tendon pair: it reels in the smaller slack of its tendons, so
    no tendon is tightened beyond taut. The result is clipped to the motor bounds."""
    slack = np.abs(np.minimum(gamma[1:], 0.0))                       # (K, T)
    s = np.zeros_like(u)
    for m in range(u.shape[1]):
        cols = np.flatnonzero(tendon_motor == m)
        if cols.size:
            s[:, m] = slack[:, cols].min(axis=1)
    return np.clip(u + s, u_bounds[:, 0], u_bounds[:, 1])


def evaluate_controls(hooks, u: np.ndarray, *, n_prep: int, n_cycle: int, heading_deg_target: float = 0.0,
                      max_tilt_deg: float = 60.0) -> dict:
    """Play ``u`` (prep + N cycles) from the reset state and measure it."""
    robot = hooks.robot
    dt = hooks.dt
    K = len(u)
    n_cycles = (K - n_prep) // n_cycle if n_cycle > 0 else 0
    if n_cycles < 1:
        raise ValueError(f"need at least one full cycle to evaluate: {K} steps, prep {n_prep}, cycle {n_cycle}")
    try:
        traj = hooks.rollout(u)
    except SimulationError as err:
        return {"cycles": n_cycles, "speed_bl_per_min": float("nan"), "upright": False,
                "sim_failure": str(err)}
    a = np.radians(heading_deg_target)
    direction = np.array([np.cos(a), 0.0, np.sin(a)])
    bl = robot.body_length
    marks = n_prep + n_cycle * np.arange(n_cycles + 1)
    com = traj.com
    per_cycle = [mps_to_bl_per_min((com[marks[i + 1]] - com[marks[i]]) @ direction / (n_cycle * dt), bl)
                 for i in range(n_cycles)]
    mean = mps_to_bl_per_min((com[marks[-1]] - com[marks[0]]) @ direction / (n_cycles * n_cycle * dt), bl)
    frame = BodyFrame(traj.x[0], robot.node_masses)
    rots = [frame.rotation(x) for x in traj.x]
    tilt = np.array([tilt_deg_of(R) for R in rots])
    head = np.unwrap([yaw_of(R) for R in rots])
    com_h = com[:, 1]
    upright = bool(tilt.max() <= max_tilt_deg and com_h.min() >= 0.5 * com_h[0])
    path = np.linalg.norm(np.diff(com[marks[0]:, [0, 2]], axis=0), axis=1).sum()
    return {
        "cycles": int(n_cycles),
        "speed_bl_per_min": float(mean),
        "speed_per_cycle_bl_per_min": [float(v) for v in per_cycle],
        "path_speed_bl_per_min": mps_to_bl_per_min(path / (n_cycles * n_cycle * dt), bl),
        "heading_change_deg": float(np.degrees(head[-1] - head[0])),
        "max_tilt_deg": float(tilt.max()),
        "upright": upright,
        "sim_steps": int(K),
        "com": traj.com.tolist(),
    }
