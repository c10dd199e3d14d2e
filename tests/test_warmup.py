"""Compiling the simulator's kernels ahead of a first run (soft_envs.sim.warmup)."""
from __future__ import annotations

import io
import subprocess

import pytest

from soft_envs.sim import warmup


def test_compile_kernels_fills_the_cache(bar_robot):
    warmup.compile_kernels(bar_robot)                     # compiles, or loads what is cached
    assert warmup.kernels_cached()


def test_nothing_happens_when_the_kernels_are_cached(bar_robot, monkeypatch):
    warmup.compile_kernels(bar_robot)
    started = []
    monkeypatch.setattr(subprocess, "Popen", lambda *a, **k: started.append(a))
    out = io.StringIO()
    with warmup.compile_ahead("tripod", out) as compiling:
        pass
    assert compiling is False and started == [] and out.getvalue() == ""


@pytest.mark.parametrize("switch, idle", [("0", True), ("auto", False)], ids=["switched-off", "busy-machine"])
def test_no_child_when_switched_off_or_no_core_is_idle(monkeypatch, switch, idle):
    """A cold cache is still announced; the kernels are then compiled on first use."""
    monkeypatch.setattr(warmup, "kernels_cached", lambda: False)
    monkeypatch.setattr(warmup, "idle_core", lambda: idle)
    monkeypatch.setenv(warmup.ENV_SWITCH, switch)
    started = []
    monkeypatch.setattr(warmup.subprocess, "Popen", lambda *a, **k: started.append(a))
    out = io.StringIO()
    with warmup.compile_ahead("tripod", out) as compiling:
        pass
    assert compiling is False and started == []
    assert out.getvalue().startswith("compiling the simulator's kernels (first run only")


def test_idle_core_compares_the_cores_with_the_load(monkeypatch):
    monkeypatch.setattr(warmup.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.setattr(warmup.os, "getloadavg", lambda: (0.9, 0.0, 0.0))
    assert warmup.idle_core()
    monkeypatch.setattr(warmup.os, "getloadavg", lambda: (1.2, 0.0, 0.0))
    assert not warmup.idle_core()


def _spy_popen(monkeypatch) -> list:
    children = []
    real = subprocess.Popen

    def spy(*args, **kwargs):
        children.append(real(*args, **kwargs))
        return children[-1]

    monkeypatch.setattr(warmup.subprocess, "Popen", spy)
    return children


def test_a_cold_cache_is_announced_and_compiled_in_a_child(monkeypatch):
    """As on a first run (the cache is taken for empty): the user is told, a child process
    compiles the kernels while the block runs, and the block's end waits for it."""
    monkeypatch.setattr(warmup, "kernels_cached", lambda: False)
    monkeypatch.setenv(warmup.ENV_SWITCH, "1")
    children = _spy_popen(monkeypatch)
    out = io.StringIO()
    with warmup.compile_ahead("tripod", out) as compiling:
        assert compiling is True
        assert "first run only" in out.getvalue()
    (child,) = children
    assert child.returncode == 0
    assert child.args[-2:] == ["tripod", "--ahead"]
    assert out.getvalue().splitlines()[-1].startswith("kernels compiled (")


def test_a_failing_child_is_reported_and_the_caller_goes_on(monkeypatch):
    monkeypatch.setattr(warmup, "kernels_cached", lambda: False)
    monkeypatch.setenv(warmup.ENV_SWITCH, "1")
    out = io.StringIO()
    with warmup.compile_ahead("no_such_robot", out):
        pass
    last = out.getvalue().splitlines()[-1]
    assert last.startswith("compiling ahead failed (") and "no_such_robot" in last
    assert last.endswith("compiling on first use instead")


def test_the_child_is_stopped_when_the_block_fails(monkeypatch):
    monkeypatch.setattr(warmup, "kernels_cached", lambda: False)
    monkeypatch.setenv(warmup.ENV_SWITCH, "1")
    children = _spy_popen(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        with warmup.compile_ahead("tripod", io.StringIO()):
            raise KeyboardInterrupt
    (child,) = children
    assert child.poll() is not None                        # ended, not left running


def test_the_warmup_compiles_the_box_kernels_too():
    """``python -m soft_envs.sim.warmup`` leaves the carry and push tasks' kernels in the cache."""
    from soft_envs.sim import load_robot
    from soft_envs.sim.contact import box_geometry
    warmup.compile_box_kernels(load_robot("tripod"))
    assert box_geometry.face_planes._cache._cache_file._load_index()


def test_the_variants_are_compiled_in_children_the_shared_kernels_first(monkeypatch):
    """``python -m soft_envs.sim.warmup --all`` (what the test suite runs before its workers
    start): the robot's own law with the Newton fallback's projected Hessian beside it, then the
    other variants, each in its own child process, the box first (here with a warm cache: the
    children load the kernels, and each must exit with 0)."""
    monkeypatch.setattr(warmup, "variants_cached", lambda names: False)    # taken for a cold cache
    children = _spy_popen(monkeypatch)
    out = io.StringIO()
    warmup.compile_variants("tripod", ("own", "paper", "box"), jobs=2, out=out)
    assert [c.args[-2:] for c in children] == [["tripod", "--ahead"], ["--variant", "own"],
                                               ["--variant", "box"], ["--variant", "paper"]]
    assert all(c.returncode == 0 for c in children)
    assert out.getvalue().startswith("simulator kernels of own, paper, box compiled and cached (")


def test_a_failing_variant_is_an_error_naming_it_and_a_bad_name_is_refused(monkeypatch):
    monkeypatch.setattr(warmup, "variants_cached", lambda names: False)
    with pytest.raises(RuntimeError, match=r"compiling the kernels \(--variant paper\) failed: .*no_such_robot"):
        warmup.compile_variants("no_such_robot", ("paper",))
    with pytest.raises(ValueError, match="variant must be one of own, coulomb, .* got 'wood'"):
        warmup.compile_variants("tripod", ("paper", "wood"))
