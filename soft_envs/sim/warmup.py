"""Compiling the simulator's numba kernels ahead of their first use.

Every kernel is ``@njit(cache=True)``: the first run on a machine compiles them (about 30 s of
CPU time for a gait optimisation) and writes them to numba's cache (``__pycache__`` beside the
sources, or ``$NUMBA_CACHE_DIR``); later runs load them in milliseconds.

The largest kernel, the elastic term's projected Hessian (the Newton solver's fallback, almost
half of the compile time), is first needed only when a step's exact Hessian is not positive
definite, typically during a gait optimisation's seed search. :func:`compile_ahead` says that
the kernels are being compiled and, when a core is idle, compiles that one in a child process
(a thread would share the interpreter lock with the caller, and numba compiles mostly in
Python) while the caller sets up its simulation, which compiles the kernels of a plain step at
the same time on another core: the two compile disjoint sets of kernels. On a busy machine a
child only takes CPU time from the caller, so none is started there.

``python -m soft_envs.sim.warmup [ROBOT]`` compiles every kernel once, e.g. after installing,
those of a robot with a box too (the carry and push tasks' contact, :func:`compile_box_kernels`;
``--no-box``: not those). ``--all`` compiles those of every variant of :data:`VARIANTS` (both
contact laws, on the plane and on a height field, and the box), in ``--jobs`` processes
(:func:`compile_variants`): what the test suite needs, compiled once before its workers start
rather than by each of them at the same time.
"""
from __future__ import annotations

import contextlib
import importlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Iterator, TextIO

import numpy as np

from .timing import DEFAULT_DT

__all__ = ["compile_kernels", "compile_box_kernels", "kernels_cached", "compile_ahead", "idle_core", "VARIANTS",
           "compile_variant", "compile_variants", "variants_cached"]

#: kernels whose cache entries tell whether the simulator has been compiled on this machine
_SENTINELS = (("soft_envs.sim.materials", "fem_assemble"),
              ("soft_envs.sim.psd_projection", "fem_assemble_projected"),
              ("soft_envs.sim.cables", "cable_length_gradients"))
#: the kernels' variants :func:`compile_variants` compiles, each with a kernel whose cache entry
#: tells whether it is compiled: the robot's own contact law on its own ground first (the kernels
#: every variant shares), then each contact law on the plane and on a height field, and a box
VARIANTS = {"own": _SENTINELS,
            "coulomb": (("soft_envs.sim.contact.coulomb", "coulomb_assemble"),),
            "paper": (("soft_envs.sim.contact.paper", "contact_assemble"),),
            "coulomb-field": (("soft_envs.sim.contact.coulomb_field", "_assemble"),),
            "paper-field": (("soft_envs.sim.contact.paper_field", "_assemble"),),
            "box": (("soft_envs.sim.contact.box_sensitivity", "prev_product"),)}
#: the order of the variants after "own" (the box, the largest, first; a field variant before
#: the other laws, so that the field's surface kernels are compiled once, not by two at a time)
_STAGE_TWO = ("box", "coulomb-field", "coulomb", "paper", "paper-field")
#: longest wait for the child [s] (it takes ~15 s of CPU time); past it the caller goes on
_WAIT = 300.0
#: "0": compile in the caller's process only, as numba does by default; "1": always start the
#: child; unset or "auto": start it when a core is idle (a busy machine gains nothing from it)
ENV_SWITCH = "SOFT_ENVS_COMPILE_AHEAD"


def idle_core() -> bool:
    """Whether a core is free for a child process: the cores this process may use minus the
    1-minute load average is at least one (without a load average: two cores or more)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:                                 # not Linux
        cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):                      # Windows
        return cores >= 2
    return cores - load >= 1.0


def kernels_cached(sentinels=_SENTINELS) -> bool:
    """Whether numba's cache holds the simulator's kernels for the current sources (a look at
    the cache index of three kernels, or of ``sentinels``; False when the cache cannot be
    inspected)."""
    try:
        for module, name in sentinels:
            cache = getattr(importlib.import_module(module), name)._cache
            if not cache._cache_file._load_index():       # {} when absent or stale
                return False
    except Exception:                                      # another numba's internals
        return False
    return True


def compile_kernels(robot, *, dt: float = DEFAULT_DT, gravity=(0.0, -9.81, 0.0), control: str = "length",
                    everything: bool = True) -> None:
    """Compile (or load from numba's cache) the kernels a simulation of ``robot`` needs, with
    the argument types a real run passes: the elastic term's projected Hessian (the Newton
    solver's fallback, the largest kernel: 13.5 of the ~30 s of CPU time); with ``everything``
    before it a 3-step rollout from the initial placement with forward sensitivities (paper
    eqs. 10-11), the adjoint gradient, cable tensions and the body frame, and after it every
    term's projected Hessian. Without ``everything`` (what :func:`compile_ahead`'s
    child does) nothing a plain step needs is compiled, so the child and the caller, which
    compiles those while it sets up, never compile the same kernel."""
    from .kinematics import BodyFrame
    from .simulator import Simulator
    sim = Simulator(robot, dt=dt, gravity=gravity, control=control)
    system = sim.system
    x = sim.initial_placement()
    x.flags.writeable = False             # as the system passes positions to the terms' kernels
    u = np.tile(robot.u_rest, (3, 1)) if control == "length" else np.zeros((3, robot.n_motors))

    def projected():
        system.elastic.assemble_projected(x, x, u[0], None, np.zeros(system.n_dof),
                                          np.zeros(system.pattern.nnz + 1))
    if not everything:
        projected()
        return
    dudz = np.full((3, robot.n_motors, 1), 1e-3)
    start = sim.state_at_rest(x)          # read-only arrays, as every step passes them
    traj = sim.rollout(u, x0=start, dudz=dudz)
    sim.rollout_gradient(u, np.zeros_like(traj.x), dudz=dudz, traj=traj)
    sim.cable_tension(traj.x[-1], u[-1])
    BodyFrame(x, robot.node_masses).rotation(traj.x[-1])
    projected()                           # last: a child of compile_ahead's may have cached them meanwhile
    system.assemble(x, start.x, u[0], True, True, start.history)


def compile_box_kernels(robot, *, dt: float = DEFAULT_DT) -> None:
    """Compile (or load) the kernels of a box on ``robot`` (:func:`~soft_envs.sim.with_box`: its
    contact with the robot and their sensitivities), by :func:`compile_kernels` of the robot
    carrying a small box on its top; ``robot`` itself must have no box."""
    from .box import Box, with_box
    p = robot.mesh.points
    top = float(p[:, 1].max())
    size = 0.2 * float(robot.body_length)
    box = Box(size=(size, size, size), center=(float(p[:, 0].mean()), top + 0.5 * size, float(p[:, 2].mean())),
              mass=0.1 * float(robot.total_mass))
    compile_kernels(with_box(robot, box), dt=dt)


def variants_cached(names=tuple(VARIANTS)) -> bool:
    """Whether numba's cache holds the kernels of each of the :data:`VARIANTS` ``names``."""
    return all(kernels_cached(VARIANTS[name]) for name in names)


def compile_variant(robot, name: str, *, dt: float = DEFAULT_DT) -> None:
    """Compile (or load) the kernels of the variant ``name`` of :data:`VARIANTS` of ``robot`` (a
    robot without a box): ``"own"`` the robot as it is, ``"coulomb"``/``"paper"`` with that
    contact law on the plane, ``"coulomb-field"``/``"paper-field"`` on a rough height field,
    ``"box"`` carrying a box (:func:`compile_box_kernels`)."""
    import dataclasses
    from .ground import HeightField
    if name not in VARIANTS:
        raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {name!r}")
    if name == "box":
        compile_box_kernels(robot, dt=dt)
        return
    if name != "own":
        law, _, field = name.partition("-")
        robot = robot.replace(contact=dataclasses.replace(robot.contact, model=law),
                              ground=HeightField.rough(0.002, 0.1) if field else None)
    compile_kernels(robot, dt=dt)


def compile_variants(robot_spec: str | os.PathLike = "tripod", names=tuple(VARIANTS), *, jobs: int = 2,
                     out: TextIO | None = None) -> float:
    """Compile the kernels of the :data:`VARIANTS` ``names`` of ``robot_spec`` (a shipped robot's
    name or a robot.toml path) into numba's cache, in up to ``jobs`` child processes
    (``python -m soft_envs.sim.warmup ROBOT --variant NAME``): ``"own"`` first (with the Newton
    fallback's projected Hessian in a child beside it, as :func:`compile_ahead` does), since
    every variant shares its kernels; then the others, the box (the largest) first, a child
    started as soon as one ends. Variants already cached are skipped; no child is left running
    when this raises. Returns the seconds it took; raises RuntimeError naming the
    variant whose child failed (its last line of error)."""
    for n in names:
        if n not in VARIANTS:
            raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {n!r}")
    names = [n for n in names if not variants_cached((n,))]
    t0 = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=_pythonpath())
    running: list = []
    try:
        for stage in range(2):
            if stage == 0:
                queue = [["--ahead"], ["--variant", "own"]] if "own" in names else []
            else:                                   # the robot's own law is one of them: cached now
                queue = [["--variant", n] for n in _STAGE_TWO if n in names and not variants_cached((n,))]
            while queue or running:
                while queue and len(running) < max(1, int(jobs)):
                    args = queue.pop(0)
                    log = tempfile.TemporaryFile()
                    running.append((args, log, subprocess.Popen(
                        [sys.executable, "-m", "soft_envs.sim.warmup", str(robot_spec), *args],
                        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=log, env=env)))
                ended = [r for r in running if r[2].poll() is not None]
                if not ended:
                    time.sleep(0.1)
                    continue
                for args, log, child in ended:          # a slot is free as soon as any child ends
                    running.remove((args, log, child))
                    log.seek(0)
                    last = log.read().decode(errors="replace").strip().splitlines()[-1:]
                    log.close()
                    if child.returncode != 0:
                        raise RuntimeError(f"compiling the kernels ({' '.join(args)}) failed: "
                                           f"{last[0] if last else f'exit {child.returncode}'}")
    finally:                                        # a failure, Ctrl-C: no child is left compiling
        for _, log, child in running:
            child.kill()
            child.wait()
            log.close()
    took = time.perf_counter() - t0
    if names and out is not None:
        print(f"simulator kernels of {', '.join(names)} compiled and cached ({took:.1f} s)", file=out, flush=True)
    return took


@contextlib.contextmanager
def compile_ahead(robot_spec: str | os.PathLike, out: TextIO | None = None) -> Iterator[bool]:
    """Around the set-up of a simulation of ``robot_spec`` (a shipped robot's name or a
    robot.toml path): when numba's cache lacks the simulator's kernels, say so on ``out``
    (default stdout) and, when a core is idle (:func:`idle_core`; ``$SOFT_ENVS_COMPILE_AHEAD``
    ``1`` always, ``0`` never), compile the largest of them in a child process
    (:func:`compile_kernels` without ``everything``) while the block runs; on leaving the
    block, wait for the child, so the kernel is in the cache when the caller first needs it.
    Yields whether a child compiles. Nothing is said or started when the kernels are cached;
    if the child fails, the caller compiles what it needs itself, as without this."""
    if kernels_cached():
        yield False
        return
    out = out or sys.stdout
    print("compiling the simulator's kernels (first run only: numba caches them for the next runs)...",
          file=out, flush=True)
    switch = os.environ.get(ENV_SWITCH, "auto")
    if switch == "0" or (switch != "1" and not idle_core()):
        yield False
        return
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as log:
        child = subprocess.Popen([sys.executable, "-m", "soft_envs.sim.warmup", str(robot_spec), "--ahead"],
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=log,
                                 env=dict(os.environ, PYTHONPATH=_pythonpath()))
        try:
            yield True
            child.wait(timeout=_WAIT)
        except subprocess.TimeoutExpired:
            pass
        finally:
            if child.poll() is None:                      # the block raised, or the child hangs
                child.kill()
                child.wait()
        if child.returncode == 0:
            print(f"kernels compiled ({time.perf_counter() - t0:.0f} s)", file=out, flush=True)
        else:
            log.seek(0)
            last = log.read().decode(errors="replace").strip().splitlines()[-1:] or [f"exit {child.returncode}"]
            print(f"compiling ahead failed ({last[0]}); compiling on first use instead", file=out, flush=True)


def _pythonpath() -> str:
    """The caller's import path for the child, so that it compiles the same sources."""
    root = str(Path(__file__).resolve().parents[2])
    rest = os.environ.get("PYTHONPATH", "")
    return root + (os.pathsep + rest if rest else "")


def main(argv: list[str] | None = None) -> int:
    import argparse
    from . import load_robot
    p = argparse.ArgumentParser(prog="python -m soft_envs.sim.warmup",
                                description="Compile the simulator's numba kernels into numba's cache.")
    p.add_argument("robot", nargs="?", default="tripod", help="shipped robot name or robot.toml path")
    p.add_argument("--ahead", action="store_true",
                   help="only the Newton fallback's projected Hessian (what compile_ahead's child compiles)")
    p.add_argument("--no-box", action="store_true", help="not the kernels of a box (the carry and push tasks)")
    p.add_argument("--all", action="store_true",
                   help="every variant: both contact laws, on the plane and a height field, and a box (in --jobs processes)")
    p.add_argument("--jobs", type=int, default=2, help="processes compiling with --all (default 2)")
    p.add_argument("--variant", choices=tuple(VARIANTS), help=argparse.SUPPRESS)     # a child of --all
    args = p.parse_args(argv)
    if args.jobs < 1:
        p.error(f"--jobs must be >= 1, got {args.jobs}")
    if args.all:
        compile_variants(args.robot, jobs=args.jobs, out=sys.stdout)
        return 0
    t0 = time.perf_counter()
    robot = load_robot(args.robot)
    if args.variant:
        compile_variant(robot, args.variant)
        return 0
    compile_kernels(robot, everything=not args.ahead)
    if not (args.ahead or args.no_box):
        compile_box_kernels(robot)
    print(f"simulator kernels compiled and cached ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
