"""Evaluating a gait: play prep + N cycles and measure speed in body lengths per minute.

The paper's unit (Table I). :func:`measure_gait` measures a finished trajectory (of
:meth:`~soft_envs.envs.GradientEnv.rollout`, or states recorded while stepping an environment);
:func:`evaluate_controls` plays controls and measures them; :func:`evaluate_result` does that for
a saved :class:`~trajopt.results.Result`. The speed is the mean velocity of the centre of mass
along the target direction over the repeated cycles (from the end of the prep phase to the end
of the last cycle); per-cycle speeds show whether the gait is periodic. "Upright" means the
body's up axis never tilts more than ``max_tilt_deg`` from vertical and the COM never drops
below half of its rest height.

The heading is the yaw of the best-fit rotation of all nodes from the rest shape
(:class:`~soft_envs.envs.BodyFrame`), not the direction of the COM path: a gait that walks
sideways along a curve does not turn. It is reported over the whole rollout and per cycle, and,
given the optimisation's ``target`` path (K+1, 2), over that horizon (prep + the optimised
cycles) together with the RMS distance of the COM from the target (turns: the quarter circle).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from soft_envs.envs import BodyFrame, GradientEnv, SimulationError, heading_vector, tilt_deg_of, yaw_of

from .optim.gait import DEFAULT_EVAL_CYCLES

__all__ = ["measure_gait", "evaluate_controls", "evaluate_result", "zero_slack_controls", "mps_to_bl_per_min",
           "DEFAULT_EVAL_CYCLES"]


def mps_to_bl_per_min(v: float, body_length: float) -> float:
    return float(v) * 60.0 / float(body_length)


def zero_slack_controls(u: np.ndarray, gamma: np.ndarray, tendon_motor: np.ndarray,
                        u_bounds: np.ndarray) -> np.ndarray:
    """Paper III-B-2: ``u_post = u + s`` with ``s = |min(Gamma, 0)|``.

    ``gamma`` (K+1, T) are the cable deformations of the rollout of ``u`` (state k+1 follows
    control k); ``tendon_motor`` (T,) is ``robot.tendon_motor``, the motor of each tendon. A motor
    drives a tendon pair: it reels in the smaller slack of its tendons, so no tendon is tightened
    beyond taut. The result is clipped to the motor bounds."""
    slack = np.abs(np.minimum(gamma[1:], 0.0))                       # (K, T)
    s = np.zeros_like(u)
    for m in range(u.shape[1]):
        cols = np.flatnonzero(tendon_motor == m)
        if cols.size:
            s[:, m] = slack[:, cols].min(axis=1)
    return np.clip(u + s, u_bounds[:, 0], u_bounds[:, 1])


def _count_cycles(n_steps: int, n_prep: int, n_cycle: int) -> int:
    n_cycles = (n_steps - n_prep) // n_cycle if n_cycle > 0 else 0
    if n_cycles < 1:
        raise ValueError(f"need at least one full cycle to evaluate: {n_steps} steps, prep {n_prep}, "
                         f"cycle {n_cycle}")
    return n_cycles


def _horizon(com: np.ndarray, head: np.ndarray, target: np.ndarray, body_length: float) -> dict[str, Any]:
    """Heading change and RMS distance [BL] of the COM from ``target`` over states 1..K_t."""
    target = np.asarray(target, dtype=np.float64)
    k = len(target) - 1
    if target.ndim != 2 or target.shape[1] != 2 or not 1 <= k <= len(com) - 1:
        raise ValueError(f"target must be a (K+1, 2) path with 1 <= K <= {len(com) - 1}, got {target.shape}")
    dist = np.linalg.norm(com[1:k + 1][:, [0, 2]] - target[1:], axis=1)
    return {"horizon_steps": int(k), "horizon_heading_change_deg": float(np.degrees(head[k] - head[0])),
            "horizon_rms_to_target_bl": float(np.sqrt(np.mean(dist ** 2)) / body_length)}


def measure_gait(traj: Any, env: GradientEnv, *, n_prep: int, n_cycle: int, heading_deg: float = 0.0,
                 max_tilt_deg: float = 60.0, target: np.ndarray | None = None) -> dict[str, Any]:
    """Speed, per-cycle speeds, path speeds (of every step, and of the COM sampled once per cycle,
    which leaves out the sway within a stride: a turn's speed along its circle), heading change
    (whole and per cycle), tilt and
    uprightness of a finished trajectory ``traj`` (anything with ``x`` (K+1, n, 3) and ``com``
    (K+1, 3) of simulation steps of ``env.timestep`` seconds, state 0 the start) of
    ``env.robot``: prep ``n_prep`` steps, then cycles of ``n_cycle`` steps, measured along
    ``heading_deg``. With ``target`` (K_t+1, 2), K_t <= K, the optimised horizon's figures too:
    ``horizon_heading_change_deg`` and ``horizon_rms_to_target_bl``."""
    robot, dt = env.robot, env.timestep
    K = len(traj.x) - 1
    n_cycles = _count_cycles(K, n_prep, n_cycle)
    direction = heading_vector(heading_deg)
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
    chords = np.linalg.norm(np.diff(com[marks][:, [0, 2]], axis=0), axis=1).sum()
    return {
        "cycles": int(n_cycles),
        "speed_bl_per_min": float(mean),
        "speed_per_cycle_bl_per_min": [float(v) for v in per_cycle],
        "path_speed_bl_per_min": mps_to_bl_per_min(path / (n_cycles * n_cycle * dt), bl),
        "cycle_path_speed_bl_per_min": mps_to_bl_per_min(chords / (n_cycles * n_cycle * dt), bl),
        "heading_change_deg": float(np.degrees(head[-1] - head[0])),
        "heading_per_cycle_deg": [float(v) for v in np.degrees(np.diff(head[marks]))],
        "max_tilt_deg": float(tilt.max()),
        "upright": upright,
        "sim_steps": int(K),
        "com": np.asarray(com).tolist(),
    } | ({} if target is None else _horizon(com, head, target, bl))


def evaluate_controls(env: GradientEnv, u: np.ndarray, *, n_prep: int, n_cycle: int, heading_deg: float = 0.0,
                      max_tilt_deg: float = 60.0, target: np.ndarray | None = None,
                      check_rollout=None) -> dict[str, Any]:
    """Play ``u`` (prep + N cycles) from ``env``'s reset state and :func:`measure_gait` it
    (``target``: see there); a failed simulation gives ``speed_bl_per_min`` NaN, ``upright``
    False and ``sim_failure``. ``check_rollout(traj)``, if given, sees the rollout before it
    is measured (it may raise; a SimulationError in it counts as a failed simulation)."""
    n_cycles = _count_cycles(len(u), n_prep, n_cycle)
    try:
        traj = env.rollout(u)
        if check_rollout is not None:
            check_rollout(traj)
    except SimulationError as err:
        return {"cycles": n_cycles, "speed_bl_per_min": float("nan"), "upright": False,
                "sim_failure": str(err)}
    return measure_gait(traj, env, n_prep=n_prep, n_cycle=n_cycle, heading_deg=heading_deg,
                        max_tilt_deg=max_tilt_deg, target=target)


def evaluate_result(res, n_cycles: int | None = None, *, ignore_robot_mismatch: bool = False) -> dict[str, Any]:
    """The metric of a saved gait (a :class:`~trajopt.results.Result`) over ``n_cycles``
    cycles (default: as it was evaluated, else :data:`DEFAULT_EVAL_CYCLES`), on the physics it
    was made on (another robot is refused unless ``ignore_robot_mismatch``, see
    :func:`trajopt.replay.env_for_result`); keyframe results are re-expanded, others (like
    exported RL gaits) play their ``u``. The optimised horizon's heading and distance to
    ``res.target`` are measured when the played controls cover it.

    What is scored is what ``trajopt play`` streams: loading checked ``u`` against the keyframes
    (:mod:`trajopt.results.checks`), and here the stored ``u_post`` of a keyframe result must be
    the zero-slack controls of the rollout of ``u`` (a ValueError naming the file otherwise)."""
    from .replay import env_for_result, result_controls
    from .results.checks import check_zero_slack
    cycles = int(res.settings.get("eval_cycles", DEFAULT_EVAL_CYCLES)) if n_cycles is None else int(n_cycles)
    if cycles < 1:
        raise ValueError(f"the number of cycles must be >= 1, got {cycles}")
    env = env_for_result(res, ignore_robot_mismatch=ignore_robot_mismatch)
    u, n_prep, n_cycle = result_controls(res, env.robot, cycles)
    target = res.target if 2 <= len(res.target) <= len(u) + 1 else None     # the optimised horizon
    heading = float(res.settings.get("heading_deg", 0.0))
    K, robot = len(res.u), env.robot

    def check_u_post(traj) -> None:
        prefix = traj if (len(u) >= K and np.array_equal(u[:K], res.u)) else env.rollout(res.u)
        check_zero_slack(res.u_post, zero_slack_controls(res.u, prefix.cable_deformation[:K + 1],
                                                         robot.tendon_motor, robot.u_bounds), res.path or "the result")

    return evaluate_controls(env, u, n_prep=n_prep, n_cycle=n_cycle, heading_deg=heading, target=target,
                             check_rollout=check_u_post if "keyframes" in res.settings else None)
