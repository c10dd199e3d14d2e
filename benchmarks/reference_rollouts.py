"""Reference rollouts for behaviour-preserving refactors: record before, compare after.

    python benchmarks/reference_rollouts.py record refs/before.npz
    python benchmarks/reference_rollouts.py compare refs/before.npz [--rtol 1e-10]
    python benchmarks/reference_rollouts.py record refs/coulomb.npz --contact coulomb

``--contact coulomb`` runs the same cases with the robots' ``[contact] model`` set to the
Coulomb law (keys ``<case>_coulomb``); the default is the paper's law, named explicitly (the
robot files' default is the Coulomb law since issue #31; recordings made before it, keys
without a suffix, were made with the paper's law and compare unchanged).
Since issue #27 ``sim.rest_state()`` is a State that carries the rest state's loaded stick
anchors; a Coulomb recording made before, when it was a bare array (anchors reset where the
nodes stood), is compared with ``--bare-start``. Under the paper's law (no anchors) both starts
are the same.

Cases (both shipped robots): a smooth gait, seeded random controls within the motor bounds
(reversing at the motors' speed limit) and zero controls, in length control; a gait in tension
control; the gait on a 10-degree slope; each with exact sensitivities of the whole rollout
(a seeded random ``dudz``), the adjoint gradient of a COM objective, and the energy, gradient
and Hessian at a mid-rollout state. ``compare`` reports the largest relative difference of
each array (``|a - b|_max / |b|_max``) and exits 1 when one exceeds ``--rtol``.

Only the public API of :mod:`soft_envs.sim` is used, so the script runs unchanged on both
sides of a refactor. The cases are those of the regression test, ``tests/data/make_reference.py``
(``cases(K)``), with longer rollouts.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import numpy as np

from soft_envs.sim import Simulator

K = 60          # steps per case: long enough for contacts and cables to switch many times
NZ = 5          # parameters of the random dudz


def _load_case_generator():
    """``tests/data/make_reference.py``: the regression test's cases, one definition for both."""
    path = Path(__file__).resolve().parents[1] / "tests" / "data" / "make_reference.py"
    spec = importlib.util.spec_from_file_location("make_reference", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cases(contact: str = "paper"):
    """The regression test's cases (smooth gait, random and zero controls, tension control, a
    10-degree slope; both robots), ``K`` steps each, the robots under the contact law
    ``contact``; the keys of a law other than the paper's end in ``_<contact>``."""
    for key, robot, kw, u in _load_case_generator().cases(K, contact=contact):
        yield (key if contact == "paper" else f"{key}_{contact}"), robot, kw, u


def record(ref_points: dict | None = None, contact: str = "paper",
           bare_start: bool = False) -> dict[str, np.ndarray]:
    """Every case's arrays; ``ref_points`` {case: (x, x_prev, u)} fixes where E, its gradient
    and Hessian are evaluated (compare uses the reference's points)."""
    ref_points = ref_points or {}
    out: dict[str, np.ndarray] = {}
    for key, robot, kw, u in cases(contact):
        sim = Simulator(robot, dt=0.033, **kw)
        x0 = sim.rest_state()              # a State since issue #27 (an array before)
        if bare_start:                     # the rest positions alone: anchors where the nodes stand
            x0 = x0.x
        rng = np.random.default_rng(99)
        dudz = rng.standard_normal((len(u), robot.n_motors, NZ)) * 1e-3
        traj = sim.rollout(u, x0=x0, dudz=dudz, store_dxdz=True)
        out[f"{key}/x0"] = np.array(getattr(x0, "x", x0))
        out[f"{key}/x"] = traj.x
        out[f"{key}/com"] = traj.com
        out[f"{key}/gamma"] = traj.cable_deformation
        out[f"{key}/dxdz"] = traj.dxdz
        out[f"{key}/dcomdz"] = traj.dcomdz
        out[f"{key}/dgammadz"] = traj.dgammadz
        # adjoint gradient of O = sum_k c_k . w (COM moved along w)
        w = np.array([1.0, 0.3, -0.5])
        dobj = np.broadcast_to(robot.node_masses[None, :, None] / robot.total_mass * w,
                               traj.x.shape).copy()
        out[f"{key}/adjoint_dOdz"] = sim.rollout_gradient(u, dobj, x0=x0, dudz=dudz, traj=traj)
        # E and its derivatives at a fixed point away from equilibrium (near equilibrium the
        # gradient is a small difference of large forces): the recorded mid-rollout state plus
        # seeded noise; compare evaluates the code under test at the reference's point
        k = len(u) // 2
        noise = np.random.default_rng(7).normal(scale=2e-4, size=traj.x[k].shape)
        xk, xp, uk = ref_points.get(key, (traj.x[k + 1] + noise, traj.x[k], u[k]))
        out[f"{key}/eval_x"], out[f"{key}/eval_xp"], out[f"{key}/eval_u"] = xk, xp, uk
        out[f"{key}/energy"] = np.array(sim.energy(xk, xp, uk))
        out[f"{key}/gradient"] = sim.gradient(xk, xp, uk)
        out[f"{key}/hessian"] = sim.hessian(xk, xp, uk).toarray()
        print(f"recorded {key}", file=sys.stderr)
    return out


def compare(ref: dict[str, np.ndarray], new: dict[str, np.ndarray], rtol: float) -> bool:
    ok = True
    width = max(len(k) for k in ref)
    for k in sorted(ref):
        a, b = new.get(k), ref[k]
        if a is None or a.shape != b.shape:
            print(f"{k.ljust(width)}  MISSING or shape {None if a is None else a.shape} != {b.shape}")
            ok = False
            continue
        scale = np.abs(b).max()
        rel = float(np.abs(a - b).max() / scale) if scale > 0 else float(np.abs(a - b).max())
        bad = rel > rtol
        ok &= not bad
        print(f"{k.ljust(width)}  {rel:.2e}{'  FAIL' if bad else ''}")
    return ok


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("action", choices=["record", "compare"])
    p.add_argument("path", type=Path)
    p.add_argument("--rtol", type=float, default=1e-10)
    p.add_argument("--contact", default="paper", help="contact law of every case (default: paper, the law of "
                   "every recording made before the robot files' default became the Coulomb law)")
    p.add_argument("--bare-start", action="store_true",
                   help="start from the rest positions as a bare array, stick anchors where the nodes stand "
                        "(what x0=sim.rest_state() meant before issue #27 made it a State with its loaded anchors)")
    a = p.parse_args(argv)
    if a.action == "record":
        new = record(contact=a.contact, bare_start=a.bare_start)
        a.path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(a.path, **new)
        print(f"wrote {a.path} ({len(new)} arrays)")
        return 0
    with np.load(a.path) as f:
        ref = {k: f[k] for k in f.files}
    cases_ = {k.rsplit("/", 1)[0] for k in ref}
    points = {c: (ref[f"{c}/eval_x"], ref[f"{c}/eval_xp"], ref[f"{c}/eval_u"])
              for c in cases_ if f"{c}/eval_x" in ref}
    new = record(points, contact=a.contact, bare_start=a.bare_start)
    ok = compare(ref, new, a.rtol)
    print("all within rtol" if ok else "DIFFERENCES above rtol")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
