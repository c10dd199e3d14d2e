"""Reserving a result name while a run lives (issue #26 item 2): a second writer of the same
name is refused at once, naming the lock file and its owner; a dead owner's lock is taken over
with a warning; the lock is gone when the run ends, however it ends. Through the context
manager, and through ``trajopt optimize``, ``sweep``, ``robustness`` and ``rl train``."""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from trajopt.cli import main
from trajopt.results.reservation import ReservationRefused, StaleReservationWarning, lock_path, read_owner, reserve

ROOT = Path(__file__).resolve().parents[1]
TINY = ["--prep-steps", "4", "--cycle-steps", "12", "--keyframes", "4", "--seeds", "1", "--cycles", "1", "--quiet"]
#: a second process that holds a reservation until the file RELEASE appears
HOLDER = """
import sys, time
from pathlib import Path
from trajopt.results.reservation import reserve
with reserve(sys.argv[1], command="holder"):
    print("held", flush=True)
    while not Path(sys.argv[2]).exists():
        time.sleep(0.05)
"""


@pytest.fixture
def holder(tmp_path):
    """``start(lock_file)``: a live process holding ``lock_file`` (returned once it holds it)."""
    procs = []

    def start(lock_file: Path) -> subprocess.Popen:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
        proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(lock_file), str(tmp_path / "RELEASE")],
                                stdout=subprocess.PIPE, text=True, env=env)
        procs.append(proc)
        assert proc.stdout.readline().strip() == "held"          # the event: it holds the lock now
        return proc

    yield start
    (tmp_path / "RELEASE").touch()
    for proc in procs:
        proc.wait(timeout=120)


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_lock_holds_the_owner_and_is_removed_after_success_and_failure(tmp_path):
    lock = tmp_path / "sub" / "run.lock"
    with reserve(lock, command="trajopt optimize tripod") as held:
        owner = json.loads(held.read_text())
        assert owner["pid"] == os.getpid() and owner["host"] == platform.node()
        assert owner["command"] == "trajopt optimize tripod" and owner["started"] > 0
        with pytest.raises(ReservationRefused, match=f"pid {os.getpid()} on host"):   # not re-entrant
            with reserve(lock):
                pass
    assert not lock.exists() and not lock.parent.exists()       # the folder made for it is gone too
    with pytest.raises(RuntimeError, match="boom"):
        with reserve(lock):
            assert lock.is_file()
            raise RuntimeError("boom")
    assert not lock.exists()
    assert lock_path(tmp_path / "tripod_walk_v5.5.npz") == tmp_path / "tripod_walk_v5.5.lock"
    assert lock_path(tmp_path / "runs" / "tripod_ppo") == tmp_path / "runs" / "tripod_ppo.lock"


def test_a_second_process_is_refused_while_the_first_holds_the_name(tmp_path, holder):
    lock = tmp_path / "run.lock"
    proc = holder(lock)
    with pytest.raises(ReservationRefused) as exc:
        with reserve(lock):
            pytest.fail("reserved a name another live process holds")
    assert str(lock) in str(exc.value) and f"pid {proc.pid} on host {platform.node()}" in str(exc.value)
    assert read_owner(lock)["pid"] == proc.pid                   # the refused one left it alone


def test_a_dead_owners_lock_is_taken_over_with_a_warning(tmp_path):
    lock = tmp_path / "run.lock"
    pid = dead_pid()
    lock.write_text(json.dumps({"pid": pid, "host": platform.node(), "started": 1.0, "command": "killed"}))
    with pytest.warns(StaleReservationWarning, match=f"pid {pid} .*no longer runs"):
        with reserve(lock):
            assert read_owner(lock)["pid"] == os.getpid()
    assert not lock.exists()
    # our own pid on a lock we do not hold: an older process's whose pid was reused
    lock.write_text(json.dumps({"pid": os.getpid(), "host": platform.node(), "started": 1.0, "command": "old"}))
    with pytest.warns(StaleReservationWarning):
        with reserve(lock):
            pass
    # another host's lock cannot be checked: refused, with the remedy
    lock.write_text(json.dumps({"pid": pid, "host": "elsewhere", "started": 1.0, "command": "remote"}))
    with pytest.raises(ReservationRefused, match="host elsewhere.*remove it by hand"):
        with reserve(lock):
            pass
    assert read_owner(lock)["host"] == "elsewhere"


def test_optimize_of_a_reserved_name_exits_2_naming_the_lock_and_its_owner(tmp_path, holder, capsys):
    proc = holder(tmp_path / "v5.5.lock")
    assert main(["optimize", "tripod", *TINY, "--iterations", "1", "--out", str(tmp_path), "--name", "v5.5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path / "v5.5.lock") in err[0] and f"pid {proc.pid} " in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v5.5.lock"]      # nothing written


def test_optimize_releases_its_name_after_success_and_failure(tmp_path, capsys):
    assert main(["optimize", "tripod", *TINY, "--iterations", "1", "--out", str(tmp_path), "--name", "v5.5"]) == 0
    assert (tmp_path / "v5.5.npz").is_file() and not (tmp_path / "v5.5.lock").exists()
    bad = tmp_path / "not_a_result.npz"
    bad.write_text("no")
    assert main(["optimize", "tripod", *TINY, "--out", str(tmp_path), "--name", "w", "--warm-start", str(bad)]) == 2
    assert "not_a_result.npz" in capsys.readouterr().err
    assert not (tmp_path / "w.lock").exists()
    # the finished result stays protected by the no-overwrite rule
    assert main(["optimize", "tripod", *TINY, "--iterations", "1", "--out", str(tmp_path), "--name", "v5.5"]) == 2
    assert "exists" in capsys.readouterr().err and not (tmp_path / "v5.5.lock").exists()


def test_a_second_sweep_into_a_held_folder_is_refused(tmp_path, holder):
    from trajopt.sweep import load_spec, run_sweep
    spec_file = tmp_path / "s.toml"
    spec_file.write_text('[[runs]]\nkind = "optimize"\nname = "r"\n[runs.args]\nrobot = "tripod"\niterations = 1\n')
    out = tmp_path / "out"
    proc = holder(out / "sweep.lock")
    with pytest.raises(ReservationRefused, match=f"sweep folder .*pid {proc.pid} "):
        run_sweep(load_spec(spec_file, out), out, serial=True)
    assert sorted(p.name for p in out.iterdir()) == ["sweep.lock"]          # no run started


def test_robustness_and_rl_train_refuse_a_held_folder(tmp_path, holder, capsys):
    proc = holder(tmp_path / "rob" / "robustness.lock")
    assert main(["robustness", str(tmp_path / "any.npz"), "--out", str(tmp_path / "rob")]) == 2
    err = capsys.readouterr().err
    assert "robustness.lock" in err and f"pid {proc.pid} " in err
    pytest.importorskip("stable_baselines3")
    proc = holder(tmp_path / "runs" / "r.lock")
    assert main(["rl", "train", "tripod", "--timesteps", "8", "--out", str(tmp_path / "runs"), "--name", "r",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "r.lock" in err and f"pid {proc.pid} " in err
    assert not (tmp_path / "runs" / "r").exists()


def test_a_lock_naming_a_reused_pid_is_taken_over(tmp_path):
    """Issue #40: the pid of a lock written long before its process started is another process's
    now (pid reuse): the lock is stale, although the pid runs."""
    if not Path(f"/proc/{os.getppid()}/stat").is_file():
        pytest.skip("needs /proc to read a process's start time")
    lock = tmp_path / "run.lock"
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        lock.write_text(json.dumps({"pid": proc.pid, "host": platform.node(), "started": 1000.0, "command": "old"}))
        with pytest.warns(StaleReservationWarning, match=f"pid {proc.pid} "):
            with reserve(lock):
                assert read_owner(lock)["pid"] == os.getpid()
        # the same live pid with a start time after its process started: a live owner, refused
        import time
        lock.write_text(json.dumps({"pid": proc.pid, "host": platform.node(), "started": time.time(),
                                    "command": "live"}))
        with pytest.raises(ReservationRefused, match=f"pid {proc.pid} "):
            with reserve(lock):
                pass
    finally:
        proc.kill()
        proc.wait()


def test_a_dangling_symlink_lock_is_refused_naming_what_it_is(tmp_path):
    lock = tmp_path / "run.lock"
    lock.symlink_to(tmp_path / "nowhere")
    with pytest.raises(ReservationRefused, match="symbolic link.*nowhere.*remove it"):
        with reserve(lock):
            pass
    assert lock.is_symlink()
