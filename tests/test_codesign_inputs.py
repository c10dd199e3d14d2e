"""``trajopt codesign``'s inputs, folder and worker processes (issue #40).

Inputs are checked before any work and before anything is created: a [design] table that
cannot be varied (naming the field), a baseline that is not a ``--speed max`` result, a damaged
``codesign.partial.json`` (one line naming the file and the field, exit 2). The folder is
reserved for the run's length (a second co-design into it is refused). The screening's worker
processes end with their parent however it ends (SIGTERM, SIGHUP, SIGKILL), and a worker that
dies says what to do. Where a test must not reach the expensive steps, the baseline search and
the screening are replaced by stubs that fail the test if reached."""
from __future__ import annotations

import json
import os
import platform
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trajopt.cli import main

ROOT = Path(__file__).resolve().parents[1]
DEADLINE = 300.0                 # s: a safety net only; the waits end on events
TINY = ["--prep-steps", "4", "--cycle-steps", "12", "--keyframes", "4", "--seeds", "1", "--cycles", "1", "--quiet"]


@pytest.fixture(scope="module")
def baseline(tmp_path_factory) -> Path:
    """The shipped Tripod's fastest gait, quick search (``--speed max``, SOFT_ENVS_QUICK=1)."""
    out = tmp_path_factory.mktemp("baseline")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SOFT_ENVS_QUICK", "1")
        assert main(["optimize", "tripod", "--speed", "max", "--quiet", "--out", str(out), "--name", "b"]) == 0
    return out / "b.npz"


@pytest.fixture
def no_work(monkeypatch):
    """The baseline search and the screening fail the test when reached."""
    import trajopt.codesign.run as run_module

    def reached(*args, **kw):
        raise AssertionError("the co-design's work started: its inputs were not checked first")

    monkeypatch.setattr(run_module, "fastest_gait", reached)
    monkeypatch.setattr(run_module, "screen_designs", reached)


def codesign(*args: str) -> int:
    return main(["codesign", *args, "--quick", "--quiet"])


# ------------------------------------------------------------------ the [design] table
def edit_design(robot_dir: Path, line: str) -> Path:
    toml = robot_dir / "robot.toml"
    key = line.split("=")[0].strip()
    text = toml.read_text()
    lines = [ln for ln in text.splitlines() if not ln.startswith(f"{key} =")]
    i = next(i for i, ln in enumerate(lines) if ln.startswith("[design]"))
    lines.insert(i + 1, line)
    toml.write_text("\n".join(lines) + "\n")
    return toml


@pytest.mark.parametrize("line, said", [
    ("routing = []", "[design].routing = [] names no tendon"),
    ("hip_height = 1.0", "[design].hip_height = 1.0"),
    ("fixed_points = [99]", "[design].fixed_points: point 99"),
    ("modulus_bounds = [1, 1]", "[design].modulus_bounds = [1.0, 1.0] leaves the moduli nothing to vary"),
])
def test_a_design_table_that_cannot_be_varied_is_refused_before_anything(robot_dir, tmp_path, capsys, no_work,
                                                                         line, said):
    toml = edit_design(robot_dir, line)
    out = tmp_path / "never"
    assert codesign(str(toml), "--out", str(out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0] and str(toml) in err[0], err
    assert not out.exists()                           # nothing created


def test_a_baseline_that_is_not_a_speed_max_result_is_refused(tmp_path, capsys, no_work):
    assert main(["optimize", "tripod", *TINY, "--iterations", "0", "--out", str(tmp_path), "--name", "plain"]) == 0
    out = tmp_path / "never"
    assert codesign("tripod", "--baseline", str(tmp_path / "plain.npz"), "--out", str(out)) == 2
    err = capsys.readouterr().err
    assert "plain.npz: not a --speed max result" in err and "trajopt optimize tripod --speed max" in err, err
    assert not out.exists()


# ------------------------------------------------------------------ the folder
def test_a_second_codesign_into_a_reserved_folder_is_refused(tmp_path, capsys, baseline, no_work):
    """Defect 1: two co-designs into one folder mixed their files; the folder is reserved."""
    out = tmp_path / "D"
    out.mkdir()
    lock = out / "codesign.lock"
    lock.write_text(json.dumps({"pid": os.getppid(), "host": platform.node(), "started": time.time(),
                                "command": "trajopt codesign tripod --vary stiffness --out D"}))
    assert codesign("tripod", "--vary", "legs", "--baseline", str(baseline), "--out", str(out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(lock) in err[0] and f"pid {os.getppid()} " in err[0] and "--vary stiffness" in err[0]
    assert sorted(p.name for p in out.iterdir()) == ["codesign.lock"]          # nothing written beside it


def test_the_folder_is_reserved_while_the_run_lives_and_released_after(tmp_path, baseline, monkeypatch):
    import trajopt.codesign.run as run_module
    seen = []

    def screen(*args, **kw):
        seen.append(json.loads((tmp_path / "D" / "codesign.lock").read_text())["pid"])
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "screen_designs", screen)
    assert codesign("tripod", "--baseline", str(baseline), "--out", str(tmp_path / "D")) == 130
    assert seen == [os.getpid()] and not (tmp_path / "D" / "codesign.lock").exists()


# ------------------------------------------------------------------ a damaged checkpoint
@pytest.fixture
def interrupted(tmp_path, baseline, monkeypatch) -> Path:
    """A folder with a genuine checkpoint after a screening round (the screening stubbed: it
    reports one round, then is interrupted)."""
    import numpy as np

    import trajopt.codesign.run as run_module
    from trajopt.codesign.screen import ScreenProgress

    def one_round(problem, theta, z, speed, target, settings, *, round_done, **kw):
        round_done(ScreenProgress(1, np.asarray(theta).tolist(), np.asarray(z).tolist(), float(speed)))
        raise KeyboardInterrupt

    out = tmp_path / "D"
    with monkeypatch.context() as mp:
        mp.setattr(run_module, "screen_designs", one_round)
        assert codesign("tripod", "--baseline", str(baseline), "--out", str(out)) == 130
    assert (out / "codesign.partial.json").is_file()
    return out


def _damaged(saved: dict) -> dict:
    return {
        "a list": "[]",
        "no state": json.dumps({"settings": saved["settings"]}),
        "state without w": json.dumps({"settings": saved["settings"],
                                       "state": {k: v for k, v in saved["state"].items() if k != "w"}}),
        "truncated": json.dumps(saved)[:200],
        "NaN in w": json.dumps({**saved, "state": {**saved["state"], "w": [float("nan")] * len(saved["state"]["w"])}}),
        "w too short": json.dumps({**saved, "state": {**saved["state"], "w": saved["state"]["w"][:3]}}),
        "stage a string": json.dumps({**saved, "state": {**saved["state"], "stage": "one"}}),
        "screen_progress a list": json.dumps({**saved, "state": {**saved["state"], "screen_progress": [1]}}),
    }


@pytest.mark.parametrize("case, field", [
    ("a list", "expected a JSON object"), ("no state", "field 'state' is missing"),
    ("state without w", "field 'state.w' is missing"), ("truncated", "not JSON"),
    ("NaN in w", "field 'state.w'"), ("w too short", "field 'state.w'"),
    ("stage a string", "field 'state.stage'"), ("screen_progress a list", "field 'state.screen_progress'"),
])
def test_a_damaged_checkpoint_is_refused_naming_the_file_and_field(interrupted, capsys, no_work, case, field):
    """Defect 8: AttributeError / KeyError / TypeError tracebacks, or a JSON error naming no file."""
    partial = interrupted / "codesign.partial.json"
    partial.write_text(_damaged(json.loads(partial.read_text()))[case])
    before = partial.read_bytes()
    capsys.readouterr()
    assert codesign("tripod", "--resume", "--out", str(interrupted)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(partial) in err[0] and field in err[0] and "--overwrite" in err[0], err
    assert partial.read_bytes() == before


def test_a_checkpoint_of_another_vary_is_refused_naming_it(interrupted, capsys, no_work):
    assert codesign("tripod", "--vary", "legs", "--resume", "--out", str(interrupted)) == 2
    err = capsys.readouterr().err
    assert "cannot resume" in err and "vary" in err and "stiffness" in err, err


# ------------------------------------------------------------------ worker processes
def _children(pid: int) -> set[int]:
    out = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            pass
    return out


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def _alive(pid: int, cmdline: str) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z" and _cmdline(pid) == cmdline          # the same process, not a zombie


def _default_dispositions() -> None:
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_DFL)


def start_codesign(baseline: Path, out: Path) -> tuple[subprocess.Popen, dict[int, str]]:
    """``trajopt codesign --workers 2`` in a subprocess, returned once both workers run (and
    the processes it started: pid -> command line)."""
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen([sys.executable, "-m", "trajopt.cli", "codesign", "tripod", "--quick", "--quiet",
                             "--workers", "2", "--baseline", str(baseline), "--out", str(out)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_dispositions)
    t0 = time.monotonic()
    while True:
        kids = {p: _cmdline(p) for p in _children(proc.pid)}
        if sum("spawn_main" in c for c in kids.values()) >= 2:
            return proc, kids
        if proc.poll() is not None or time.monotonic() - t0 > DEADLINE:
            proc.kill()
            pytest.fail(f"the workers never started; exit {proc.poll()}; stderr:\n{proc.communicate()[1]}")
        time.sleep(0.05)


def gone_within(processes: dict[int, str], seconds: float) -> list[int]:
    """The processes still alive after ``seconds`` (polled: returns as soon as none is)."""
    t0 = time.monotonic()
    while True:
        alive = [p for p, c in processes.items() if _alive(p, c)]
        if not alive or time.monotonic() - t0 > seconds:
            return alive
        time.sleep(0.05)


needs_proc = pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads processes from /proc")


@needs_proc
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGKILL])
def test_workers_end_with_their_parent(tmp_path, baseline, signum):
    """Defect 4: SIGTERM or SIGHUP of ``codesign --workers 2`` orphaned its workers (and the
    resource tracker) under pid 1, holding stdout (a pipeline hung). Whatever ends the parent,
    even SIGKILL, no process it started is alive 5 s later, and its stdout reaches EOF."""
    proc, kids = start_codesign(baseline, tmp_path / "D")
    proc.send_signal(signum)
    try:
        proc.wait(timeout=DEADLINE)
        assert gone_within(kids, 5.0) == []
    finally:
        for pid, cmdline in kids.items():             # a failing run leaves no orphan behind
            if _alive(pid, cmdline):
                os.kill(pid, signal.SIGKILL)
    out, err = proc.communicate(timeout=DEADLINE)      # EOF: no process holds stdout any more
    if signum != signal.SIGKILL:
        assert proc.returncode == 128 + signum, err
        assert f"terminated by {signal.Signals(signum).name}" in err and "Traceback" not in err, err
        assert not (tmp_path / "D" / "codesign.lock").exists()


class _ReapedElsewhere:
    """A dead worker whose exit status another thread (the pool's manager) is reaping: the first
    joins see no exit code (multiprocessing's waitpid gets ECHILD and reports None)."""

    def __init__(self, code: int, unknown_for: int):
        self.code, self.unknown_for, self.exitcode = code, unknown_for, None

    def join(self, timeout=None):
        self.unknown_for -= 1
        if self.unknown_for < 0:
            self.exitcode = self.code


def test_a_worker_reaped_by_the_pool_is_still_named_by_its_signal():
    """The race behind a flaky "ended abruptly" for a SIGKILL: how_they_died read the exit code
    after one join, while the pool's manager thread was reaping the same child."""
    from trajopt.codesign.score import Scorer
    scorer = Scorer(2)
    scorer._seen = {_ReapedElsewhere(-signal.SIGTERM, 0), _ReapedElsewhere(-signal.SIGKILL, 3)}
    assert scorer.how_they_died() == "killed by SIGKILL"


@needs_proc
def test_a_worker_killed_says_what_to_do(tmp_path, baseline):
    """Defect 7: a worker killed (as the out-of-memory killer does) gave two tracebacks and
    advice about ``if __name__ == "__main__":`` that does not apply to the command line."""
    proc, kids = start_codesign(baseline, tmp_path / "D")
    worker = next(p for p, c in kids.items() if "spawn_main" in c)
    os.kill(worker, signal.SIGKILL)
    try:
        out, err = proc.communicate(timeout=DEADLINE)
    finally:
        for pid, cmdline in kids.items():
            if _alive(pid, cmdline):
                os.kill(pid, signal.SIGKILL)
    assert proc.returncode == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err and "__main__" not in err, err
    assert "a worker process" in err and "died" in err and "SIGKILL" in err
    assert "--resume" in err and "--workers 1" in err
    assert gone_within(kids, 5.0) == []
