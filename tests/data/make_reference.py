"""Regenerate ``tests/data/reference_rollouts.npz``: short rollouts of both shipped robots that
``tests/test_reference_rollouts.py`` compares the simulator against.

    python tests/data/make_reference.py            # writes tests/data/reference_rollouts.npz

WHEN TO REGENERATE: only for an *intended* change of the physics or of the shipped robots (a
new contact law as the default, a different material model, new meshes or parameters in
assets/), and then in the same commit as that change, saying in its message what changed and
why the old numbers are no longer right. Never regenerate to make the regression test pass
after a refactor, an optimisation or a bug fix that was not meant to change results: the test
failing is then the finding. Print the differences first (``pytest tests/test_reference_rollouts.py``)
and put them in the commit message.

Cases (as benchmarks/reference_rollouts.py, shorter): for the Tripod and the Puppy, a smooth
gait, seeded random controls (reversing at the motors' speed limit) and zero controls in length
control; the gait as tensions in tension control; the gait on a 10-degree slope. Each is
``K = 30`` steps from ``Simulator.rest_state()`` with dt = 0.033 s and a seeded random
``dudz`` (2 parameters). Recorded: the COM, the cable deformations, six node positions and
``dcomdz``. Only the public API of ``soft_envs.sim`` is used.

The steps are solved to a Newton tolerance of 1e-11 m (``NEWTON_TOL``), not the default 1e-8 m:
what is pinned is the physics (the exact implicit-Euler solution), not where a particular
solver happens to stop. Measured: at 1e-8 m two valid solver settings differ by up to 2e-7 m
after 30 steps (a contact switching on or off amplifies a 1e-8 m difference); at 1e-11 m the
same settings (CHOLMOD or SuperLU, factorisation reused or not, 1e-13 m) differ by at most
1.5e-11 m in positions and 1.5e-7 relative in dcomdz.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:                   # run as a script from anywhere in the checkout
    sys.path.insert(0, str(ROOT))

from soft_envs.sim import NewtonOptions, Simulator, incline_gravity, load_robot  # noqa: E402

PATH = Path(__file__).with_name("reference_rollouts.npz")
K = 30           # steps per case (<= 40: the tolerance below assumes short rollouts)
NZ = 2           # parameters of the random dudz
N_NODES = 6      # node positions recorded per case
DT = 0.033
NEWTON_TOL = 1e-11


def gait(robot, K: int, period: int = 36) -> np.ndarray:
    """Each motor a raised cosine between its bounds, phase-shifted motor to motor."""
    t = np.arange(K) * DT
    lo, hi = robot.u_bounds[:, 0], robot.u_bounds[:, 1]
    u = np.empty((K, robot.n_motors))
    for m in range(robot.n_motors):
        ph = 2 * np.pi * m / robot.n_motors
        u[:, m] = lo[m] + (hi[m] - lo[m]) * 0.5 * (1 - np.cos(2 * np.pi * t / (period * DT) + ph))
    return u


def random_controls(robot, K: int, rng, du_max: float = 1.7e-3) -> np.ndarray:
    """Uniform random targets within the bounds, followed at most ``du_max`` per step."""
    lo, hi = robot.u_bounds[:, 0], robot.u_bounds[:, 1]
    target = rng.uniform(lo, hi, size=(K, robot.n_motors))
    u = np.empty_like(target)
    cur = np.clip(0.0, lo, hi)
    for k in range(K):
        cur = cur + np.clip(target[k] - cur, -du_max, du_max)
        u[k] = cur
    return u


#: the contact law of the reference rollouts: the paper's, named here rather than taken from the
#: robot files (whose default is the Coulomb law since issue #31), so the recorded physics stays
#: the paper's bit for bit whatever the files say
CONTACT = "paper"


def cases(K: int = K, contact: str = CONTACT):
    """``(name, robot, Simulator keyword arguments, controls)`` of every case, ``K`` steps each,
    the robots under the contact law ``contact`` (``benchmarks/reference_rollouts.py`` uses the
    same cases, longer, and under the Coulomb law too)."""
    for name in ("tripod", "puppy"):
        robot = load_robot(name)
        robot = robot.replace(contact=dataclasses.replace(robot.contact, model=contact))
        rng = np.random.default_rng(1234)
        g = gait(robot, K)
        yield f"{name}/gait", robot, {}, g
        yield f"{name}/random", robot, {}, random_controls(robot, K, rng)
        yield f"{name}/zero", robot, {}, np.zeros((K, robot.n_motors))
        yield f"{name}/tension", robot, {"control": "tension"}, 2.0 * g / robot.u_bounds[:, 1].max()
        yield f"{name}/slope10", robot, {"gravity": incline_gravity(10.0)}, g


def recorded_nodes(robot) -> np.ndarray:
    """Six nodes spread over the mesh's node numbering."""
    return np.linspace(0, robot.mesh.n_nodes - 1, N_NODES).round().astype(np.int64)


def simulate(robot, sim_kwargs: dict, u: np.ndarray, **newton) -> dict[str, np.ndarray]:
    """The recorded quantities of one case (``newton``: NewtonOptions fields, default the tight
    ``tol=NEWTON_TOL``; others for studies of the comparison's robustness)."""
    sim = Simulator(robot, dt=DT, newton=NewtonOptions(**{"tol": NEWTON_TOL, **newton}), **sim_kwargs)
    x0 = sim.rest_state()
    dudz = np.random.default_rng(99).standard_normal((len(u), robot.n_motors, NZ)) * 1e-3
    traj = sim.rollout(u, x0=x0, dudz=dudz)
    nodes = recorded_nodes(robot)
    return {"com": traj.com, "gamma": traj.cable_deformation, "nodes": traj.x[:, nodes], "dcomdz": traj.dcomdz}


def record() -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for key, robot, kw, u in cases():
        for name, arr in simulate(robot, kw, u).items():
            out[f"{key}/{name}"] = arr
        print(f"recorded {key}", file=sys.stderr)
    return out


def main() -> int:
    data = record()
    np.savez_compressed(PATH, **data)
    print(f"wrote {PATH} ({len(data)} arrays, {PATH.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
