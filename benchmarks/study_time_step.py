"""Study: where the time-step error of the fast gaits comes from.

    python benchmarks/study_time_step.py            # everything: 16 CPU-minutes (22 min on a loaded machine)
    python benchmarks/study_time_step.py --quick    # the two fastest gaits only: 5.5 CPU-minutes
    python benchmarks/study_time_step.py --tables speeds,cost

The gaits of /work/shared/cases/fast_gaits_2026-12-03 (Tripod and Puppy ``--speed max``, the
co-designed Tripod's two gaits) and the paper's 72-step walks (``trajopt optimize ROBOT --task
walk``, made in ``--walks`` when missing) are replayed by the protocol of the issue: prep, then
the cycle 10 times, controls joined in time by straight lines (row k at t = (k+1) 33 ms, u_rest
at t = 0), ``Simulator(robot, dt=0.033/n)`` from ``rest_state(u_rest)``, speed over cycles
2-10 in BL/min. Tables (text, then one JSON line each, :func:`common.report`):

1. speed against n = 1..16 (32) physics steps per control step, with the spread of the
   per-cycle speeds over cycles 2-10 (0: periodic motion) and the feet's touchdowns per cycle;
2. one thing changed at a time, study-only code (nothing in soft_envs/ or trajopt/ changes):
   BDF2 through the same Newton solve; stiffness-proportional damping added at fine steps
   (contact springs, foam); the friction's normal force at the step's own solution or the
   average of both steps (IPC's lagged iterations); contact stiffness and slip distance x0.3,
   x3 at 33 ms and fine steps;
3. each source's share of the coarse-vs-fine error E = v(33 ms) - v_fine (mean of n = 8, 16);
4. the lowest modes of the robots standing and the damping ratio implicit Euler gives them at
   33, 8.25 and 2.06 ms, and BDF2 at 33 ms;
5. the speed's change under 1 um of noise on the controls or on the rest state;
6. CPU time (process_time, best of 3, alternating) per simulated second of the Puppy speedmax
   replay and of a 168-step Jacobian rollout (nz = 16) at n = 1..4, Newton iterations per step;
7. implicit Euler at n against 4n on every case, with the cost ratios.

Measured (2026-12-03; docs/fidelity.md has the tables, benchmarks/results/time_step.md the
output). Speed at 33 ms -> fine (mean of 4.1
and 2.1 ms) [BL/min]: Tripod speedmax 26.56 -> 20.85 (E = +27 %), Puppy speedmax 31.34 ->
26.78 (+17 %), co-designed gait 46.28 -> 15.46, its re-optimised gait 37.82 -> -2.94, Tripod
walk 8.485 -> 8.39 (+1 %), Puppy walk 9.21 -> 9.88 (-7 %). No single source explains E:
BDF2 at 33 ms removes 36 % of the Puppy's E and makes the Tripod's motion irregular (-21 %);
the friction's normal force of the current step over-corrects (Tripod 9.72, Puppy 25.35 BL/min
at 33 ms: 295 % and 131 % of E; the trapezoidal average 165 % and 69 %); contact damping of
beta = 33 ms - h added at 2 ms restores the Tripod's 33-ms speed (103 %) but not the Puppy's
(-4 %); k_n and r_s x0.3 / x3 leave E within 3.1-5.2 (Tripod) and 4.2-5.0 BL/min (Puppy).
Implicit Euler's numerical damping is the model's only damping of body vibrations: damping
ratios 0.28-0.79 at 33 ms, 0.02-0.18 at 2 ms for the modes below 30 Hz. 1 um of noise moves
the speed by <= 0.004 BL/min at 33 and 4 ms (periodic motion; the re-optimised co-designed
gait 0.26 at 4 ms); at 1 ms the Tripod's motion is
chaotic (+-0.9 BL/min), its feet bounce (15 -> 48 touchdowns per cycle). n = 4 is within 3 %
of n = 16 on three of the four converging gaits (Puppy walk 3.5 %) at 1.6-1.9x the CPU time
per simulated second of n = 1 in rollouts and 1.96-2.4x in Jacobian rollouts (three runs on a
loaded machine); n = 3: worst 4.6 %, 1.7-2.0x; n = 2: worst 8.6 %, 1.4-1.6x.
"""
from __future__ import annotations

import argparse
import dataclasses
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from common import report

from soft_envs.sim import Simulator, load_robot
from soft_envs.sim.contact.penalty import d2Q, normal_forces
from soft_envs.sim.integrator import NewtonSolver
from soft_envs.sim.linsolve import FactorCache

DT = 0.033                       # the control step, and today's physics step [s]
CASES_DIR = Path("/work/shared/cases/fast_gaits_2026-12-03")
WALKS_DIR = Path("/tmp/studyres")

#: name -> (robot, result file); "cases:" is --cases, "walks:" is --walks (the paper's 72-step walks)
CASES = {
    "tripod_speedmax": ("tripod", "cases:tripod_speedmax.npz"),
    "puppy_speedmax": ("puppy", "cases:puppy_speedmax.npz"),
    "codesign_gait": ("cases:tripod_codesign/robot.toml", "cases:tripod_codesign/tripod_walk.npz"),
    "codesign_reoptimised": ("cases:tripod_codesign/robot.toml", "cases:tripod_codesign/tripod_walk_reoptimised.npz"),
    "tripod_walk72": ("tripod", "walks:tripod_walk.npz"),
    "puppy_walk72": ("puppy", "walks:puppy_walk.npz"),
}
FASTEST = ("tripod_speedmax", "puppy_speedmax")


# ---------------------------------------------------------------------------------- the cases
@dataclasses.dataclass
class Case:
    name: str
    robot: object
    u: np.ndarray            # the played control rows: prep, then the cycle 10 times
    n_prep: int
    n_cycle: int
    cycles: int = 10


def load_case(name: str, cases_dir: Path, walks_dir: Path, tmp: Path, cycles: int = 10) -> Case:
    """The robot and the played controls of case ``name``. The result is copied to ``tmp``
    first: ``Result.load`` rewrites a result's .json sidecar when it does not match its .npz,
    and the shared study cases must not be written."""
    from trajopt.results import Result, ResultFileWarning

    def where(spec):
        kind, rel = spec.split(":", 1) if ":" in spec else (None, spec)
        return {"cases": cases_dir, "walks": walks_dir}[kind] / rel if kind else spec

    robot_spec, res_spec = CASES[name]
    src = where(res_spec)
    dst = tmp / name / src.name
    dst.parent.mkdir(parents=True, exist_ok=True)
    for suffix in (".npz", ".json"):
        if src.with_suffix(suffix).exists():
            shutil.copy(src.with_suffix(suffix), dst.with_suffix(suffix))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResultFileWarning)
        res = Result.load(dst)
    robot = load_robot(str(where(robot_spec)))
    s = res.settings
    n_prep, n_cycle = int(s["n_prep"]), int(s["n_cycle"])
    u = np.asarray(res.u, dtype=np.float64)
    played = np.vstack([u[:n_prep]] + [u[n_prep:n_prep + n_cycle]] * cycles)
    return Case(name, robot, played, n_prep, n_cycle, cycles)


def make_walks(walks_dir: Path) -> None:
    """The paper's 72-step walks (``trajopt optimize ROBOT --task walk``), when missing."""
    for robot in ("tripod", "puppy"):
        if not (walks_dir / f"{robot}_walk.npz").exists():
            print(f"making {walks_dir}/{robot}_walk.npz (trajopt optimize {robot} --task walk)", flush=True)
            subprocess.run([sys.executable, "-m", "trajopt.cli", "optimize", robot, "--task", "walk",
                            "--out", str(walks_dir), "--quiet"], check=True)


def interpolation(K: int, sub: int) -> np.ndarray:
    """``W`` (K*sub, K+1): the controls of the physics steps from ``[u_rest; u]`` (control row k
    at t = (k+1) DT, u_rest at t = 0), joined by straight lines; step j ends at t = (j+1) DT/sub."""
    W = np.zeros((K * sub, K + 1))
    for j in range(K * sub):
        a, r = divmod(j + 1, sub)
        if r == 0:
            W[j, a] = 1.0
        else:
            W[j, a] = 1.0 - r / sub
            W[j, a + 1] = r / sub
    return W


def fine_controls(robot, u: np.ndarray, sub: int) -> np.ndarray:
    return interpolation(len(u), sub) @ np.vstack([robot.u_rest[None], u])


def speed(case: Case, com: np.ndarray, sub: int) -> float:
    """BL/min over cycles 2..cycles from the COM at the physics steps."""
    c = com[::sub]
    i0, i1 = case.n_prep + case.n_cycle, case.n_prep + case.cycles * case.n_cycle
    return float((c[i1, 0] - c[i0, 0]) / ((i1 - i0) * DT) / case.robot.body_length * 60.0)


# ---------------------------------------------------------------------------------- the schemes
class DampedNewton(NewtonSolver):
    """Implicit Euler with a viscous damping force ``-D v`` added: ``Phi += |x - x_{k-1}|_D^2 /
    (2h)`` with a positive semi-definite ``D`` set before every step (:meth:`set_damping`: the
    values of the Hessian pattern, fixed during the step). Robots without fixed nodes only."""

    def __init__(self, system, dt, options=None):
        super().__init__(system, dt) if options is None else super().__init__(system, dt, options)
        assert len(system.free) == system.n_dof
        self._D = None
        self._Ddata = None

    def set_damping(self, ddata: np.ndarray | None) -> None:
        if ddata is None:
            self._D, self._Ddata = None, None
            return
        self._Ddata = ddata / self.dt
        self._D = self.system.pattern.full(self._Ddata)

    def phi(self, x, xt, x_prev, u, history=None) -> float:
        p = super().phi(x, xt, x_prev, u, history)
        if self._D is not None and np.isfinite(p):
            d = (x - x_prev).ravel()
            p += 0.5 * float(d @ (self._D @ d))
        return p

    def phi_assemble(self, x, xt, x_prev, u, project=False, want_hess=True, history=None):
        p, grad, hdata = super().phi_assemble(x, xt, x_prev, u, project, want_hess, history)
        if self._D is not None and np.isfinite(p):
            d = (x - x_prev).ravel()
            Dd = self._D @ d
            grad += Dd
            p += 0.5 * float(d @ Dd)
            if want_hess:
                n = self.system.pattern.nnz
                hdata[:n] += self._Ddata[:n]
        return p, grad, hdata


def rayleigh_damping(beta: float):
    """``D = beta K(x_{k-1})``, K the positive semi-definite (projected) Hessian of E at the
    step's start: stiffness-proportional damping, which implicit Euler at step h adds to a
    mode of frequency w << 1/h with beta ~ h (damping ratio w h / 2)."""
    def damping(sim, x_prev, u, hist):
        _, _, h = sim.system.assemble(x_prev, x_prev, u, project=True, history=hist)
        return beta * h
    return damping


def elastic_damping(beta: float):
    """``D = beta K_FEM(x_{k-1})``: stiffness-proportional (Rayleigh) damping of the foam
    alone, K its element-wise projected Hessian at the step's start."""
    def damping(sim, x_prev, u, hist):
        el = sim.system.elastic
        grad = np.zeros(sim.system.n_dof)
        h = np.zeros(sim.system.pattern.nnz + 1)
        el.assemble_projected(x_prev, x_prev, u, None, grad, h)
        return beta * h
    return damping


def contact_damping(beta: float):
    """``D = beta Q_n''(-y_{k-1})`` on the normal dof of every contact node: the same
    stiffness-proportional damping, on the contact springs only."""
    def damping(sim, x_prev, u, hist):
        c = sim.system.contact
        d = np.zeros(sim.system.pattern.nnz + 1)
        k = np.array([d2Q(-x_prev[n, 1], c.k_n, c.eps_n) for n in c.nodes])
        np.add.at(d, c.diag_slots[3 * c.nodes + 1], beta * k)
        return d
    return damping


@dataclasses.dataclass
class Run:
    com: np.ndarray
    iterations: np.ndarray      # Newton iterations per physics step (summed over fixed-point passes)
    passes: np.ndarray | None = None   # fixed-point passes per step (scheme "implicit_n")
    cpu: float = 0.0
    touching: np.ndarray | None = None  # (K+1, contact nodes): below the ground (N > 0)


def _depth(N: np.ndarray, k: float, eps: float) -> np.ndarray:
    """The depth s below the ground at which the normal penalty pushes with force N (the
    inverse of Q_n'); -1 mm (above the ground) for N = 0."""
    N = np.asarray(N, dtype=np.float64)
    if eps == 0.0:
        s = N / k
    else:
        s = np.where(N < 0.5 * k * eps, np.sqrt(2.0 * eps * np.maximum(N, 0.0) / k), N / k + 0.5 * eps)
    return np.where(N > 0.0, s, -1e-3)


def simulate(robot, uf: np.ndarray, dt: float, scheme: str = "euler", damping=None, x0_shift=None,
             n_weight: float = 1.0, n_tol: float = 1e-3, max_passes: int = 30) -> Run:
    """Roll the physics-step controls ``uf`` out with step ``dt`` from the rest state under
    ``robot.u_rest``. Schemes:

    * ``"euler"``: ``Simulator.rollout`` itself (implicit Euler, the project's step);
    * ``"bdf2"``: BDF2 through the same Newton solve: a solver of step ``h' = 2 dt / 3`` given
      ``x~ = 4/3 x_{k-1} - 1/3 x_{k-2} + h' (4/3 v_{k-1} - 1/3 v_{k-2})`` (a fake ``x_{k-2}``
      with ``2 x_{k-1} - x_{k-2} = x~``), the energy seeing the true ``x_{k-1}``;
      ``v_k = (3 x_k - 4 x_{k-1} + x_{k-2}) / (2 dt)``;
    * ``"damped"``: implicit Euler plus ``damping(sim, x_prev, u, hist)`` (:class:`DampedNewton`);
    * ``"implicit_n"``: implicit Euler with the friction's normal force ``N = (1 - n_weight)
      N_{k-1} + n_weight N_k`` (``n_weight = 1``: the step's own; 0.5: the trapezoidal average)
      by lagged iterations as in IPC: solve with N fixed, set N from the solution, re-solve,
      until ``max |dN_k| <= n_tol * max N_k`` between passes, at most ``max_passes`` solves.
      N enters the energy through the contact nodes' heights in the ``x_prev`` the energy
      sees (the only use of ``x_prev`` in the energy), set to the depths that give N; the
      anchors' update uses the same N.

    ``x0_shift`` (n, 3): added to the rest positions (x, x_prev, x_prev2) before the start."""
    sim = Simulator(robot, dt=dt)
    rest = sim.rest_state(robot.u_rest)
    if x0_shift is not None:
        x = rest.x + x0_shift
        rest = rest.replace(x=x, x_prev=x, x_prev2=x)
    t0 = time.process_time()
    if scheme == "euler":
        tr = sim.rollout(uf, x0=rest, check_bounds=False)
        return Run(tr.com, tr.newton_iterations, cpu=time.process_time() - t0,
                   touching=tr.x[:, sim.system.contact.nodes, 1] < 0.0)
    system = sim.system
    masses = robot.node_masses
    K = len(uf)
    xs = np.empty((K + 1,) + rest.x.shape)
    xs[0] = rest.x
    its = np.zeros(K, dtype=np.int64)
    passes = np.ones(K, dtype=np.int64)
    cache = FactorCache()
    hist = rest.history
    x1, x2, x3 = np.array(rest.x), np.array(rest.x), None
    if scheme == "bdf2":
        newton = NewtonSolver(system, 2.0 * dt / 3.0)
        v1 = np.zeros_like(x1)
        v2 = np.zeros_like(x1)
    elif scheme == "damped":
        newton = DampedNewton(system, dt)
    else:
        newton = sim.newton
    for k in range(K):
        u = uf[k]
        if scheme == "bdf2":
            hp = newton.dt
            xt = (4.0 * x1 - x2) / 3.0 + hp * (4.0 * v1 - v2) / 3.0
            x, info = newton.step(x1, 2.0 * x1 - xt, u, k, cache=cache, history=hist)
            its[k] = info.iterations
            v = (3.0 * x - 4.0 * x1 + x2) / (2.0 * dt)
            hist = system.next_history(x, x1, hist)
            v2, v1 = v1, v
        elif scheme == "damped":
            newton.set_damping(damping(sim, x1, u, hist))
            x, info = newton.step(x1, x2, u, k, x_prev3=x3, cache=cache, history=hist)
            its[k] = info.iterations
            hist = system.next_history(x, x1, hist)
        elif scheme == "implicit_n":
            c = system.contact
            xt = 2.0 * x1 - x2
            n_start = normal_forces(x1, c.nodes, c.k_n, c.eps_n)
            n_prev, xp = n_start, x1
            for p in range(max_passes):
                x, info = newton.step(xp, 2.0 * xp - xt, u, k, cache=cache, history=hist)
                its[k] += info.iterations
                n_sol = normal_forces(x, c.nodes, c.k_n, c.eps_n)
                if np.abs(n_sol - n_prev).max() <= n_tol * max(n_sol.max(), 1e-12):
                    break
                n_prev = n_sol
                xp = x1.copy()
                xp[c.nodes, 1] = -_depth((1.0 - n_weight) * n_start + n_weight * n_sol, c.k_n, c.eps_n)
            passes[k] = p + 1
            hist = system.next_history(x, xp, hist)
        else:
            raise ValueError(scheme)
        x3, x2, x1 = x2, x1, x
        xs[k + 1] = x
    com = np.einsum("kni,n->ki", xs, masses) / masses.sum()
    return Run(com, its, passes if scheme == "implicit_n" else None, time.process_time() - t0,
               touching=xs[:, system.contact.nodes, 1] < 0.0)


def replay(case: Case, sub: int, robot=None, u=None, **kw) -> tuple[float, Run]:
    """(speed [BL/min], Run) of the case's controls at ``sub`` physics steps per control step."""
    robot = case.robot if robot is None else robot
    run = simulate(robot, fine_controls(robot, case.u if u is None else u, sub), DT / sub, **kw)
    return speed(case, run.com, sub), run


def with_contact(robot, **changes):
    return robot.replace(contact=dataclasses.replace(robot.contact, **changes))


# ---------------------------------------------------------------------------------- the tables
def per_cycle(case: Case, com: np.ndarray, sub: int) -> np.ndarray:
    """Speed of every cycle [BL/min] (cycle 1 first)."""
    c = com[::sub]
    idx = case.n_prep + case.n_cycle * np.arange(case.cycles + 1)
    return np.diff(c[idx, 0]) / (case.n_cycle * DT) / case.robot.body_length * 60.0


def measured(case: Case, sub: int, variant: str = "euler", **kw) -> dict:
    """One replay as a row: speed, the spread of the per-cycle speeds over cycles 2..10 (0:
    the motion is periodic), Newton iterations per physics step, CPU seconds."""
    v, run = replay(case, sub, **kw)
    cyc = per_cycle(case, run.com, sub)[1:]
    i0 = (case.n_prep + case.n_cycle) * sub
    t = run.touching[i0:]
    row = {"case": case.name, "variant": variant, "n": sub, "h_ms": 1e3 * DT / sub, "speed": v,
           "cycle_spread": float(cyc.max() - cyc.min()),
           "touchdowns_per_cycle": float((t[1:] & ~t[:-1]).sum() / (case.cycles - 1)),
           "its_per_step": float(run.iterations.mean()), "cpu_s": run.cpu}
    if run.passes is not None:
        row["passes_per_step"] = float(run.passes.mean())
    print(f"  {case.name:21s} {variant:32s} n={sub:2d}: {v:6.2f} BL/min  ({run.cpu:.1f} s)", flush=True)
    return row


def speed_table(cases, subs_of) -> tuple[list[dict], dict]:
    """Table 1: every case at every number ``n`` of physics steps per control step (h = 33/n
    ms). Returns the rows and ``{case: {n: speed}}``; each row's ``vs_fine_pct`` is against the
    case's fine reference, the mean of n = 8 and 16 (h = 4.1 and 2.1 ms)."""
    rows, speeds = [], {}
    for case in cases:
        got = speeds.setdefault(case.name, {})
        mine = [measured(case, n) for n in subs_of(case.name)]
        for r in mine:
            got[r["n"]] = r["speed"]
        ref = fine_reference(got)
        for r in mine:
            r["vs_fine_pct"] = 100.0 * (r["speed"] / ref - 1.0)
        rows += mine
    return rows, speeds


def fine_reference(got: dict) -> float:
    return float(np.mean([got[n] for n in (8, 16) if n in got]))


def source_table(case: Case, base: dict, level: str) -> list[dict]:
    """Table 2: one thing changed at a time (``base``: the case's speeds of table 1 by n).
    ``level``: "full" (the two fastest gaits: fine-step runs at n = 4, 8 and 16 too),
    "fine8" (fine-step runs at n = 8), "coarse" (33 ms only)."""
    rows = []

    def add(variant, n, **kw):
        r = measured(case, n, variant, **kw)
        r["change"] = r["speed"] - base[n]
        rows.append(r)
        return r

    full = level == "full"
    fine = {"full": (8, 16), "fine8": (8,), "coarse": ()}[level]
    # 1. the integrator's damping: BDF2 at 33 ms (and at a finer step: the same limit?)
    add("bdf2", 1, scheme="bdf2")
    if level != "coarse":
        add("bdf2", 4 if full else 8, scheme="bdf2")
    # ... and damping added back at fine steps: stiffness-proportional, beta = 33 ms - h
    for n in (4, 16) if full else fine:
        add("contact damping beta=33ms-h", n, scheme="damped", damping=contact_damping(DT - DT / n))
    if full:
        add("foam damping beta=33ms-h", 4, scheme="damped", damping=elastic_damping(DT - DT / 4))
    # 2. the normal force of the friction at the step's own solution (lagged iterations), and
    #    the average of the two
    for w, label in ((1.0, "current-step N"), (0.5, "trapezoidal N")):
        add(label, 1, scheme="implicit_n", n_weight=w)
        if full:
            add(label, 4, scheme="implicit_n", n_weight=w)
    if full:
        add("current-step N", 16, scheme="implicit_n")
    # 3. and 4. contact stiffness and slip distance, at 33 ms and at fine steps
    for key in ("stiffness", "slip_distance"):
        for f in (0.3, 3.0):
            robot = with_contact(case.robot, **{key: getattr(case.robot.contact, key) * f})
            for n in (1,) + fine:
                add(f"{key} x{f:g}", n, robot=robot)
    return rows


def shares(case_name: str, base: dict, rows: list[dict]) -> dict:
    """Table 3: each source's share of the coarse-vs-fine error ``E = v(33 ms) - v_fine``:
    ``(v(33 ms) - v'(33 ms)) / E`` for a variant v' that removes the source at 33 ms;
    ``(v'(h) - v(h)) / (v(33 ms) - v(h))`` for damping added back at a fine step h (the part
    of the error it restores); and the error itself with the contact parameters scaled."""
    v1, ref = base[1], fine_reference(base)
    err = v1 - ref
    got = {(r["variant"], r["n"]): r["speed"] for r in rows if r["case"] == case_name}
    out = {"case": case_name, "v_33ms": v1, "v_fine": ref, "error": err}
    out["share_bdf2_pct"] = 100.0 * (v1 - got[("bdf2", 1)]) / err
    n_d = max([n for (v, n) in got if v == "contact damping beta=33ms-h"], default=None)
    out["restored_by_contact_damping_pct"] = (100.0 * (got[("contact damping beta=33ms-h", n_d)] - base[n_d])
                                              / (v1 - base[n_d]) if n_d else None)
    out["share_current_N_pct"] = 100.0 * (v1 - got[("current-step N", 1)]) / err
    out["share_trapezoidal_N_pct"] = 100.0 * (v1 - got[("trapezoidal N", 1)]) / err
    for key, short in (("stiffness", "k_n"), ("slip_distance", "r_s")):
        for f in (0.3, 3.0):
            v = f"{key} x{f:g}"
            fine = [got[(v, n)] for n in (8, 16) if (v, n) in got]
            out[f"error_{short}_x{f:g}"] = got[(v, 1)] - float(np.mean(fine)) if fine else None
    return out


def fragility_table(case: Case, subs, seeds: int) -> list[dict]:
    """Table 5: the speed's response to tiny changes at a given step: the controls + 1 um of
    noise (every entry), and the rest state + 1 um of noise (every node coordinate)."""
    rows = []
    n_nodes = case.robot.mesh.n_nodes
    for n in subs:
        v0 = replay(case, n)[0]
        du, dx = [], []
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            du.append(replay(case, n, u=case.u + 1e-6 * rng.standard_normal(case.u.shape))[0] - v0)
            dx.append(replay(case, n, x0_shift=1e-6 * rng.standard_normal((n_nodes, 3)))[0] - v0)
        rows.append({"case": case.name, "n": n, "h_ms": 1e3 * DT / n, "speed": v0,
                     "controls_1um_max_change": float(np.abs(du).max()),
                     "state_1um_max_change": float(np.abs(dx).max()), "seeds": seeds})
        print(f"  {case.name} n={n}: {v0:.2f}, +-{np.abs(du).max():.3f} (controls), +-{np.abs(dx).max():.3f} (state)",
              flush=True)
    return rows


# ---------------------------------------------------------------------------------- modes
def _damping_ratio(z: complex, h: float) -> float:
    s = np.log(z) / h
    return float(-s.real / abs(s))


def ie_ratio(w: float, h: float) -> float:
    """Damping ratio implicit Euler gives an undamped mode of angular frequency w at step h."""
    return _damping_ratio(1.0 / (1.0 - 1j * w * h), h)


def bdf2_ratio(w: float, h: float) -> float:
    r = np.roots([3.0 - 2.0j * w * h, -4.0, 1.0])
    return _damping_ratio(r[np.argmax(abs(r))], h)


def mode_table(robot_name: str, robot, count: int = 8) -> list[dict]:
    """Table 4: the lowest modes of the robot standing at rest (Hessian of E at the rest state,
    lumped masses; contact and friction springs included, cables slack at u_rest), the share
    of each mode's stiffness in the contact term, and the damping ratio implicit Euler gives it
    at h = 33, 8.25 and 2.06 ms, and BDF2 at 33 ms."""
    sim = Simulator(robot)
    rest = sim.rest_state(robot.u_rest)
    x, u, system = np.array(rest.x), robot.u_rest, sim.system
    H = sim.hessian(x, x, u, rest.history).toarray()
    hd = np.zeros(system.pattern.nnz + 1)
    system.contact.assemble(x, x, u, rest.history[system.terms.index(system.contact)],
                            np.zeros(system.n_dof), hd, True)
    Hc = system.pattern.full(hd).toarray()
    s = 1.0 / np.sqrt(system.mass)
    w2, V = np.linalg.eigh(s[:, None] * H * s[None, :])
    phi = s[:, None] * V
    rows = []
    for k in range(count):
        w = float(np.sqrt(max(w2[k], 0.0)))
        rows.append({"robot": robot_name, "mode": k, "f_hz": w / (2 * np.pi),
                     "contact_share": float(phi[:, k] @ Hc @ phi[:, k] / w2[k]),
                     "zeta_ie_33ms": ie_ratio(w, DT), "zeta_ie_8.25ms": ie_ratio(w, DT / 4),
                     "zeta_ie_2.06ms": ie_ratio(w, DT / 16), "zeta_bdf2_33ms": bdf2_ratio(w, DT)})
    f = np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi)
    rows.append({"robot": robot_name, "mode": f"all {len(f)}: {int((f < 10).sum())} below 10 Hz, "
                 f"{int((f < 30).sum())} below 30 Hz, {int((f < 100).sum())} below 100 Hz",
                 "f_hz": float(f.max()), "contact_share": None, "zeta_ie_33ms": None, "zeta_ie_8.25ms": None,
                 "zeta_ie_2.06ms": None, "zeta_bdf2_33ms": None})
    return rows


# ---------------------------------------------------------------------------------- cost
def cost_table(case: Case, subs=(1, 2, 3, 4), rounds: int = 3, nz: int = 16, K: int = 168) -> list[dict]:
    """Table 6: CPU time (time.process_time, best of ``rounds``, the n measured alternately in
    every round) per simulated second of the case's replay and of a K-step Jacobian rollout
    (``rollout(u, dudz=...)`` with nz random columns, dudz joined by straight lines like u),
    at n physics steps per control step; ratios to n = 1; Newton iterations per physics step."""
    robot = case.robot
    rng = np.random.default_rng(0)
    dudz = 1e-3 * rng.standard_normal((K, robot.n_motors, nz))
    jobs = {}
    for n in subs:
        sim = Simulator(robot, dt=DT / n)
        rest = sim.rest_state(robot.u_rest)
        W = interpolation(K, n)
        jobs[n] = (sim, rest, fine_controls(robot, case.u, n), W @ np.vstack([robot.u_rest[None], case.u[:K]]),
                   np.einsum("jk,kmz->jmz", W[:, 1:], dudz))
    best = {(n, kind): np.inf for n in subs for kind in ("replay", "jacobian")}
    its = {}
    for _ in range(rounds):
        for n in subs:
            sim, rest, uf, uj, dj = jobs[n]
            t0 = time.process_time()
            tr = sim.rollout(uf, x0=rest, check_bounds=False)
            best[(n, "replay")] = min(best[(n, "replay")], time.process_time() - t0)
            t0 = time.process_time()
            tj = sim.rollout(uj, x0=rest, dudz=dj, check_bounds=False)
            best[(n, "jacobian")] = min(best[(n, "jacobian")], time.process_time() - t0)
            its[n] = (float(tr.newton_iterations.mean()), float(tj.newton_iterations.mean()))
    sim_s = {"replay": len(case.u) * DT, "jacobian": K * DT}
    rows = []
    for n in subs:
        r = {"case": case.name, "n": n, "h_ms": 1e3 * DT / n}
        for kind in ("replay", "jacobian"):
            r[f"{kind}_s_per_sim_s"] = best[(n, kind)] / sim_s[kind]
            r[f"{kind}_ratio"] = best[(n, kind)] / best[(subs[0], kind)]
        r["replay_its_per_step"], r["jacobian_its_per_step"] = its[n]
        r["replay_its_per_control_step"] = n * its[n][0]
        rows.append(r)
    return rows


def candidates_table(speeds: dict, cost: list[dict]) -> list[dict]:
    """Table 7: implicit Euler at n physics steps per control step against 4n (the convergence
    test) on every case, with the cost ratios of table 6. ``worst_converging_pct``: the worst
    case among the gaits that converge (the two speedmax gaits and the 72-step walks; the
    co-designed gaits swing without trend at fine steps, table 5)."""
    rows = []
    ratio = {r["n"]: r for r in cost}
    for n in sorted({n for got in speeds.values() for n in got if 4 * n in got}):
        row = {"n": n, "h_ms": 1e3 * DT / n}
        worst = 0.0
        for name, got in speeds.items():
            d = 100.0 * (got[n] / got[4 * n] - 1.0) if n in got and 4 * n in got else None
            row[f"{name}_vs_4n_pct"] = d
            if d is not None and not name.startswith("codesign"):
                worst = max(worst, abs(d))
        row["worst_converging_pct"] = worst
        row["replay_cost_ratio"] = ratio[n]["replay_ratio"] if n in ratio else None
        row["jacobian_cost_ratio"] = ratio[n]["jacobian_ratio"] if n in ratio else None
        rows.append(row)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the two fastest gaits, fewer steps, seeds and rounds")
    ap.add_argument("--cases", type=Path, default=CASES_DIR, help="the study cases (default %(default)s)")
    ap.add_argument("--walks", type=Path, default=WALKS_DIR,
                    help="where the paper's 72-step walks are, made there when missing (default %(default)s)")
    ap.add_argument("--tables", default="speeds,sources,modes,fragility,cost",
                    help="comma-separated subset of speeds,sources,modes,fragility,cost (candidates need speeds and cost)")
    args = ap.parse_args(argv)
    tables = set(args.tables.split(","))
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    names = list(FASTEST) if args.quick else list(CASES)
    if not args.quick and any(n.endswith("walk72") for n in names):
        args.walks.mkdir(parents=True, exist_ok=True)
        make_walks(args.walks)
    t_start = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        cases = {n: load_case(n, args.cases, args.walks, Path(tmp)) for n in names}
    speeds = {}
    if "speeds" in tables or "sources" in tables:
        print("table 1: speed against the physics step", flush=True)

        def subs_of(name):
            if args.quick:
                return (1, 2, 4, 8, 16)
            if name.endswith("walk72"):
                return (1, 2, 3, 4, 8, 12, 16)
            return (1, 2, 3, 4, 6, 8, 12, 16) + ((24, 32) if name in FASTEST else ())
        rows, speeds = speed_table(cases.values(), subs_of)
        report("speed [BL/min] against the physics step h = 33 ms / n (controls joined by straight lines)", rows)
    if "sources" in tables:
        print("table 2: one source changed at a time", flush=True)
        src, share = [], []
        for name, case in cases.items():
            level = "full" if name in FASTEST else "coarse" if name.endswith("walk72") else "fine8"
            got = source_table(case, speeds[name], level)
            src += got
            share.append(shares(name, speeds[name], got))
        report("one thing changed at a time (change: against implicit Euler at the same n)", src)
        report("share of the coarse-vs-fine error E = v(33 ms) - v_fine (v_fine: mean of n = 8 and 16; "
               "error_*: E with the contact parameter scaled, v_fine then from n = 8 (and 16))", share)
    if "modes" in tables:
        print("table 4: modes of the robots standing", flush=True)
        rows = []
        for name in ("tripod", "puppy"):
            rows += mode_table(name, load_robot(name))
        report("lowest modes standing at rest and the numerical damping ratio of each scheme", rows)
    if "fragility" in tables:
        print("table 5: fragility", flush=True)
        rows = []
        for name, case in cases.items():
            if name in FASTEST:
                subs = (1, 8) if args.quick else (1, 8, 32)
                seeds = 1 if args.quick else 2
            else:
                subs, seeds = (8,), 1
            rows += fragility_table(case, subs, seeds)
        report("speed change under 1 um of noise on the controls or on the rest state", rows)
    if "cost" in tables:
        print("table 6: cost", flush=True)
        cost = cost_table(cases["puppy_speedmax"], rounds=1 if args.quick else 3)
        report("CPU time per simulated second (Puppy speedmax; best of rounds, alternating)", cost)
        if speeds:
            report("convergence test: implicit Euler at n against 4n, with the cost ratios to n = 1",
                   candidates_table(speeds, cost))
    print(f"\ntotal wall time {time.time() - t_start:.0f} s")


if __name__ == "__main__":
    main()
