"""``trajopt sweep``: sweep files, a local Ray with 2 CPUs, faults, resuming and Ctrl-C."""
from __future__ import annotations

import hashlib
import json
import os
import secrets
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from trajopt import Result
from trajopt.sweep import load_spec, read_status, run_sweep
from trajopt.sweep.runner import plan
from trajopt.sweep.task import resumes

ROOT = Path(__file__).resolve().parents[1]
#: a tiny optimisation: one Gauss-Newton iteration on short cycles (a few seconds)
TINY = ('iterations = 1\nseeds = 1\ncycle_steps = 12\nprep_steps = 4\ncycles = 1\nkeyframes = 2\n')


def write(tmp_path: Path, text: str, name: str = "sweep.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def tiny_block(name: str, grid: str, robot: str = "tripod", extra: str = "") -> str:
    return (f'[[runs]]\nkind = "optimize"\nname = "{name}"\n[runs.args]\nrobot = "{robot}"\n{TINY}{extra}'
            f"[runs.grid]\n{grid}\n")


def digest(path: Path) -> dict[str, str]:
    return {str(p.relative_to(path)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(path.rglob("*")) if p.is_file()}


# ----------------------------------------------------------------------------- killed while running (no Ray)
#: a sweep (serial) whose optimisation is killed by SIGKILL right after its first checkpoint
KILLED_AFTER_FIRST_CHECKPOINT = """
import os, signal, sys
import trajopt.optimize_run as run
real = run.optimize_gait
def killed(*a, callback, **kw):
    def cb(entry, partial):
        callback(entry, partial)
        os.kill(os.getpid(), signal.SIGKILL)
    return real(*a, callback=cb, **kw)
run.optimize_gait = killed
from trajopt.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_run_killed_while_running_resumes_from_its_checkpoint(tmp_path, monkeypatch):
    """Issue #40: a sweep run killed (SIGKILL, a power cut) while its status and its checkpoint
    say "running" continues from that checkpoint when the sweep runs again; it does not start
    afresh (this test fails if it does)."""
    text = tiny_block("k{speed:g}", "speed = [3.0]").replace("iterations = 1\n", "iterations = 3\n")
    spec_path, out = write(tmp_path, text), tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run([sys.executable, "-c", KILLED_AFTER_FIRST_CHECKPOINT, "sweep", str(spec_path), "--out",
                           str(out), "--serial", "--no-plot"], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    run_dir = out / "k3"
    assert read_status(run_dir)["status"] == "running"
    checkpoint = Result.load(run_dir / "k3.partial.npz")
    assert checkpoint.status == "running" and len(checkpoint.history) == 1
    import trajopt.optimize_run as optimize_run
    calls = []
    real = optimize_run.optimize_gait

    def counted(*a, resume=None, **kw):
        calls.append(resume)
        return real(*a, resume=resume, **kw)

    monkeypatch.setattr(optimize_run, "optimize_gait", counted)
    with pytest.warns(UserWarning, match="no longer runs"):         # the killed run's locks are stale
        outcome = run_sweep(load_spec(spec_path, out), out, serial=True)
    assert outcome.statuses["k3"]["status"] == "done"
    assert len(calls) == 1 and calls[0] is not None and len(calls[0].history) == 1     # resumed, not restarted
    res = Result.load(run_dir / "k3.npz")
    assert len(res.history) == 3 and res.history[0] == checkpoint.history[0]
    assert not (run_dir / "k3.partial.npz").exists()


# ----------------------------------------------------------------------------- sweep files (no Ray)
def test_spec_expands_grids_names_and_arguments(tmp_path):
    spec_path = write(tmp_path, '[sweep]\ndescription = "d"\n' + tiny_block(
        "{robot}_v{speed:g}_f{contact_friction:g}", 'speed = [4.0, 6.5]\ncontact_friction = [500.0]',
        extra="symmetry = false\n") + tiny_block("other{_k}", "_k = [1]", robot="robots/mine.toml"))
    spec = load_spec(spec_path, tmp_path / "out")
    assert spec.names() == ["tripod_v4_f500", "tripod_v6.5_f500", "other1"]
    first = spec.runs[0]
    assert first.contact() == {"friction": 500.0}
    argv = first.argv()
    assert argv[:2] == ["optimize", "tripod"] and "--no-symmetry" in argv
    assert argv[argv.index("--cycle-steps") + 1] == "12" and argv[argv.index("--speed") + 1] == "4.0"
    assert not any(a.startswith("--contact") or a.startswith("--_") for a in argv)
    assert spec.runs[2].params["robot"] == str((tmp_path / "robots/mine.toml").resolve())


@pytest.mark.parametrize("text, message", [
    ('[[runs]]\nkind = "optimise"\n', "runs[0].kind must be one of"),
    ('[[runs]]\nkind = "optimize"\n[runs.args]\nrobot = "tripod"\nspeeed = 3\n', "unknown argument 'speeed'"),
    ('[[runs]]\nkind = "optimize"\n[runs.args]\nrobot = "tripod"\nspeed = "fast"\n', "argument speed: must be a finite number > 0 [BL/min] or 'max', got 'fast'"),
    ('[[runs]]\nkind = "optimize"\n[runs.args]\nspeed = 3\n', "argument 'robot' is missing"),
    ('[[runs]]\nkind = "optimize"\nname = "{robot}_{sped}"\n[runs.args]\nrobot = "tripod"\n',
     "runs[0].name: {sped} is not a parameter"),
    ('[[runs]]\nkind = "optimize"\nname = "same"\n[runs.args]\nrobot = "tripod"\n[runs.grid]\nspeed = [1, 2]\n',
     "run name 'same' is made twice"),
    ('[[runs]]\nkind = "optimize"\n[runs.args]\nrobot = "tripod"\nout = "x"\n', "'out' is set by the sweep"),
    ('[[runs]]\nkind = "optimize"\n[runs.args]\nrobot = "tripod"\n[runs.grid]\nspeed = 3\n',
     "runs[0].grid.speed must be a non-empty list"),
    ('[[runs]]\nkind = "evaluate"\n[runs.args]\nresult = "r.npz"\ncontact_friction = 1.0\n',
     "applies to kind 'optimize' only"),
    ('[[runs]]\nkind = "optimize"\nname = "a/b"\n[runs.args]\nrobot = "tripod"\n', "not a plain directory name"),
    ("[[runs]\n", "not valid TOML"),
    ("[sweep]\n", "no runs"),
])
def test_spec_errors_name_the_file_and_field(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(ValueError) as err:
        load_spec(path)
    assert str(path) in str(err.value) and message in str(err.value)


def test_quick_arguments_keep_the_run_names(tmp_path, monkeypatch):
    path = write(tmp_path, tiny_block("r{speed:g}", "speed = [4.0]") + "[runs.quick]\niterations = 2\n")
    monkeypatch.delenv("SOFT_ENVS_QUICK", raising=False)
    assert load_spec(path).runs[0].params["iterations"] == 1
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")
    from trajopt.sweep import quick_requested
    quick = load_spec(path, quick=quick_requested())
    assert quick.names() == ["r4"] and quick.runs[0].params["iterations"] == 2


def test_contact_parameters_run_on_a_copy_of_the_robot_file(tmp_path):
    import numpy as np
    from soft_envs.sim import load_robot
    from trajopt.sweep.task import _derived_robot
    out = tmp_path / "out"
    spec = load_spec(write(tmp_path, tiny_block("f{contact_friction:g}", "contact_friction = [250.0]\n"
                                                "contact_stiffness = [3000.0]")), out)
    run = spec.runs[0]
    (out / run.name).mkdir(parents=True)
    path = _derived_robot(run, out / run.name)
    robot, base = load_robot(path), load_robot("tripod")
    assert robot.contact.friction == 250.0 and robot.contact.stiffness == 3000.0
    assert robot.contact.blend == base.contact.blend and robot.payload_mass == base.payload_mass
    assert np.array_equal(robot.mesh.points, base.mesh.points)
    assert run.argv(path)[1] == str(path) and "robot" not in run.contact()      # the log's command


def test_robot_given_as_a_path_expands_to_its_name_in_run_names(tmp_path, robot_dir):
    toml = robot_dir / "robot.toml"
    toml.write_text(toml.read_text().replace('name = "tripod"', 'name = "my_tripod"', 1))
    spec = load_spec(write(tmp_path, tiny_block("{robot}_v{speed:g}", f'robot = ["tripod", "{toml}", '
                                                '"robots/gone/robot.toml"]\nspeed = [4.0]')
                           .replace('robot = "tripod"\n', "")), tmp_path / "out")
    assert spec.names() == ["tripod_v4", "my_tripod_v4", "gone_v4"]      # no slashes, the robot's name
    assert spec.runs[1].params["robot"] == str(toml)                     # the command still gets the path


def test_non_utf8_sweep_file_names_the_file_and_byte_offset(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'[[runs]]\nkind = "optimize"\nname = "caf\xe9"\n')
    with pytest.raises(ValueError, match=r"latin1.toml: not UTF-8 text: byte 0xe9 at offset 38 \(line 3\)"):
        load_spec(path)


def test_dry_run_refuses_what_the_run_would_refuse(tmp_path, capsys):
    from trajopt.cli import main
    text = (tiny_block("ok", "_x = [0]") + tiny_block("unknown", "_x = [0]", robot="no_such_robot")
            + tiny_block("negative", "contact_stiffness = [-1.0]"))
    out = tmp_path / "out"
    assert main(["sweep", str(write(tmp_path, text)), "--out", str(out), "--dry-run"]) == 2
    lines = capsys.readouterr().out.splitlines()
    state = {ln[8:].split()[0]: ln[:7].strip() for ln in lines if ln[:7].strip() in ("refused", "to run", "done")}
    assert state == {"ok": "to run", "unknown": "refused", "negative": "refused"}, lines
    assert any("unknown robot 'no_such_robot'" in ln for ln in lines)
    assert any("contact.stiffness must be positive, got -1.0" in ln for ln in lines)
    assert lines[-1] == "0 done, 1 to run, 2 refused" and not out.exists()


def test_only_runs_the_matching_runs_and_the_summary_keeps_the_whole_sweep(tmp_path, capsys):
    from trajopt.cli import main
    path = write(tmp_path, tiny_block("a_{_x}", "_x = [0]") + tiny_block("b_{_x}", "_x = [0]"))
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--serial", "--only", "c_*"]) == 2
    assert "sweep.toml: --only 'c_*' matches no run; the runs are a_0, b_0" in capsys.readouterr().err
    assert not out.exists()
    assert main(["sweep", str(path), "--out", str(out), "--serial", "--no-plot", "--only", "a_*"]) == 0
    assert "1 runs" in capsys.readouterr().out and not (out / "b_0").exists()
    rows = (out / "summary.csv").read_text().splitlines()
    assert [r.split(",")[:3] for r in rows[1:]] == [["a_0", "optimize", "done"], ["b_0", "optimize", "not started"]]
    assert main(["sweep", str(path), "--out", str(out), "--serial", "--no-plot", "--only", "b_?"]) == 0
    rows = (out / "summary.csv").read_text().splitlines()
    assert [r.split(",")[:3] for r in rows[1:]] == [["a_0", "optimize", "done"], ["b_0", "optimize", "done"]]


def test_fractional_speed_run_and_status_files_that_lie(tmp_path):
    """A run named with a fractional target speed (``v5.5``) finishes as done (its result was
    once saved as ``v5.npz``); a "done" status whose result was deleted is run again; a
    corrupted status.json is rebuilt from the result files."""
    out = tmp_path / "out"
    spec = load_spec(write(tmp_path, tiny_block("v{speed:g}", "speed = [5.5]")), out)
    first = run_sweep(spec, out, serial=True)
    assert first.count("done") == 1, first.statuses
    res = Result.load(out / "v5.5" / "v5.5.npz")
    assert res.settings["speed_bl_per_min"] == 5.5 and not (out / "v5.5" / "v5.npz").exists()
    assert not (out / "sweep.lock").exists() and not (out / "v5.5" / "v5.5.lock").exists()
    digest_before = digest(out / "v5.5")

    (out / "v5.5" / "status.json").write_text('{"run": "v5.5", "status": "do')          # cut
    todo, done = plan(spec, out)
    assert not todo and done["v5.5"]["status"] == "done" and "recovered" in done["v5.5"]
    assert (out / "v5.5" / "status.json").read_text().endswith('"do')                  # a plan writes nothing
    again = run_sweep(spec, out, serial=True)
    assert again.skipped == ["v5.5"] and read_status(out / "v5.5")["metrics"]["speed_bl_per_min"] == \
        res.evaluation["speed_bl_per_min"]
    assert {k: v for k, v in digest(out / "v5.5").items() if k != "status.json"} == \
        {k: v for k, v in digest_before.items() if k != "status.json"}

    (out / "v5.5" / "v5.5.npz").unlink()                                                # deleted by hand
    todo, done = plan(spec, out)
    assert [r.name for r in todo] == ["v5.5"] and not done
    third = run_sweep(spec, out, serial=True)
    assert third.skipped == [] and third.count("done") == 1 and (out / "v5.5" / "v5.5.npz").is_file()


def test_a_speed_max_run_counts_its_whole_search_s_steps(tmp_path):
    """A ``--speed max`` run's summary counts every simulation step of its search (the candidates'
    optimisations, evaluations and hold replays), not only its chosen gait's optimisation."""
    spec = load_spec(ROOT / "examples" / "rl_seeds_coulomb.toml", tmp_path, quick=True).only(["tripod_trajopt_max"])
    assert run_sweep(spec, tmp_path, serial=True).statuses["tripod_trajopt_max"]["status"] == "done"
    ev = Result.load(tmp_path / "tripod_trajopt_max" / "tripod_trajopt_max.npz").evaluation
    steps = read_status(tmp_path / "tripod_trajopt_max")["metrics"]["sim_steps"]
    assert steps == ev["search_sim_steps"] > ev["optimization_sim_steps"]


@pytest.mark.parametrize("name", ["sweep_speeds.toml", "rl_seeds.toml", "rl_seeds_coulomb.toml"])
def test_example_sweep_files_load_full_and_quick(name):
    full = load_spec(ROOT / "examples" / name)
    quick = load_spec(ROOT / "examples" / name, quick=True)
    assert full.names() == quick.names() and len(full.runs) >= 4
    robots = {r.params.get("robot") for r in full.runs if "robot" in r.params}
    assert robots == {"tripod", "puppy"}


def test_rl_comparison_sweeps_are_the_same_runs_under_each_law_and_fair_budgets():
    """examples/rl_seeds*.toml (issue #28 item 4): the same runs under both laws; trajopt's
    ``--speed max`` gets exactly one PPO seed's simulation steps (its timesteps rounded up to whole
    rollouts, as PPO collects them); the long PPO run has 5x the seeds' budget."""
    import math

    from trajopt.rl.hyperparams import default_hyperparams
    specs = {law: load_spec(ROOT / "examples" / name)
             for law, name in (("paper", "rl_seeds.toml"), ("coulomb", "rl_seeds_coulomb.toml"))}
    assert specs["paper"].names() == specs["coulomb"].names()
    for law, spec in specs.items():
        assert {r.params["contact"] for r in spec.runs} == {law}
        runs = {r.name: r for r in spec.runs}
        for robot in ("tripod", "puppy"):
            trajopt = runs[f"{robot}_trajopt_max"]
            assert trajopt.kind == "optimize" and trajopt.params["speed"] == "max"
            seeds = [runs[f"{robot}_{algo}_seed{s}"] for algo in ("ppo", "sac") for s in (0, 1, 2)]
            assert {r.params["seed"] for r in seeds} == {0, 1, 2}
            ppo = runs[f"{robot}_ppo_seed0"].params
            rollout = default_hyperparams("ppo", n_envs=ppo["n_envs"])["n_steps"] * ppo["n_envs"]
            assert trajopt.params["max_sim_steps"] == math.ceil(ppo["timesteps"] / rollout) * rollout
            long = runs[f"{robot}_ppo5x_seed1"].params
            assert long["algo"] == "ppo" and long["timesteps"] == 5 * ppo["timesteps"]
            assert {k: v for k, v in long.items() if k not in ("timesteps", "checkpoint_every", "seed")} == \
                {k: v for k, v in ppo.items() if k not in ("timesteps", "checkpoint_every", "seed")}


def _free_port() -> int:
    import socket
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@dataclass(frozen=True)
class LocalRay:
    """A local Ray cluster: its ``address`` and the ``env`` its clients need (its token)."""

    address: str
    env: dict


@pytest.fixture(scope="module")
def local_ray(tmp_path_factory):
    """A local Ray cluster with 2 CPUs for this file's sweeps (started once: its start and stop
    take 5-10 s), run by ``ray start --head --block`` in a process group of its own: never in the
    test process. A Ray driver takes over its process (ray.init sets a SIGTERM handler that raises
    SystemExit, and the driver exits when it loses its raylet): in a pytest-xdist worker that
    crashed the worker and hung the whole test run. So the sweeps of these tests run as
    ``trajopt sweep --address`` subprocesses, with the cluster's token in their environment."""
    pytest.importorskip("ray")
    ray_bin = Path(sys.executable).with_name("ray")
    if not ray_bin.is_file():
        pytest.skip("the ray command is not installed beside this Python")
    port = _free_port()
    # the cluster's token (Ray's token authentication), given to the sweeps' subprocesses
    auth = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16)}
    # Ray starts its workers at nice 15: on a machine kept busy by other processes at normal
    # priority they would get ~1 % of a core and these tests would wait on the scheduler, not on
    # the sweep. Workers at the test's own priority make the waits independent of the load.
    env = dict(os.environ, **auth, RAY_worker_niceness="0", RAY_USAGE_STATS_ENABLED="0")
    log = tmp_path_factory.mktemp("ray_head") / "ray_head.log"
    with open(log, "w") as fh:
        head = subprocess.Popen([str(ray_bin), "start", "--head", "--block", f"--port={port}", "--num-cpus=2",
                                 "--include-dashboard=false", "--disable-usage-stats",
                                 f"--temp-dir={tempfile.mkdtemp(prefix='ray', dir='/tmp')}"],
                                env=env, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        _wait_for(lambda: "Ray runtime started" in log.read_text(), 120, "the Ray head", head, log)
        yield LocalRay(f"127.0.0.1:{port}", auth)
    finally:
        for sig, wait in ((signal.SIGTERM, 5), (signal.SIGKILL, 10)):
            try:
                os.killpg(head.pid, sig)
            except ProcessLookupError:
                break
            try:
                head.wait(timeout=wait)
                break
            except subprocess.TimeoutExpired:
                continue
        try:
            os.killpg(head.pid, signal.SIGKILL)           # what the head started and left behind
        except ProcessLookupError:
            pass


def sweep_env(ray: LocalRay) -> dict:
    """The environment of a ``trajopt sweep`` subprocess on ``ray``: this checkout first on the
    import path, the cluster's token."""
    return dict(os.environ, **ray.env, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))


def sweep_cli(spec_path: Path, out: Path, ray: LocalRay, *extra: str) -> subprocess.CompletedProcess:
    """``trajopt sweep SPEC --out OUT --address ADDRESS`` on ``ray`` in a subprocess (its output returned)."""
    env = sweep_env(ray)
    return subprocess.run([sys.executable, "-m", "trajopt.cli", "sweep", str(spec_path), "--out", str(out),
                           "--address", ray.address, *extra], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=load_scaled(900))


def statuses(spec, out: Path) -> dict[str, dict]:
    """Every run's status file, by name."""
    return {run.name: read_status(out / run.name) or {} for run in spec.runs}


def test_four_tiny_optimisations_write_results_and_summary(local_ray, tmp_path):
    spec_path = write(tmp_path, tiny_block("{robot}_v{speed:g}", 'robot = ["tripod"]\nspeed = [3.0, 4.0, 5.0, 6.0]')
                      .replace('robot = "tripod"\n', ""))
    out = tmp_path / "out"
    proc = sweep_cli(spec_path, out, local_ray)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "4 done, 0 failed, 0 interrupted of 4 runs" in proc.stdout
    spec = load_spec(spec_path, out)
    for run, v in zip(spec.runs, (3.0, 4.0, 5.0, 6.0)):
        res = Result.load(out / run.name / f"{run.name}.npz")
        assert res.settings["speed_bl_per_min"] == v and res.settings["n_cycle"] == 12
        assert read_status(out / run.name)["metrics"]["speed_bl_per_min"] == res.evaluation["speed_bl_per_min"]
    assert sorted(p.name for p in out.glob("summary.*")) == ["summary.csv", "summary.md", "summary.png"]
    csv_lines = (out / "summary.csv").read_text().splitlines()
    assert len(csv_lines) == 5 and all(",done," in ln for ln in csv_lines[1:])


def test_failed_run_is_reported_and_rerun_skips_finished_runs(local_ray, tmp_path):
    text = (tiny_block("ok{speed:g}", "speed = [3.0, 4.0, 5.0]") + tiny_block("broken", "_x = [0]", robot="no_such_robot.toml")
            + '[[runs]]\nkind = "evaluate"\nname = "eval3"\n[runs.args]\nresult = "{out}/ok3/ok3.npz"\ncycles = 1\n')
    out = tmp_path / "out"
    spec_path = write(tmp_path, text)
    proc = sweep_cli(spec_path, out, local_ray, "--no-plot")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    spec = load_spec(spec_path, out)
    status = statuses(spec, out)
    assert sorted(n for n, st in status.items() if st.get("status") == "done") == ["eval3", "ok3", "ok4", "ok5"]
    assert status["broken"]["status"] == "failed"
    # evaluations start after the optimisations they read
    ev = json.loads((out / "eval3" / "evaluation.json").read_text())
    assert status["eval3"]["started"] >= status["ok3"]["finished"]
    optimised = status["ok3"]["metrics"]          # `trajopt evaluate` prints 3 decimals
    assert ev["speed_bl_per_min"] == pytest.approx(optimised["speed_bl_per_min"], abs=6e-4)
    assert ev["upright"] == optimised["upright"]
    reason = status["broken"]["reason"]
    assert "no_such_robot.toml" in reason and "not found" in reason
    assert f"failed: broken: {reason}" in proc.stdout
    assert "no_such_robot.toml" in (out / "summary.md").read_text()
    before = {name: digest(out / name) for name in ("ok3", "ok4", "ok5")}

    todo, finished = plan(load_spec(spec_path, out), out)
    assert sorted(finished) == ["eval3", "ok3", "ok4", "ok5"] and [r.name for r in todo] == ["broken"]
    again = sweep_cli(spec_path, out, local_ray, "--no-plot")
    assert again.returncode == 1 and "(4 skipped as done)" in again.stdout, again.stdout + again.stderr
    assert read_status(out / "broken")["status"] == "failed"        # retried, fails again
    assert {name: digest(out / name) for name in before} == before   # finished runs untouched
    # a run directory made with other arguments is never overwritten
    changed = write(tmp_path, text.replace("speed = [3.0, 4.0, 5.0]", "speed = [3.0]").replace("seeds = 1", "seeds = 2"),
                    "changed.toml")
    with pytest.raises(ValueError, match="made with other arguments"):
        plan(load_spec(changed, out), out)


def load_scaled(seconds: float) -> float:
    """A safety-net deadline: ``seconds`` on an idle machine, times the load per core when the
    machine is busier (CI and shared machines run at load 10+ on 2 cores)."""
    try:
        load = os.getloadavg()[0] / (os.cpu_count() or 1)
    except (OSError, AttributeError):
        load = 1.0
    return seconds * max(1.0, load)


def _wait_for(predicate, timeout: float, what: str, proc: subprocess.Popen | None = None,
              log: Path | None = None) -> None:
    """Wait for an event (``predicate()`` true); ``timeout`` is only a safety net, scaled by
    the machine's load while waiting. If ``proc`` ends first, fail at once with its ``log``."""
    t0 = time.time()
    while not predicate():
        if proc is not None and proc.poll() is not None:
            output = log.read_text() if log is not None and log.is_file() else ""
            raise AssertionError(f"the sweep ended (exit {proc.returncode}) before {what}:\n{output}")
        if time.time() - t0 > load_scaled(timeout):
            raise AssertionError(f"timed out after {time.time() - t0:.0f} s waiting for {what}")
        time.sleep(0.25)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_killed_worker_and_sigint_leave_finished_runs_intact(local_ray, tmp_path, signum):
    """Two tiny runs finish, then two long ones start: the worker of one is killed (recorded as
    failed with the reason), then the sweep gets SIGINT (Ctrl-C) or SIGTERM: it exits 130 or 143,
    the other long run is interrupted with its checkpoint saved for --resume, and the finished
    runs are untouched. (ray.init sets a SIGTERM handler of its own, which exits the process: the
    sweep puts trajopt's back, so SIGTERM ends it as Ctrl-C does.)"""
    # the long runs: Puppy gaits on the paper's 72-step cycle, far from converged when stopped
    long_args = "iterations = 100\nseeds = 1\ncycles = 1\n"
    text = (tiny_block("quick{speed:g}", "speed = [3.0, 4.0]")
            + tiny_block("long{speed:g}", "speed = [5.0, 6.0]", robot="puppy").replace(TINY, long_args))
    out = tmp_path / "out"
    spec_path = write(tmp_path, text)
    address, env = local_ray.address, sweep_env(local_ray)
    log = tmp_path / "sweep.log"                     # a file, not a pipe: readable while it runs
    with open(log, "w") as log_fh:
        proc = subprocess.Popen([sys.executable, "-m", "trajopt.cli", "sweep", str(spec_path), "--out", str(out),
                                 "--address", address, "--no-plot"], cwd=ROOT, env=env,
                                stdout=log_fh, stderr=subprocess.STDOUT, text=True)
    try:
        done = lambda n: (read_status(out / n) or {}).get("status") == "done"   # noqa: E731
        _wait_for(lambda: done("quick3") and done("quick4"), 300, "the two tiny runs", proc, log)
        before = {n: digest(out / n) for n in ("quick3", "quick4")}
        _wait_for(lambda: all((out / n / f"{n}.partial.npz").is_file() for n in ("long5", "long6")), 300,
                  "the first checkpoints of the long runs", proc, log)
        os.kill(read_status(out / "long5")["pid"], signal.SIGKILL)
        _wait_for(lambda: (read_status(out / "long5") or {}).get("status") == "failed", 120,
                  "the killed run's status", proc, log)
        proc.send_signal(signum)
        # the sweep gives its runs in flight CANCEL_GRACE_S to save, then writes the summary and stops Ray
        proc.wait(timeout=load_scaled(300))
        output = log.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signum, output
    label = "Ctrl-C" if signum == signal.SIGINT else "SIGTERM"
    assert f"interrupted ({label}): stopping 1 runs in flight" in output, output
    assert {n: digest(out / n) for n in before} == before
    killed = read_status(out / "long5")
    assert killed["status"] == "failed" and "worker died" in killed["reason"]
    stopped = read_status(out / "long6")
    assert stopped["status"] == "interrupted", stopped
    assert json.loads((out / "long6" / "long6.partial.json").read_text())["status"] == "interrupted"
    assert (out / "summary.csv").is_file()
    spec = load_spec(spec_path, out)
    todo, finished = plan(spec, out)
    assert sorted(finished) == ["quick3", "quick4"] and sorted(r.name for r in todo) == ["long5", "long6"]
    assert resumes(spec.runs[3], out / "long6")                      # continues from its checkpoint


def _options(parser) -> dict[str, object]:
    """dest -> default of a parser's options (a test may read argparse's internals; of two
    options with one dest, ``--symmetry`` / ``--no-symmetry``, the first sets the default)."""
    out: dict[str, object] = {}
    for a in parser._actions:
        if a.option_strings and a.dest != "help":
            out.setdefault(a.dest, a.default)
    return out


def _sub(parser, *words):
    for word in words:
        parser = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices[word]
    return parser


@pytest.mark.parametrize("kind", ["optimize", "rl-train", "rl-evaluate", "evaluate"])
def test_run_kinds_describe_the_options_of_their_command(kind):
    """The sweep checks a run's options against the kinds' library-level description
    (trajopt.sweep.kinds), not the command line; the two name the same options, and the
    library functions the runs call take them with the command's defaults."""
    import inspect
    from trajopt.cli import build_parser
    from trajopt.optimize_run import OPTIMIZE_OPTIONS, OptimizeRun
    from trajopt.rl.options import TRAIN_OPTIONS, train_with_options
    from trajopt.sweep.kinds import KINDS
    desc = KINDS[kind]
    command = _options(_sub(build_parser(), *desc.command))
    assert set(desc.options) == set(command)
    library = {"optimize": {f: getattr(OptimizeRun("tripod"), f) for f in OPTIMIZE_OPTIONS if f != "robot"},
               "rl-train": {k: p.default for k, p in inspect.signature(train_with_options).parameters.items()
                            if k in TRAIN_OPTIONS}}.get(kind)
    if library is not None:
        assert library == {k: (v if k != "hp" else ()) for k, v in command.items()}


def test_a_spec_value_is_converted_as_the_command_line_converts_it(tmp_path):
    spec = load_spec(write(tmp_path, tiny_block("v{speed}", 'speed = ["5.5"]')), tmp_path / "out")
    assert spec.names() == ["v5.5"] and spec.runs[0].arguments()["speed"] == 5.5
    with pytest.raises(ValueError, match=r"sweep.toml: runs\[0\] \(run 'x'\): argument symmetry: must be true or false"):
        load_spec(write(tmp_path, tiny_block("x", "_k = [0]", extra="symmetry = 1\n")))


@pytest.mark.rl
def test_rl_runs_call_the_library_and_write_their_files(tmp_path):
    """An rl-train run (tiny PPO, exported as a Result) and an rl-evaluate run of it, in this
    process: their figures come from the files they wrote (policy.npz, evaluation.json)."""
    pytest.importorskip("stable_baselines3")
    hp = '["n_steps=32", "batch_size=32", "n_epochs=1", "policy_kwargs=dict(net_arch=[8])"]'
    text = ('[[runs]]\nkind = "rl-train"\nname = "ppo"\n[runs.args]\nrobot = "tripod"\ntimesteps = 64\n'
            f'n_envs = 1\nhp = {hp}\n'
            '[[runs]]\nkind = "rl-evaluate"\nname = "ppo_eval"\n[runs.args]\nmodel = "{out}/ppo"\ncycles = 1\n'
            'fidelity = true\n')
    out = tmp_path / "out"
    outcome = run_sweep(load_spec(write(tmp_path, text), out), out, serial=True)
    assert outcome.count("done") == 2, outcome.statuses
    trained = outcome.statuses["ppo"]
    assert trained["metrics"]["timesteps"] >= 64 and Result.load(out / "ppo" / "policy.npz").task == "rl"
    assert trained["command"][:4] == ["trajopt", "rl", "train", "tripod"]
    ev = json.loads((out / "ppo_eval" / "evaluation.json").read_text())
    assert ev["cycles"] == 1 and ev["speed_bl_per_min"] == outcome.statuses["ppo_eval"]["metrics"]["speed_bl_per_min"]
    # fidelity = true: the policy also at 2x, 4x and 8x finer physics, its own row the evaluation's
    rows = ev["fidelity"]["rows"]
    assert [r["factor"] for r in rows] == [1, 2, 4, 8] and rows[0]["speed_bl_per_min"] == ev["speed_bl_per_min"]
    assert [r["substeps"] for r in rows] == [ev["substeps"] * f for f in (1, 2, 4, 8)]


@pytest.mark.rl
def test_an_rl_evaluate_run_with_task_gives_the_task_s_score(tmp_path, monkeypatch):
    """``kind = "rl-evaluate"`` with ``task = true``: the run trained on a task id scored with its
    task's own score on the id (as ``trajopt rl evaluate --task``), in evaluation.json and the
    summary's metrics; the walk metric's options are refused with it."""
    pytest.importorskip("stable_baselines3")
    monkeypatch.setenv("SOFT_ENVS_QUICK", "1")                 # one evaluation episode
    hp = '["n_steps=32", "batch_size=32", "n_epochs=1", "policy_kwargs=dict(net_arch=[8])"]'
    text = ('[[runs]]\nkind = "rl-train"\nname = "ppo"\n[runs.args]\nrobot = "SoftTripodPushBox-v0"\ntimesteps = 32\n'
            f'n_envs = 1\nhp = {hp}\n'
            '[[runs]]\nkind = "rl-evaluate"\nname = "ppo_task"\n[runs.args]\nmodel = "{out}/ppo"\ntask = true\n'
            '[[runs]]\nkind = "rl-evaluate"\nname = "ppo_bad"\n[runs.args]\nmodel = "{out}/ppo"\ntask = true\n'
            'seed = 3\n')
    out = tmp_path / "out"
    outcome = run_sweep(load_spec(write(tmp_path, text), out), out, serial=True)
    assert outcome.count("done") == 2 and outcome.statuses["ppo_bad"]["status"] == "failed", outcome.statuses
    assert "task = true scores the task's own episodes: seed does not apply" in outcome.statuses["ppo_bad"]["reason"]
    ev = json.loads((out / "ppo_task" / "evaluation.json").read_text())
    assert ev["task"] == "push_box" and ev["env_id"] == "SoftTripodPushBox-v0" and len(ev["episodes"]) == 1
    assert outcome.statuses["ppo_task"]["metrics"]["task"]["score"] == ev["score"]


def test_a_sweep_off_a_terminal_beats_while_a_run_is_running(tmp_path, monkeypatch):
    """Off a terminal, a line per finished run (no carriage return), and a heartbeat line while
    a run takes longer than the heartbeat period (30 s, shortened here) (#41)."""
    import io

    import trajopt.progress
    monkeypatch.setattr(trajopt.progress, "HEARTBEAT_S", 0.05)
    out, stream = tmp_path / "out", io.StringIO()
    spec = load_spec(write(tmp_path, tiny_block("t{speed:g}", "speed = [5]")), out)
    outcome = run_sweep(spec, out, serial=True, stream=stream)
    assert outcome.statuses["t5"]["status"] == "done", outcome.statuses
    text = stream.getvalue()
    assert "\r" not in text and "sweep: 0/1 runs, still working" in text
    assert text.splitlines()[-1].startswith("[1/1] done        t5 ")


@pytest.mark.parametrize("second", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_second_signal_while_the_runs_in_flight_save_stops_the_wait(tmp_path, monkeypatch, second):
    """SIGTERM stops a sweep (the runs in flight are cancelled and given CANCEL_GRACE_S to
    save); a second SIGTERM or a Ctrl-C in that grace period ends the wait at once: the runs
    still out are recorded interrupted, and the signal is no exception escaping from Ray's wait
    (Ray's C++ wait turns one into a SystemError) or leaving them unrecorded. Ray is a stand-in
    here that sends the signals from its wait."""
    import trajopt.sweep.runner as runner
    from trajopt.hardware.signals import COMMAND_SIGNALS, StopSignals
    spec = load_spec(write(tmp_path, tiny_block("r{_k}", "_k = [1, 2]")), tmp_path / "out")
    waits = []

    class Cancelled(Exception):
        pass

    class FakeRay:
        class exceptions:
            TaskCancelledError = RayError = Cancelled

        def remote(self, fn):
            class Task:
                def options(self, **kw):
                    return self

                def remote(self, run, out):
                    return object()
            return Task()

        def wait(self, refs, num_returns, timeout):
            waits.append(len(refs))
            if len(waits) <= 2:                        # the sweep's wait, then the grace period's
                os.kill(os.getpid(), signal.SIGTERM if len(waits) == 1 else second)
            return [], list(refs)

        def cancel(self, ref):
            pass

    monkeypatch.setattr(runner, "start_ray", lambda workers, address: (FakeRay(), False))
    recorded = []

    class Quiet:
        def line(self, text):
            pass

    with StopSignals(signals=COMMAND_SIGNALS):          # the command's own handlers, as trajopt sweep's
        signum = runner._run_ray(spec.runs, tmp_path / "out", 1, None, recorded.append, Quiet())
    assert signum == signal.SIGTERM
    assert waits == [2, 2]                              # one wait of the grace period, not its 60 s of them
    assert [st["status"] for st in recorded] == ["interrupted", "interrupted"]
    assert all(st["reason"] == "interrupted (SIGTERM)" for st in recorded)
