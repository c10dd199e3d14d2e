"""A/B timing of two checkouts of this project, alternated in one run (for refactors that
must not be slower).

    python benchmarks/ab_compare.py /path/to/checkout_A /path/to/checkout_B [--rounds 5]

Each round runs the same timing script once under each checkout (a subprocess with that
checkout first on ``PYTHONPATH``), alternating A, B, A, B ..., so a slow spell of the shared
machine hits both. Timed: a 168-step gait rollout of the Puppy and of the Tripod, the Puppy's
rollout with exact sensitivities for nz = 32 parameters, and 300 random-action steps of
``SoftTripod-v1``, all under the paper's contact law named explicitly (``contact="paper"``), so
that both sides simulate the same physics whatever their robot files' default law (the paper's
before issue #31, Coulomb's since). Prints the best CPU time of each over the rounds and the ratio B / A.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

SNIPPET = r"""
import dataclasses, json, time
import numpy as np
import gymnasium as gym
import soft_envs
from soft_envs.sim import Simulator, load_robot
sys_path_check = soft_envs.__file__

def gait(robot, K=168, dt=0.033, period=72):
    t = np.arange(K) * dt
    u = np.zeros((K, robot.n_motors))
    for m in range(robot.n_motors):
        u[:, m] = robot.u_bounds[m, 1] * 0.5 * (1 - np.cos(2 * np.pi * t / (period * dt) + 2 * np.pi * m / robot.n_motors))
    return u

def best(f, n=3):
    # CPU time of this process (single-threaded: OMP_NUM_THREADS=1): much less sensitive than
    # wall time to other processes sharing the cores
    f()
    out = []
    for _ in range(n):
        t0 = time.process_time(); f(); out.append(time.process_time() - t0)
    return min(out)

res = {"module": sys_path_check}
for name in ("puppy", "tripod"):
    r = load_robot(name); r = r.replace(contact=dataclasses.replace(r.contact, model="paper"))
    sim = Simulator(r); x0 = sim.rest_state(); u = gait(r)
    res[f"{name}_rollout_s"] = best(lambda: sim.rollout(u, x0=x0))
    if name == "puppy":
        dudz = np.random.default_rng(0).normal(size=(len(u), r.n_motors, 32)) * 1e-4
        res["puppy_jacobian_s"] = best(lambda: sim.rollout(u, x0=x0, dudz=dudz), n=2)
env = gym.make("SoftTripod-v1", contact="paper")
env.reset(seed=0)
rng = np.random.default_rng(0)
acts = rng.uniform(-1, 1, size=(300, 2))
def run_env():
    env.reset(seed=0)
    for a in acts:
        env.step(a)
res["tripod_env_300_steps_s"] = best(run_env, n=2)
print("RESULT" + json.dumps(res))
"""


def run(checkout: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(checkout), OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", "import sys\n" + SNIPPET], env=env, capture_output=True,
                         text=True, check=True, cwd=checkout).stdout
    return json.loads(out.split("RESULT", 1)[1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--rounds", type=int, default=5)
    args = p.parse_args(argv)
    runs = {"A": [], "B": []}
    for r in range(args.rounds):
        for key, path in (("A", args.a), ("B", args.b)):
            runs[key].append(run(path))
            print(f"round {r + 1} {key}: " + ", ".join(f"{k} {v:.3f}" for k, v in runs[key][-1].items()
                                                    if k != "module"), flush=True)
    print(f"A = {runs['A'][0]['module']}\nB = {runs['B'][0]['module']}")
    print(f"{'figure (best of rounds)':<28}{'A':>9}{'B':>9}{'B/A':>7}")
    for k in runs["A"][0]:
        if k == "module":
            continue
        a = min(r[k] for r in runs["A"])
        b = min(r[k] for r in runs["B"])
        print(f"{k:<28}{a:9.3f}{b:9.3f}{b / a:7.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
