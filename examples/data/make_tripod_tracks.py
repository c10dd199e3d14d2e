"""Write the synthetic marker tracks ``trajopt calibrate`` is shown on in the README:
``tripod_tracks.csv`` (t, marker, x, y, z), ``tripod_markers.csv`` (the 8 markers' rest
positions) and ``tripod_gait.npz`` (+ .json: the controls that were played).

Run:  python examples/data/make_tripod_tracks.py          (a few seconds; rewrites the three files)

A Tripod under the paper's contact law with hidden parameters (E 25 % stiffer, nu 0.36 instead of 0.3, friction 30 % lower)
plays 120 steps of a gait (the two motors pull in turn, 1.2 s period) while a tracker records 8
surface markers at 30 Hz with 0.5 mm noise (seeded: the files are the same every run).
``examples/calibrate_from_markers.py`` makes the same data with :func:`write_tripod_tracks`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from soft_envs.envs import MarkerSet, load_robot, with_contact_law, with_parameters
from trajopt.calibration.calibrate import synthetic_tracks
from trajopt.results.result import Result
from trajopt.calibration.tracks import write_tracks

HERE = Path(__file__).resolve().parent
#: the parameters of the robot that made the tracks (the shipped Tripod's: 1e5 Pa, 0.3, 1000 /m)
HIDDEN = {"youngs_modulus": 1.25e5, "poisson_ratio": 0.36, "friction": 700.0}


def write_tripod_tracks(markers_csv: Path, gait_npz: Path, tracks_csv: Path, *, steps: int = 120,
                        hidden: dict[str, float] = HIDDEN) -> dict[str, float]:
    """Write the three files for a Tripod with ``hidden`` parameters playing ``steps`` steps;
    returns ``hidden``."""
    robot = with_contact_law(load_robot("tripod"), "paper")   # the files were made under the paper's law
    dt = 0.033
    # 8 markers on the surface, spread over the body (farthest-point sampling of surface nodes)
    X, surface = robot.mesh.points, robot.mesh.boundary_nodes
    chosen = [surface[np.argmax(X[surface, 1])]]
    while len(chosen) < 8:
        chosen.append(surface[np.argmax(np.min(np.linalg.norm(X[surface][:, None] - X[chosen][None], axis=2),
                                               axis=1))])
    markers = MarkerSet.bind(robot.mesh, [f"m{i}" for i in range(8)], X[chosen])
    Path(markers_csv).parent.mkdir(parents=True, exist_ok=True)
    Path(markers_csv).write_text("marker,x,y,z\n" + "".join(
        f"{n},{p[0]:.9g},{p[1]:.9g},{p[2]:.9g}\n" for n, p in zip(markers.names, markers.points)))
    # the controls that were played: the two motors pull in turn, 1.2 s period
    t = dt * np.arange(steps)
    u = np.stack([0.5 * robot.u_bounds[m, 1] * (1 - np.cos(2 * np.pi * t / 1.2 + 2.0 * m))
                  for m in range(robot.n_motors)], axis=1)
    Result(robot="tripod", task="custom", motor_names=robot.motor_names, dt=dt, z=np.zeros(0), u=u, u_post=u,
           target=np.zeros((steps + 1, 2)), com=np.zeros((steps + 1, 3))).save(gait_npz)
    # what the tracker saw: the robot with hidden parameters
    times, positions, _ = synthetic_tracks(with_parameters(robot, hidden), markers, u, dt, rate_hz=30.0,
                                           noise_m=5e-4)
    write_tracks(tracks_csv, times, markers.names, positions)
    return hidden


if __name__ == "__main__":
    write_tripod_tracks(HERE / "tripod_markers.csv", HERE / "tripod_gait.npz", HERE / "tripod_tracks.csv")
    print(f"wrote {HERE / 'tripod_tracks.csv'}, {HERE / 'tripod_markers.csv'}, {HERE / 'tripod_gait.npz'} (+ .json)")
