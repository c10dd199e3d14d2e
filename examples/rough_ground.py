"""The Tripod walking one gait on the plane, on rough ground and up a step.

Run:  python examples/rough_ground.py          (about 15 s)

What it shows: a ground that is not flat is a :class:`~soft_envs.sim.ground.HeightField` given to
the robot (``robot.replace(ground=...)``, ``robot.toml``'s ``[ground]`` table or the
environments' ``ground=`` keyword); the contact laws then press on the field along its normal and
rub in its tangent plane. The same periodic gait (the two motors over their whole range,
0.66 s cycle, 'back' 3/8 of a cycle ahead of 'front') is played on each ground, and we print how far the robot got, its speed in body lengths
per minute, its largest tilt (whether it stayed upright) and how deep its feet sank into the
surface.

SOFT_ENVS_QUICK=1 (the project's convention for CI) shrinks the work to a smoke test.
"""
import os

import numpy as np

from soft_envs.sim import HeightField, Simulator, load_robot
from soft_envs.sim.kinematics import BodyFrame, tilt_deg_of

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
K = 20 if QUICK else 150                         # control steps of 33 ms (5 s; quick: 0.66 s)

robot = load_robot("tripod")                     # Coulomb friction, 4 physics steps per control step
t = np.arange(K) * 0.033
u = np.zeros((K, robot.n_motors))
for m, phase in enumerate((0.0, 0.75 * np.pi)):  # raised cosines: front, then back
    u[:, m] = robot.u_bounds[m, 1] * 0.5 * (1 - np.cos(2 * np.pi * t / 0.66 + phase))

grounds = {
    "plane y = 0": None,
    "rough, RMS 1 mm": HeightField.rough(amplitude=0.001, wavelength=0.05, seed=0),
    "rough, RMS 3 mm": HeightField.rough(amplitude=0.003, wavelength=0.05, seed=0),
    "step up 5 mm at x = 0.2 m": HeightField.step(height=0.005, position=0.2, width=0.01),
    "trench 5 mm deep, 3 cm long": HeightField.trench(depth=0.005, start=0.2, length=0.03, width=0.01),
}
for name, ground in grounds.items():
    sim = Simulator(robot.replace(ground=ground), substeps=robot.contact.law.default_substeps)
    traj = sim.rollout(u, x0=sim.rest_state())
    frame = BodyFrame(traj.x[0], robot.node_masses)
    tilt = max(tilt_deg_of(frame.rotation(x)) for x in traj.x)
    feet = traj.x[:, :, 1] - (0.0 if ground is None else ground.height(traj.x[:, :, 0], traj.x[:, :, 2]))
    dx = traj.com[-1, 0] - traj.com[0, 0]
    speed = dx / robot.body_length / (K * sim.dt) * 60.0
    print(f"{name:28s}: COM {1000 * dx:+6.1f} mm along x in {K * sim.dt:.1f} s ({speed:+.2f} BL/min), "
          f"largest tilt {tilt:4.1f} deg{' (fell over)' if tilt > 60 else ''}, deepest foot "
          f"{1000 * max(-feet.min(), 0.0):.2f} mm into the ground")
