"""Shared fixtures: small meshes and robots built in Python (fast), shipped robots (cached)."""
from __future__ import annotations

import functools
import shutil
import signal
from pathlib import Path

import meshio
import numpy as np
import pytest

from soft_envs.sim import Robot, Simulator, load_robot
from soft_envs.sim.meshgen import voxel_tet_mesh
from soft_envs.sim.robot_file import asset_path


def pytest_configure(config):
    """Ctrl-C reaches the tests and the processes they start even when pytest itself was started
    with SIGINT ignored (``nohup pytest &`` from a non-interactive shell: a background job
    inherits SIG_IGN, Python then installs no KeyboardInterrupt handler, and an exec'd child
    keeps the signal ignored). The tests of the motors' stop on Ctrl-C and of an interrupted
    sweep send SIGINT and expect it to arrive."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if (not hasattr(config, "workerinput")            # pytest itself, not one of xdist's workers
            and getattr(config.option, "numprocesses", None)     # workers will start (not -n 0)
            and not (getattr(config.option, "collectonly", False) or getattr(config.option, "help", False))):
        compile_kernels_once()


def compile_kernels_once() -> None:
    """On a cold numba cache (a fresh clone, as in CI, or after an edit of ``soft_envs.sim``),
    the kernels of every variant the tests use (both contact laws, on the plane and a height
    field, a box) are compiled once, in one process per core, before xdist's workers start:
    otherwise each worker, each example's and README command's subprocess and each Ray worker
    begun before the cache is written compiles them again (a cold run's tests took ~12 % longer
    than a warm one's). On a warm cache this is a look at six cache indexes. A failure is
    printed and the tests go on (they then report the error themselves)."""
    import os
    import sys
    from soft_envs.sim import warmup
    if warmup.variants_cached():
        return
    print("compiling the simulator's kernels once before the tests (numba's cache is cold)...", flush=True)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        warmup.compile_variants("tripod", jobs=max(1, min(cores, 2)), out=sys.stdout)
    except Exception as exc:  # noqa: BLE001 - the tests show what is wrong, with a full traceback
        print(f"compiling the kernels ahead failed ({exc}); each test compiles what it needs", flush=True)


#: the longest test files (summed durations, ``pytest --durations=0``: 70-100 s each against a
#: few seconds for most), run first: pytest-xdist's ``--dist loadfile`` hands out files in
#: collection order, and one of them begun last would leave the other core idle at the end
LONGEST_FIRST = ("test_examples.py", "test_suite.py", "test_codesign_command.py", "test_sweep.py",
                 "test_readme_commands.py", "test_rl_tuning.py", "test_calibrate_checks.py", "test_motor_limit.py")


def pytest_collection_modifyitems(session, config, items):
    """The files of :data:`LONGEST_FIRST` first, in that order; the others as collected."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def block_mesh(nx=3, ny=2, nz=1, size=(0.06, 0.02, 0.02)) -> meshio.Mesh:
    xs, ys, zs = (np.linspace(0, s, n + 1) for s, n in zip(size, (nx, ny, nz)))
    p, t = voxel_tet_mesh(xs, ys, zs, np.ones((nx, ny, nz), bool))
    return meshio.Mesh(p, [("tetra", t)])


def small_robot(**kw) -> Robot:
    """A 6 cm foam bar with one motor driving a 3-point tendon along its top."""
    mesh = block_mesh()
    args = dict(youngs_modulus=1e5, poisson_ratio=0.3, density=100.0,
                tendons=[dict(name="t0", points=[[0.055, 0.015, 0.01], [0.03, 0.012, 0.012],
                                                 [0.005, 0.015, 0.01]])],
                motors=[dict(name="m0", tendons=["t0"], u_max=0.01)])
    args.update(kw)
    return Robot.from_mesh(mesh, **args)


@pytest.fixture(scope="session")
def bar_robot() -> Robot:
    return small_robot()


@functools.lru_cache(maxsize=None)
def shipped(name: str):
    robot = load_robot(name)
    sim = Simulator(robot)
    return robot, sim, sim.rest_positions()


@pytest.fixture(scope="session")
def tripod():
    return shipped("tripod")


@pytest.fixture(scope="session")
def puppy():
    return shipped("puppy")


@pytest.fixture
def robot_dir(tmp_path) -> Path:
    """A copy of the shipped Tripod's robot.toml and mesh in ``tmp_path``, to edit."""
    src = asset_path("tripod").parent
    shutil.copy(src / "tripod.vtu", tmp_path / "tripod.vtu")
    shutil.copy(src / "robot.toml", tmp_path / "robot.toml")
    return tmp_path




@pytest.fixture
def png_titles(monkeypatch):
    """``png_titles(module)``: the list, filled as the test runs, of the suptitles of the figures
    ``module`` writes through its ``atomic_write_png`` (which still writes them)."""
    titles: list[str] = []

    def watch(module) -> list[str]:
        real = module.atomic_write_png

        def keep(fig, path, **kw):
            titles.append(fig._suptitle.get_text())
            return real(fig, path, **kw)

        monkeypatch.setattr(module, "atomic_write_png", keep)
        return titles
    return watch

def _sigpipe_ignored() -> bool | None:
    """Whether this process ignores SIGPIPE, as the kernel sees it (``/proc/self/status``: a
    library may change it in C, behind Python's back), or None where that cannot be read."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("SigIgn:"):
                return bool(int(line.split()[1], 16) >> (int(signal.SIGPIPE) - 1) & 1)
    except (OSError, ValueError, AttributeError):
        pass
    return None


@pytest.fixture(autouse=True)
def _sigpipe_stays_ignored(request):
    """Python ignores SIGPIPE from the start (a write to a closed pipe raises BrokenPipeError). A
    test, or a library it loads, that leaves SIGPIPE at its default action kills the test process
    at the next such write, as a process pool's queue makes when its workers are terminated: in a
    pytest-xdist worker that crashed the worker and hung the run. The disposition is put back
    after every test, and the test that changed it fails."""
    before = _sigpipe_ignored()
    yield
    after = _sigpipe_ignored()
    if before and not after:
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
        pytest.fail(f"{request.node.nodeid} left SIGPIPE at its default action (process-ending); put back "
                    "to ignored")
