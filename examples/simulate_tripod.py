"""Simulate the shipped Tripod: stand, then bend its middle leg back and forth.

Run:  python examples/simulate_tripod.py

What it shows: load a robot, find its rest state, roll out a control trajectory, read the
centre of mass and cable deformations, and get exact derivatives of the whole rollout.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""
import os

import numpy as np

from soft_envs.sim import Simulator, load_robot

robot = load_robot("tripod")                 # assets/tripod/robot.toml
print(robot.summary())
sim = Simulator(robot, dt=0.033)             # implicit Euler, h = 0.033 s (paper)
x0 = sim.rest_state()                        # standing on the ground, u = 0

# 2 s of alternating contractions of the two motors (metres of cable pulled in)
K = 15 if os.environ.get("SOFT_ENVS_QUICK") == "1" else 60     # quick: CI smoke test
t = np.arange(K) * sim.dt
u = np.zeros((K, robot.n_motors))
u[:, 0] = 0.006 * np.clip(np.sin(2 * np.pi * t), 0, None)   # "front" bends the leg forward
u[:, 1] = 0.006 * np.clip(-np.sin(2 * np.pi * t), 0, None)  # "back" bends it backward

# dudz: here one parameter per motor scaling its whole signal, so dcomdz[k, :, m] is how the
# centre of mass at step k moves if motor m's amplitude grows (exact, by sensitivity analysis)
dudz = np.stack([np.diag(u[k]) for k in range(K)])          # (K, n_motors, nz=2)
traj = sim.rollout(u, x0=x0, dudz=dudz)

print(f"COM moved {1000 * (traj.com[-1, 0] - traj.com[0, 0]):+.2f} mm along x in {K * sim.dt:.1f} s")
print("Newton iterations per step:", traj.newton_iterations.mean().round(2))
print("final cable deformations Gamma [mm]:", np.round(1000 * traj.cable_deformation[-1], 3))
print("d COM_x(final) / d amplitude [mm per unit]:", np.round(1000 * traj.dcomdz[-1, 0], 3))
