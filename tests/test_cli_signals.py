"""How the commands end on a signal or a closed pipe (issue #40): SIGTERM and SIGHUP end
``optimize`` (plain and ``--speed max``) as Ctrl-C does (the checkpoint saved as "interrupted",
the lock released, a message, exit 128 + N); ``--speed max`` checkpoints its search and
``--resume`` continues it; ``evaluate R | head -1`` exits quietly.

The commands run as real subprocesses; each signal is sent once the run has written its
checkpoint (an event: the file appears), and the run is held there (a patched optimiser that
waits) so that it cannot finish first, whatever the load."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trajopt import Result
from trajopt.cli import main

ROOT = Path(__file__).resolve().parents[1]
DEADLINE = 300.0            # s: a safety net only; every wait ends on an event
TINY = ["--prep-steps", "4", "--cycle-steps", "12", "--keyframes", "4", "--seeds", "1", "--cycles", "1", "--quiet"]

#: runs ``trajopt`` with the optimiser held (sleeping) after its first checkpoint (plain
#: optimize) or before its second optimisation (--speed max): the signal finds it there
HELD = """
import os, sys, time
import trajopt.optimize_run as run, trajopt.fastest as fastest
real_run, real_fastest = run.optimize_gait, fastest.optimize_gait
def park():
    # tell the test the process is parked in the sleep, where a signal always interrupts it (sent
    # any earlier, it may land in a finaliser run by the garbage collector, which swallows it)
    open(os.environ["HELD_MARKER"], "w").close()
    time.sleep(600)
def held_run(*a, callback, **kw):
    def cb(entry, partial):
        out = callback(entry, partial)
        park()
        return out
    return real_run(*a, callback=cb, **kw)
calls = []
def held_fastest(*a, **kw):
    calls.append(1)
    if len(calls) == 2:
        park()
    return real_fastest(*a, **kw)
run.optimize_gait, fastest.optimize_gait = held_run, held_fastest
from trajopt.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _default_dispositions() -> None:       # in the child: as from a shell, whatever ran pytest
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_DFL)


def start(args: list[str], code: str = HELD, *, held: Path | None = None, **env) -> subprocess.Popen:
    """``trajopt ARGS`` run by ``code``; ``held``: the file the HELD code creates once parked."""
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}", **env}
    if held is not None:
        env["HELD_MARKER"] = str(held)
    return subprocess.Popen([sys.executable, "-c", code, *args], env=env, preexec_fn=_default_dispositions,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_until(ready, proc: subprocess.Popen, what: str) -> None:
    t0 = time.monotonic()
    while not ready():
        if proc.poll() is not None or time.monotonic() - t0 > DEADLINE:
            proc.kill()
            out, err = proc.communicate()
            pytest.fail(f"{what} never happened; exit {proc.returncode}; stderr:\n{err}")
        time.sleep(0.05)


def wait_for_file(path: Path, proc: subprocess.Popen) -> None:
    wait_until(path.exists, proc, f"{path} appearing")


def rows_saved(state: Path) -> int:
    try:
        return len(json.loads(state.read_text())["rows"])
    except (OSError, ValueError, KeyError):
        return 0


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_optimize_ends_on_sigterm_and_sighup_as_on_ctrl_c(tmp_path, signum):
    proc = start(["optimize", "tripod", *TINY, "--iterations", "50", "--out", str(tmp_path), "--name", "w"],
                 held=tmp_path / "held")
    partial = tmp_path / "w.partial.npz"
    wait_for_file(partial, proc)
    wait_for_file(tmp_path / "held", proc)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=DEADLINE)
    assert proc.returncode == 128 + signum, err
    name = signal.Signals(signum).name
    assert f"interrupted by {name}: iteration 1 saved to {partial}" in err and "--resume" in err, err
    assert "Traceback" not in err
    assert Result.load(partial).status == "interrupted"
    assert not (tmp_path / "w.lock").exists()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_speed_max_checkpoints_its_search_and_resumes_it(tmp_path, signum, monkeypatch, capsys):
    """Ctrl-C or SIGTERM during --speed max: the finished runs of the search are kept
    (NAME.search.partial/), and --resume continues after them instead of starting afresh."""
    args = ["optimize", "tripod", "--speed", "max", "--out", str(tmp_path), "--name", "m", "--quiet"]
    proc = start(args, held=tmp_path / "held", SOFT_ENVS_QUICK="1")
    state = tmp_path / "m.search.partial" / "state.json"
    wait_until(lambda: rows_saved(state) == 1, proc, "the first finished optimisation saved")
    wait_for_file(tmp_path / "held", proc)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=DEADLINE)
    assert proc.returncode == 128 + signum, err
    assert "Traceback" not in err and "1 finished optimisation of the search saved" in err and "--resume" in err, err
    saved = json.loads(state.read_text())
    assert saved["status"] == "interrupted" and len(saved["rows"]) == 1
    assert not (tmp_path / "m.lock").exists() and not (tmp_path / "m.npz").exists()
    # a new run without --resume is refused; --resume continues after the finished run
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")
    assert main(args) == 2
    assert "--resume" in capsys.readouterr().err
    import trajopt.fastest as fastest
    calls = []
    real = fastest.optimize_gait
    monkeypatch.setattr(fastest, "optimize_gait", lambda *a, **kw: calls.append(1) or real(*a, **kw))
    assert main([*args, "--resume"]) == 0
    res = Result.load(tmp_path / "m.npz")
    rows = (tmp_path / "m.search.csv").read_text().splitlines()[1:]
    assert len(calls) == len(rows) - 1 == res.settings["search"]["runs"] - 1      # the first run not again
    assert not (tmp_path / "m.search.partial").exists()


def test_evaluate_into_a_closed_pipe_exits_quietly(tmp_path):
    """``trajopt evaluate R | head -1``: head closes the pipe; no "Broken pipe", no traceback."""
    assert main(["optimize", "tripod", *TINY, "--iterations", "0", "--out", str(tmp_path), "--name", "r"]) == 0
    read, write = os.pipe()
    os.close(read)                              # the reader is gone before the first line
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.run([sys.executable, "-m", "trajopt.cli", "evaluate", str(tmp_path / "r.npz")],
                          stdout=write, stderr=subprocess.PIPE, text=True, env=env, timeout=DEADLINE)
    os.close(write)
    assert proc.stderr == "" and proc.returncode == 128 + signal.SIGPIPE, proc.stderr


#: runs ``trajopt`` with RL training held (sleeping) at its first environment step
RL_HELD = """
import os, sys, time
import stable_baselines3.common.callbacks as cb
RealList = cb.CallbackList
class Park(cb.BaseCallback):
    def _on_step(self):
        open(os.environ["HELD_MARKER"], "w").close()
        time.sleep(600)
        return True
cb.CallbackList = lambda callbacks: RealList(list(callbacks) + [Park()])
from trajopt.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_rl_train_saves_its_model_on_sigterm_as_on_ctrl_c(tmp_path, signum):
    pytest.importorskip("stable_baselines3")
    proc = start(["rl", "train", "tripod", "--timesteps", "256", "--n-envs", "1", "--vec-env", "dummy",
                  "--no-progress", "--out", str(tmp_path), "--name", "r"], RL_HELD, held=tmp_path / "held")
    wait_for_file(tmp_path / "held", proc)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=DEADLINE)
    assert proc.returncode == 128 + signum, err
    label = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
    assert f"interrupted by {label} after" in err and "Traceback" not in err, err
    config = json.loads((tmp_path / "r" / "rl_config.json").read_text())
    assert config["status"] == "interrupted" and (tmp_path / "r" / "model.zip").is_file()
