"""Sensitivity benchmark (issue: sensitivity analysis).

In one run on the Puppy (168 steps, nz = 32: 8 motors x 4 keyframes, no symmetry) and the
Tripod (nz = 8), prints: rollout time, rollout + Jacobian time and their ratio (target <= 1.3),
and the same for central finite differences (2 nz rollouts; ratio about 2 nz). Also the adjoint
gradient of a scalar objective (one backward pass) for comparison.
Run: python benchmarks/bench_sensitivity.py
"""
from __future__ import annotations

import time

import numpy as np

from common import best_of, report
from soft_envs.sim import Simulator, load_robot
from trajopt.optim.parameterization import GaitParameterization


def bench(name: str) -> dict:
    robot = load_robot(name)
    sim = Simulator(robot)
    x0 = sim.rest_state()
    param = GaitParameterization(robot.u_bounds, robot.mirror_map, symmetry=False)
    z = param.seeds(2)[1]
    u, dudz = param.controls(z), param.dudz()
    t_roll = best_of(lambda: sim.rollout(u, x0=x0), repeat=3)
    t_jac = best_of(lambda: sim.rollout(u, x0=x0, dudz=dudz), repeat=3)
    t0 = time.perf_counter()
    sim.rollout(u + 1e-7 * dudz[:, :, 0], x0=x0)
    t_fd = 2 * param.nz * (time.perf_counter() - t0)            # central differences: 2 nz rollouts
    traj = sim.rollout(u, x0=x0)
    w = np.random.default_rng(0).normal(size=traj.x.shape)
    t_adj = best_of(lambda: sim.rollout_gradient(u, w, x0=x0, dudz=dudz, traj=traj), repeat=2)
    return {"robot": name, "steps": len(u), "nz": param.nz, "rollout_s": t_roll, "rollout_jacobian_s": t_jac,
            "ratio": t_jac / t_roll, "finite_diff_s": t_fd, "fd_ratio": t_fd / t_roll,
            "adjoint_backward_s": t_adj}


def main() -> None:
    rows = [bench("puppy"), bench("tripod")]
    report("sensitivity: rollout Jacobian vs rollout", rows)
    r = rows[0]
    print(f"puppy: Jacobian of 168 steps x {r['nz']} parameters costs {r['ratio']:.2f} rollouts "
          f"(target <= 1.3: {'OK' if r['ratio'] <= 1.3 else 'MISSED'}); finite differences {r['fd_ratio']:.0f}")


if __name__ == "__main__":
    main()
