"""The Tripod carrying a payload and pushing a box: the two tasks with a second body.

Run:  python examples/carry_and_push.py          (about a minute)

What it shows: ``SoftTripodCarry-v0`` and ``SoftTripodPushBox-v0`` (and the Puppy's ids) add a
stiff box to the robot's simulation (a :class:`soft_envs.sim.Box`: 8 nodes, 5 tets, in the same
implicit-Euler solve, with mass, gravity, ground contact and contact with friction against the
robot's nodes; docs/tasks.md, docs/contact.md). One open-loop gait (both motors over their whole
range as raised cosines, a 0.66 s cycle, 'back' 3/8 of a cycle ahead of 'front': the gait of
examples/rough_ground.py) is played for 5 s at each difficulty, and we print how far the robot and
the box went, whether the payload fell, and how far the box was pushed. Last, the exact
derivative of where the pushed box ends with respect to the gait's amplitude (the environment's
gradient hook, ``rollout`` with ``dudz``: the box's contact has sensitivities) against central
differences; then trajopt optimises the walk with the box ahead (`trajopt optimize tripod --task
push_box`) and its gait is scored on the id by how far it pushes the box.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""
import os

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401  (registers the ids)

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
STEPS = 10 if QUICK else 150                     # environment steps of 33 ms (5 s; quick: 0.33 s)
LEVELS = ("easy",) if QUICK else ("easy", "medium", "hard")

def gait(u_max, K, dt, amplitude=1.0):
    """The raised-cosine gait's contractions (K, 2) [m] at ``amplitude`` (1: the whole range)."""
    t = np.arange(K)[:, None] * dt
    return amplitude * u_max * 0.5 * (1 - np.cos(2 * np.pi * t / 0.66 + np.array([0.0, 0.75 * np.pi])))


for env_id in ("SoftTripodCarry-v0", "SoftTripodPushBox-v0"):
    for level in LEVELS:
        env = gym.make(env_id, difficulty=level)
        env.reset(seed=0)
        u_max = env.unwrapped.robot.u_bounds[:, 1]
        box = env.unwrapped.box
        ret, ended = 0.0, "ran 5 s" if not QUICK else f"ran {STEPS} steps"
        for u in gait(u_max, STEPS, env.unwrapped.dt):
            _, reward, terminated, truncated, info = env.step(env.unwrapped.control_to_action(u))
            ret += reward
            if terminated:
                ended = ("payload fell" if info.get("payload_fell") else
                         "success" if info["is_success"] else "ended") + f" at step {env.unwrapped._n_sub}"
                break
        robot_dx, box_dx = 1e3 * info["displacement"][0], 1e3 * info["box_displacement"][0]
        what = (f"payload {1e3 * box.mass:.1f} g (mu {box.friction_coefficient:g}) moved {box_dx:+6.1f} mm"
                if "Carry" in env_id else f"box {1e3 * box.mass:.1f} g pushed {box_dx:+6.1f} mm")
        print(f"{env_id:22s} {level:6s}: robot {robot_dx:+6.1f} mm, {what}, tilt {info['box_tilt_deg']:4.1f} deg; "
              f"return {ret:+7.2f}; {ended}")

# d (the box's x at the end) / d amplitude over a 0.66 s push (0.2 s quick), at 90 % of the range: the
# rollout with dudz that the environment's gradient hook runs, on a simulator of its robot and physics
# solved to 1e-10 m per step (the environment's default, 1e-6 m, is the size of a difference step)
from soft_envs.sim import NewtonOptions, Simulator  # noqa: E402

env = gym.make("SoftTripodPushBox-v0").unwrapped
sim = Simulator(env.robot, dt=env.dt, substeps=env.substeps, newton=NewtonOptions(tol=1e-10))
start = sim.rest_state(env.robot.u_rest)
K = 6 if QUICK else 20
u_max = env.robot.u_bounds[:, 1]
u = gait(u_max, K, env.dt, 0.9)
traj = sim.rollout(u, x0=start, dudz=(u / 0.9)[:, :, None], store_dxdz=True)
box = env.robot.box_nodes
exact = traj.dxdz[-1, 3 * box, 0].mean()                 # the box centre's x, from its corners' rows
fd = []
for h in (1e-4, 1e-5):
    ends = [sim.rollout(gait(u_max, K, env.dt, 0.9 + s * h), x0=start).x[-1, box, 0].mean() for s in (1, -1)]
    fd.append(1e3 * (ends[0] - ends[1]) / (2 * h))
print(f"d(box x after {K * env.dt:.2f} s) / d amplitude: {1e3 * exact:+.3f} mm exact; central differences "
      f"{fd[0]:+.3f} mm (h = 1e-4), {fd[1]:+.3f} mm (h = 1e-5): the smaller step agrees; a larger one may cross "
      f"a foot's or the box's stick-slip event")

# trajopt with the box: the walk's objective on the robot with the task's box, the gait scored on the
# id by the task's own score (`trajopt optimize tripod --task push_box` does the same from the shell)
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from trajopt.optimize_run import OptimizeRun, run_optimization  # noqa: E402
from trajopt.results.result import Result  # noqa: E402
from trajopt.tasks.play import gait_on_task  # noqa: E402

with tempfile.TemporaryDirectory() as out:
    quick = dict(iterations=1, seeds=0, cycle_steps=12, prep_steps=6, cycles=1) if QUICK else dict(iterations=3)
    run_optimization(OptimizeRun("tripod", task="push_box", out=Path(out), quiet=True, **quick))
    res = Result.load(Path(out) / "tripod_push_box.npz")
    ev = gait_on_task(res, episodes=1)
    ep = ev["episodes"][0]
    print(f"trajopt push_box ({len(res.history)} Gauss-Newton iterations): the robot walks "
          f"{res.evaluation['speed_bl_per_min']:.2f} BL/min with the box ahead; on {ev['env_id']} the box is "
          f"{ev['score_name']} {ev['score']:+.2f} {ev['score_unit']} ({ep['end']} at step {ep['steps']})")
