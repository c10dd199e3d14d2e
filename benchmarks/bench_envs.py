"""Environment benchmark (issue: Gymnasium environments).

For SoftTripod-v0 and SoftPuppy-v0 (``gymnasium.make`` with its default wrappers, one process):
  * env steps/s with uniformly random actions from the seeded action space, and with a smooth
    periodic action (benchmarks/common.py's gait-like control mapped to actions),
  * Newton iterations and factorisations per step,
  * the share of the step spent outside ``Simulator.step`` (the environment layer: action
    checks, speed limit, observation with the Kabsch rotation, reward, info, wrappers).
Targets from the issue: Tripod >= 1000 steps/s, Puppy >= 300 steps/s; env layer < 10 %.
Each figure is the best of ``REPEATS`` runs of ``STEPS`` steps from the same seeded reset
(the machine may be shared; the overhead share is measured inside each run, so it is robust).
Run: python benchmarks/bench_envs.py
"""
from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401  (registers the ids)
import soft_envs.sim.integrator as integrator
from common import gait_controls, report

STEPS = 300
REPEATS = 3
TARGETS = {"SoftTripod-v0": 1000.0, "SoftPuppy-v0": 300.0}

_newton: list[tuple[int, int]] = []
_orig_newton_step = integrator.NewtonSolver.step


def _counting_newton_step(self, *args, **kwargs):
    x, info = _orig_newton_step(self, *args, **kwargs)
    _newton.append((info.iterations, info.factorizations))
    return x, info


def run(env, actions: np.ndarray) -> dict:
    """Step through ``actions`` from a seeded reset; returns wall and simulator time."""
    sim = env.unwrapped.simulator
    t_sim = [0.0]
    step = type(sim).step

    def timed_step(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return step(sim, *args, **kwargs)
        finally:
            t_sim[0] += time.perf_counter() - t0

    sim.step = timed_step
    env.reset(seed=0)
    _newton.clear()
    resets = 0
    t0 = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
            resets += 1
    wall = time.perf_counter() - t0
    del sim.step
    its = np.mean(_newton, axis=0) if _newton else np.zeros(2)
    return {"wall": wall, "sim": t_sim[0], "its": float(its[0]), "facts": float(its[1]), "resets": resets}


def bench(env_id: str, kind: str) -> dict:
    env = gym.make(env_id, max_episode_steps=10 * STEPS)
    u_env = env.unwrapped
    if kind == "random":
        env.action_space.seed(0)
        actions = np.array([env.action_space.sample() for _ in range(STEPS)])
    else:
        u = gait_controls(u_env.robot, K=STEPS, dt=u_env.timestep)
        actions = u_env.control_to_action(u).astype(np.float32)
    best = min((run(env, actions) for _ in range(REPEATS)), key=lambda r: r["wall"])
    env.close()
    rate = STEPS / best["wall"]
    return {"env": env_id, "actions": kind, "steps_per_s": rate, "sim_only_steps_per_s": STEPS / best["sim"],
            "env_layer_pct": 100.0 * (best["wall"] - best["sim"]) / best["wall"],
            "newton_its_per_step": best["its"], "factorizations_per_step": best["facts"],
            "resets": best["resets"], "target_steps_per_s": TARGETS[env_id]}


def main() -> None:
    integrator.NewtonSolver.step = _counting_newton_step
    rows = [bench(env_id, kind) for env_id in TARGETS for kind in ("random", "smooth")]
    report(f"environments: steps/s ({STEPS} steps, best of {REPEATS}, frame_skip 1, dt 0.033 s)", rows)
    for r in rows:
        ok = r["steps_per_s"] >= r["target_steps_per_s"]
        print(f"{r['env']} ({r['actions']} actions): {r['steps_per_s']:.0f} steps/s "
              f"(target >= {r['target_steps_per_s']:.0f}): {'OK' if ok else 'MISSED'}; env layer "
              f"{r['env_layer_pct']:.1f} % of the step (target < 10 %): "
              f"{'OK' if r['env_layer_pct'] < 10 else 'MISSED'}")


if __name__ == "__main__":
    main()
