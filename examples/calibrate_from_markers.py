"""Fit the foam's Young's modulus, Poisson ratio and the ground friction to tracked markers.

Run:  python examples/calibrate_from_markers.py                (about a minute)
      SOFT_ENVS_QUICK=1 python examples/calibrate_from_markers.py   (tiny settings, as CI runs it)

The paper fits E and nu "through trial and error" (II-A). Here a Tripod with hidden parameters
(E 25 % stiffer, nu 0.36 instead of 0.3, friction 30 % lower) plays a gait while a tracker
records 8 markers at 30 Hz with 0.5 mm noise; ``trajopt calibrate`` then recovers the
parameters from the tracks (Gauss-Newton with exact sensitivities of the whole rollout), with
standard errors, a plot of the tracks before and after, and a new robot.toml. The same from the
shell, with the files this example writes:

    trajopt calibrate tripod --markers results/calibration/tracks.csv \\
        --controls results/calibration/gait.npz --marker-points results/calibration/markers.csv \\
        --fit youngs_modulus,poisson_ratio,friction --out results/calibration/fit
"""
import os
from pathlib import Path

import numpy as np

from soft_envs.envs import MarkerSet, load_robot, with_parameters
from trajopt.calibrate import synthetic_tracks
from trajopt.cli import main
from trajopt.results import Result
from trajopt.tracks import write_tracks

QUICK = os.environ.get("SOFT_ENVS_QUICK") == "1"
OUT = Path("results") / "calibration"
OUT.mkdir(parents=True, exist_ok=True)
robot = load_robot("tripod")
dt = 0.033

# 8 markers on the surface, spread over the body (farthest-point sampling of surface nodes)
X, surface = robot.mesh.points, robot.mesh.boundary_nodes
chosen = [surface[np.argmax(X[surface, 1])]]
while len(chosen) < 8:
    chosen.append(surface[np.argmax(np.min(np.linalg.norm(X[surface][:, None] - X[chosen][None], axis=2), axis=1))])
markers = MarkerSet.bind(robot.mesh, [f"m{i}" for i in range(8)], X[chosen])
(OUT / "markers.csv").write_text("marker,x,y,z\n" + "".join(
    f"{n},{p[0]:.9g},{p[1]:.9g},{p[2]:.9g}\n" for n, p in zip(markers.names, markers.points)))

# the controls that were played: the two motors pull in turn, 1.2 s period
K = 30 if QUICK else 120
t = dt * np.arange(K)
u = np.stack([0.5 * robot.u_bounds[m, 1] * (1 - np.cos(2 * np.pi * t / 1.2 + 2.0 * m))
              for m in range(robot.n_motors)], axis=1)
gait = Result(robot="tripod", task="custom", motor_names=robot.motor_names, dt=dt, z=np.zeros(0), u=u, u_post=u,
              target=np.zeros((K + 1, 2)), com=np.zeros((K + 1, 3))).save(OUT / "gait.npz")

# what the tracker saw: the robot with hidden parameters
fit = ["youngs_modulus"] if QUICK else ["youngs_modulus", "poisson_ratio", "friction"]
hidden = {"youngs_modulus": 1.25e5, "poisson_ratio": 0.36, "friction": 700.0}
hidden = {k: hidden[k] for k in fit}
times, positions, _ = synthetic_tracks(with_parameters(robot, hidden), markers, u, dt, rate_hz=30.0, noise_m=5e-4)
write_tracks(OUT / "tracks.csv", times, markers.names, positions)
print("hidden:", ", ".join(f"{k} = {v:g}" for k, v in hidden.items()))

code = main(["calibrate", "tripod", "--markers", str(OUT / "tracks.csv"), "--controls", str(gait),
             "--marker-points", str(OUT / "markers.csv"), "--fit", ",".join(fit), "--out", str(OUT / "fit")])
print(f"the plot of the tracks before and after the fit: {OUT / 'fit' / 'tracks.png'}")
raise SystemExit(code)
