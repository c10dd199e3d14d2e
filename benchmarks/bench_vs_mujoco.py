"""Side by side with MuJoCo's 3-D flex on the same tet mesh (issue #15, item 5).

For each shipped robot, MuJoCo's flex (``benchmarks/mujoco_flex.py``: same nodes and tets,
Young's modulus, Poisson ratio, node masses with the payload, h = 0.033 s, integrator
``discrete``, a ground plane) stands on the ground; MuJoCo cannot attach tendons to a flex, so
standing is all it does. The script first prints that the two models are comparable (total
mass, rest COM height, sag under gravity, penetration, that MuJoCo's model stands still), then
times, alternating in one process for ``--rounds`` rounds (best of each figure):

  * MuJoCo standing [ms/step] (and, for reference, MuJoCo with its default approximate contact
    diagonal, which sinks into the ground, and with its solver iterations capped at 10, which
    stands the same but cuts short the M + h^2 K solve that hits its cap every step: see
    mujoco_flex.py),
  * ours, for each contact law: standing (zero controls), a smooth sine gait
    (``common.gait_controls``) and random targets approached at the motors' speed limit
    (``common.random_controls``, the environments' 100 rpm on a 5 mm spool), each in ms/step
    and as a ratio to MuJoCo standing; Newton iterations per step; the gait step in CHOLMOD
    factorisations of that robot's Hessian (mid-gait, as in bench_sim.py),
  * the environments' steps/s with random actions (``SoftTripod-v1``/``SoftPuppy-v1`` with
    ``contact=`` the case's law).
The issue's targets (Coulomb law) are printed beside the figures; the load average is printed
per round (the machine is shared: compare the ratios, measured in the same round).
Run: python benchmarks/bench_vs_mujoco.py [--contact paper coulomb] [--rounds 3] [--steps 168]
Needs the ``bench`` extra: pip install -e .[bench]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import re
import time

import gymnasium as gym
import numpy as np

import soft_envs  # noqa: F401  (registers the environment ids)
from common import gait_controls, random_controls, report
from mujoco_flex import FlexModel
from soft_envs.envs import with_contact_law
from soft_envs.sim import Simulator, load_robot
from soft_envs.sim.kinematics import BodyFrame, tilt_deg_of

DT = 0.033
ENV_NAMES = {"tripod": "SoftTripod", "puppy": "SoftPuppy"}
#: issue #15's speed targets, for the Coulomb law
TARGETS = {"gait_x": 1.0, "random_x": 1.5, "gait_factorizations": 4.0,
           "env_steps_per_s": {"tripod": 500.0, "puppy": 350.0}}
#: MuJoCo models timed: the comparable one ("mujoco"), and for reference MuJoCo's default
#: approximate contact diagonal (sinks into the ground) and a 10-iteration cap (see mujoco_flex.py)
MJ_VARIANTS = {"mujoco": {}, "mujoco_default_contact": {"exact_contact_diagonal": False},
               "mujoco_10_iterations": {"iterations": 10}}
STILL_TOL = 1e-4          # [m] largest node motion over the timed standing run that counts as still


def motor_rate(robot, dt: float) -> np.ndarray:
    """Per-step change of each motor's contraction at its no-load speed, as a fraction of its
    range (the environments' speed limit, ``soft_envs.envs.base``)."""
    v = robot.max_contraction_speed
    return v * dt / np.diff(robot.u_bounds, axis=1)[:, 0]


def elapsed(f) -> float:
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


class OursCase:
    """Our simulator for one robot and contact law: controls, rest state, environment."""

    def __init__(self, name: str, law: str, steps: int, env_steps: int):
        self.robot = with_contact_law(load_robot(name), law)
        self.sim = Simulator(self.robot, dt=DT)
        self.x0 = self.sim.rest_positions()
        r = self.robot
        self.controls = {"stand": np.zeros((steps, r.n_motors)),
                         "gait": gait_controls(r, K=steps, dt=DT),
                         "random": random_controls(r, steps, seed=0, rate=motor_rate(r, DT))}
        self.newton_its = {k: float(self.sim.rollout(u, x0=self.x0).newton_iterations.mean())
                           for k, u in self.controls.items()}      # also compiles and warms up
        gait = self.sim.rollout(self.controls["gait"], x0=self.x0)
        k = steps // 2                                             # a mid-gait Hessian
        u = self.controls["gait"]
        xt = 2 * gait.x[k] - gait.x[k - 1]
        _, _, self.hessian = self.sim.newton.phi_assemble(gait.x[k + 1], xt, gait.x[k], u[k])
        self.env_id = f"{ENV_NAMES[name]}-v1"         # the latest id, under either law (contact=)
        self.env = None
        if self.env_id in gym.registry:
            self.env = gym.make(self.env_id, contact=law, max_episode_steps=10 * env_steps)
            self.env.action_space.seed(0)
            self.actions = np.array([self.env.action_space.sample() for _ in range(env_steps)])

    def time_rollout(self, kind: str) -> float:
        u = self.controls[kind]
        return elapsed(lambda: self.sim.rollout(u, x0=self.x0)) / len(u)

    def time_factorize(self, number: int = 20) -> float:
        solver = self.sim.newton.solver
        return elapsed(lambda: [solver.factorize(self.hessian) for _ in range(number)]) / number

    def time_env(self) -> tuple[float, int]:
        """Seconds per environment step with random actions, and simulation failures."""
        env, failures = self.env, 0
        env.reset(seed=0)
        t0 = time.perf_counter()
        for a in self.actions:
            _, _, terminated, truncated, info = env.step(a)
            failures += "sim_failure" in info
            if terminated or truncated:
                env.reset()
        return (time.perf_counter() - t0) / len(self.actions), failures


def settle_mujoco(mj: FlexModel, x_start: np.ndarray, settle: int, steps: int) -> dict:
    """Start MuJoCo at ``x_start`` at rest, take ``settle`` steps, then ``steps`` standing: what
    it settled to, how much it moved while standing, and the state to time from."""
    mj.set_state(x_start)
    mj.step(settle)
    x = mj.positions()
    com0 = mj.masses @ mj.placement / mj.total_mass
    out = {"sag_mm": 1e3 * (com0[1] - mj.com()[1]), "penetration_mm": -1e3 * min(x[:, 1].min(), 0.0),
           "tilt_deg": tilt_deg(mj.placement, mj.masses, x), "state": mj.snapshot()}
    capped = mj.warnings().get("mjWARN_INERTIA", 0)
    mj.step(steps)
    out.update(drift=float(np.abs(mj.positions() - x).max()), speed=float(np.abs(mj.data.qvel).max()),
               contacts=int(mj.data.ncon), its=int(mj.data.solver_niter[0]),
               capped=(mj.warnings().get("mjWARN_INERTIA", 0) - capped) / steps)
    return out


def tilt_deg(x_ref: np.ndarray, masses: np.ndarray, x: np.ndarray) -> float:
    """Angle between the body's best-fit up vector and +y (soft_envs.sim.kinematics)."""
    return tilt_deg_of(BodyFrame(x_ref, masses).rotation(x))


def sag_with_double_stiffness(case: "OursCase", settle: int, mu: float) -> tuple[float, float]:
    """Sag [mm] of ours and of MuJoCo's flex with Young's modulus doubled: both models must
    respond to E alike (MuJoCo warns, wrongly, that its flex has no passive forces)."""
    robot = case.robot.replace(youngs_modulus=2 * case.robot.youngs_modulus)
    sim = Simulator(robot, dt=DT)
    x_place = sim.initial_placement()
    ours = 1e3 * (robot.com(x_place)[1] - robot.com(sim.rest_positions())[1])
    return ours, settle_mujoco(FlexModel(robot, DT, mu), case.x0, settle, 1)["sag_mm"]


def comparability(name: str, case: OursCase, mjs: dict[str, FlexModel], settle: int, steps: int,
                  mu: float) -> tuple[list[dict], dict]:
    """Rows of model facts, ours beside each MuJoCo variant (``MJ_VARIANTS``), and the settled
    MuJoCo states to time from."""
    robot, sim = case.robot, case.sim
    x_place = sim.initial_placement()
    com0 = robot.com(x_place)[1]
    stand = sim.rollout(case.controls["stand"], x0=case.x0)
    mj = {v: settle_mujoco(model, case.x0, settle, steps) for v, model in mjs.items()}
    ours = {"total mass [g]": 1e3 * robot.total_mass, "rest COM height [mm]": 1e3 * com0,
            "sag of the COM under gravity [mm]": 1e3 * (com0 - robot.com(case.x0)[1]),
            "deepest node below the ground [mm]": -1e3 * min(case.x0[:, 1].min(), 0.0),
            "tilt [deg]": tilt_deg(x_place, robot.node_masses, case.x0),
            f"largest node motion standing {steps} steps [mm]": 1e3 * float(np.abs(stand.x[-1] - stand.x[0]).max()),
            f"stands still (motion <= {1e3 * STILL_TOL:g} mm)": True,
            "largest node speed at the end [mm/s]": 1e3 * float(np.abs(stand.x[-1] - stand.x[-2]).max()) / DT,
            "nodes in contact": int((case.x0[:, 1] < 0).sum())}
    rows = [{"robot": name, "quantity": q, "ours": o} for q, o in ours.items()]
    for v, r in mj.items():
        values = [1e3 * mjs[v].total_mass, 1e3 * (mjs[v].masses @ mjs[v].placement)[1] / mjs[v].total_mass,
                  r["sag_mm"], r["penetration_mm"], r["tilt_deg"], 1e3 * r["drift"], r["drift"] <= STILL_TOL,
                  1e3 * r["speed"], r["contacts"]]
        for row, value in zip(rows, values):
            row[v] = value
    e2 = sag_with_double_stiffness(case, settle, mu)
    rows.insert(4, {"robot": name, "quantity": "sag with Young's modulus doubled [mm]", "ours": e2[0],
                    "mujoco": e2[1], **{v: None for v in mj if v != "mujoco"}})
    for q, key in (("MuJoCo: constraint solver iterations per step", "its"),
                   ("MuJoCo: M+h^2K solves that hit the iteration cap, per step", "capped")):
        rows.append({"robot": name, "quantity": q, "ours": None, **{v: r[key] for v, r in mj.items()}})
    return rows, {v: r["state"] for v, r in mj.items()}


def time_mujoco(mj: FlexModel, state, steps: int) -> float:
    mj.restore(state)
    return elapsed(lambda: mj.step(steps)) / steps


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", nargs="+", default=["tripod", "puppy"], choices=sorted(ENV_NAMES))
    p.add_argument("--contact", nargs="+", default=None, choices=["paper", "coulomb"],
                   help="contact laws to time (default: both)")
    p.add_argument("--rounds", type=int, default=3, help="alternating timing rounds (best of each figure)")
    p.add_argument("--steps", type=int, default=168, help="steps per timed run (MuJoCo and ours)")
    p.add_argument("--env-steps", type=int, default=300, help="environment steps per timed run")
    p.add_argument("--settle", type=int, default=300, help="MuJoCo steps to settle before timing")
    a = p.parse_args()
    a.contact = a.contact or ["paper", "coulomb"]
    for name in ("rounds", "steps", "env_steps", "settle"):
        if getattr(a, name) < (2 if name == "steps" else 1):
            p.error(f"--{name.replace('_', '-')} must be at least {2 if name == 'steps' else 1}")
    return a


def setup(a) -> tuple[dict, dict, dict]:
    """Our cases, the MuJoCo models and their settled states; prints the comparability table."""
    cases, mjs, states, facts = {}, {}, {}, []
    for name in a.robots:
        for law in a.contact:
            cases[name, law] = OursCase(name, law, a.steps, a.env_steps)
        ref = cases[name, a.contact[0]]
        mu = getattr(ref.robot.contact, "friction_coefficient", 0.8)
        mjs[name] = {v: FlexModel(ref.robot, DT, mu, **kw) for v, kw in MJ_VARIANTS.items()}
        rows, states[name] = comparability(name, ref, mjs[name], a.settle, a.steps, mu)
        facts += rows
    report(f"comparability: our model ({a.contact[0]} law) vs MuJoCo's flex (standing, h = {DT} s)", facts)
    return cases, mjs, states


def time_rounds(a, cases: dict, mjs: dict, states: dict) -> tuple[dict, dict, list]:
    """Every figure once per round, alternating; seconds per step (or per environment step)."""
    times: dict[tuple, list[float]] = {}
    failures: dict[tuple, int] = {}
    loads = []
    for r in range(a.rounds):
        for name in a.robots:
            for variant in MJ_VARIANTS:
                times.setdefault((name, "mujoco", variant), []).append(
                    time_mujoco(mjs[name][variant], states[name][variant], a.steps))
            for law in a.contact:
                case = cases[name, law]
                for kind in case.controls:
                    times.setdefault((name, law, kind), []).append(case.time_rollout(kind))
                times.setdefault((name, law, "factorize"), []).append(case.time_factorize())
                if case.env is not None:
                    t, fails = case.time_env()
                    times.setdefault((name, law, "env"), []).append(t)
                    failures[name, law] = failures.get((name, law), 0) + fails
        loads.append(os.getloadavg()[0])
        print(f"round {r + 1}/{a.rounds} done, load average {loads[-1]:.2f}")
    return times, failures, loads


def summary_rows(a, cases: dict, times: dict, failures: dict) -> list[dict]:
    best = {k: min(v) for k, v in times.items()}
    rows = []
    for name in a.robots:
        t_mj = best[name, "mujoco", "mujoco"]
        for law in a.contact:
            case, env = cases[name, law], cases[name, law].env is not None
            row = {"robot": name, "contact": law, "mj_stand_ms": 1e3 * t_mj,
                   "mj_default_contact_ms": 1e3 * best[name, "mujoco", "mujoco_default_contact"],
                   "mj_10_its_ms": 1e3 * best[name, "mujoco", "mujoco_10_iterations"]}
            for kind in case.controls:
                row[f"{kind}_ms"] = 1e3 * best[name, law, kind]
                row[f"{kind}_x_mj"] = best[name, law, kind] / t_mj
            row.update({f"{k}_newton_its": v for k, v in case.newton_its.items() if k != "stand"})
            row["linear_solver"] = type(case.sim.newton.solver).__name__
            row["factorize_ms"] = 1e3 * best[name, law, "factorize"]
            row["gait_in_factorizations"] = best[name, law, "gait"] / best[name, law, "factorize"]
            row["env"] = f"{case.env_id}, contact={law}" if env else f"{case.env_id} (not registered)"
            row["env_steps_per_s"] = 1.0 / best[name, law, "env"] if env else None
            row["env_step_x_mj"] = best[name, law, "env"] / t_mj if env else None
            row["env_failures"] = failures.get((name, law))
            rows.append(row)
    return rows


def main() -> None:
    import mujoco

    a = parse_args()
    warnings: list[str] = []
    mujoco.set_mju_user_warning(lambda msg: warnings.append(msg.strip()))
    print(f"MuJoCo {mujoco.__version__}, Python {platform.python_version()}, {os.cpu_count()} cores; "
          f"h = {DT} s; contact laws: {a.contact}; {a.rounds} rounds of {a.steps} steps "
          f"({a.env_steps} environment steps); load average {os.getloadavg()[0]:.2f}")
    cases, mjs, states = setup(a)
    print_warnings(warnings)
    times, failures, loads = time_rounds(a, cases, mjs, states)
    rows = summary_rows(a, cases, times, failures)
    report(f"ours vs MuJoCo flex standing: best of {a.rounds} alternating rounds, {a.steps} steps", rows)
    report("run", [{"mujoco": mujoco.__version__, "rounds": a.rounds, "steps": a.steps,
                    "env_steps": a.env_steps, "load_per_round": loads,
                    "load_at_end": list(os.getloadavg()), "targets_coulomb": TARGETS}])
    print(json.dumps({"benchmark": "bench_vs_mujoco: seconds per step, every round",
                      "times": {"/".join(k): v for k, v in times.items()}}))
    print_targets(rows)


def print_warnings(messages: list[str]) -> None:
    """MuJoCo's warnings, once per kind (their numbers stripped), with how often they came."""
    kinds: dict[str, list] = {}
    for msg in messages:
        kinds.setdefault(re.sub(r"[-+]?\d[\d.e+-]*", "#", msg), []).append(msg)
    for same in kinds.values():
        note = (" [spurious: its elasticity acts, see the sag with E doubled]"
                if "no equality constraints or passive forces" in same[0] else "")
        print(f"MuJoCo warned ({len(same)}x, first shown): {' '.join(same[0].split())}{note}")


def print_targets(rows: list[dict]) -> None:
    """The issue's targets (Coulomb law) beside the figures; the paper law is shown for reference."""
    print("\nissue #15 targets (Coulomb law; the paper law's figures are for reference):")
    for r in rows:
        check = r["contact"] == "coulomb"

        def verdict(ok: bool) -> str:
            return ("OK" if ok else "MISSED") if check else "-"

        env_target = TARGETS["env_steps_per_s"][r["robot"]]
        env = r["env_steps_per_s"]
        print(f"{r['robot']:>6} {r['contact']:>7}: gait {r['gait_x_mj']:.2f}x MuJoCo standing (<= "
              f"{TARGETS['gait_x']}: {verdict(r['gait_x_mj'] <= TARGETS['gait_x'])}), random "
              f"{r['random_x_mj']:.2f}x (<= {TARGETS['random_x']}: {verdict(r['random_x_mj'] <= TARGETS['random_x'])}), "
              f"gait step = {r['gait_in_factorizations']:.1f} factorisations (<= {TARGETS['gait_factorizations']}: "
              f"{verdict(r['gait_in_factorizations'] <= TARGETS['gait_factorizations'])}), "
              + (f"{r['env']} {env:.0f} steps/s with random actions (>= {env_target:.0f}: "
                 f"{verdict(env >= env_target)})" if env is not None else f"{r['env']}: no figure"))


if __name__ == "__main__":
    main()
