"""Running a sweep: one Ray task per run, resuming, faults, Ctrl-C, progress.

A sweep holds its folder while it runs (``DIR/sweep.lock``, :mod:`trajopt.results.reservation`): a
second sweep into the same folder is refused at once. Runs whose ``status.json`` says ``done``
(with the same kind and parameters, and their result files present) are skipped;
the others (never started, failed, interrupted, killed) are started, optimisations from their
last checkpoint. A run that fails (exception, simulation error, killed worker) is recorded
with its reason and the others go on. Ctrl-C (or SIGTERM, SIGHUP where the caller turns them
into :class:`~trajopt.hardware.signals.Terminated`, as ``trajopt sweep`` does) cancels the runs in
flight (an optimisation saves its last iterate for ``--resume``), leaves every finished run as it
was, writes the summary and returns with ``interrupted = True`` and the ``signal``.
"""
from __future__ import annotations

import os
import signal as signals
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..hardware.signals import COMMAND_SIGNALS, StopSignals, Terminated, signal_label, signal_of
from ..progress import Progress
from ..results.reservation import reserve
from .spec import Run, SweepSpec
from .task import SWEEP_LOCK, execute, read_status, recover_status, result_present, write_status

__all__ = ["run_sweep", "SweepOutcome", "plan", "start_ray"]

#: seconds the runs in flight get to save themselves after Ctrl-C
CANCEL_GRACE_S = 60.0


@dataclass
class SweepOutcome:
    """What a sweep did: the final status of every run (by name), which were skipped as
    already done, whether it was interrupted (and by which signal: SIGINT for Ctrl-C), and its
    wall time."""

    statuses: dict[str, dict[str, Any]]
    skipped: list[str] = field(default_factory=list)
    interrupted: bool = False
    signal: int | None = None
    wall_time_s: float = 0.0

    def count(self, status: str) -> int:
        return sum(1 for s in self.statuses.values() if s.get("status") == status)


def plan(spec: SweepSpec, out: Path, *, repair: bool = False) -> tuple[list[Run], dict[str, dict]]:
    """(runs to start, statuses of the runs already done). A run directory made with other
    parameters is an error: the sweep never overwrites a result that is not its own. A run
    "done" whose result files were deleted is started again; an unreadable status.json is
    rebuilt from the run's result files (:func:`~trajopt.sweep.task.recover_status`; written
    back with ``repair``, only reported otherwise)."""
    todo, done = [], {}
    for run in spec.runs:
        st = read_status(out / run.name)
        if st is None:
            st = recover_status(run, out / run.name)
            if st is not None and repair:
                write_status(out / run.name, st)
        if st is not None and st.get("status") == "done" and not result_present(run, out / run.name):
            st = {**st, "status": "deleted", "reason": "its status said done but its result files are gone"}
        if st is not None and (st.get("kind") != run.kind or st.get("params") != _jsonish(run.params)):
            raise ValueError(f"{out / run.name}: holds run {run.name!r} made with other arguments "
                             f"(kind {st.get('kind')!r}, {st.get('params')}); this sweep file asks for "
                             f"{run.kind!r}, {run.params}. Use another --out, or move that directory away")
        if st is not None and st.get("status") == "done":
            done[run.name] = st
        else:
            todo.append(run)
    return todo, done


def _jsonish(params: dict) -> dict:
    import json
    return json.loads(json.dumps(params, default=str))


def start_ray(workers: int | None = None, address: str | None = None):
    """Connect to ``address`` ("auto", "ray://HOST:PORT", "HOST:PORT") or start a local Ray
    with ``workers`` CPUs (default: all); reuse a Ray already initialised in this process.
    ``ray.init`` sets a SIGTERM handler of its own (it exits the process); a handler the caller had
    set (``trajopt sweep``'s: an orderly end, as Ctrl-C) is put back. Returns (ray module, whether
    we started it)."""
    try:
        import ray
    except ImportError as exc:
        raise ValueError("trajopt sweep needs Ray, which is not installed: pip install soft-envs[ray]") from exc
    if ray.is_initialized():
        return ray, False
    kwargs: dict[str, Any] = {"log_to_driver": False, "configure_logging": True, "logging_level": "ERROR"}
    main = threading.current_thread() is threading.main_thread()
    previous = signals.getsignal(signals.SIGTERM) if main else None
    try:
        return _init_ray(ray, workers, address, kwargs), True
    finally:
        if callable(previous):              # SIG_DFL and SIG_IGN are not: Ray's handler stays then
            signals.signal(signals.SIGTERM, previous)


def _init_ray(ray, workers: int | None, address: str | None, kwargs: dict[str, Any]):
    """``ray.init`` at ``address``, else a local Ray of ``workers`` CPUs (:func:`start_ray`)."""
    if address:
        try:
            ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError, TimeoutError) as exc:
            raise ValueError(f"--address {address}: cannot connect to a Ray cluster there ({exc}); start one "
                             "with 'ray start --head' (see docs/scale.md) or leave --address out") from exc
    else:
        ray.init(num_cpus=int(workers or os.cpu_count() or 1), include_dashboard=False, **kwargs)
    return ray


class _Progress:
    """A tqdm bar over runs on a terminal, plain lines otherwise (and a heartbeat line after 30 s
    of silence, :class:`trajopt.progress.Progress`)."""

    def __init__(self, total: int, stream=None):
        self.total = total
        self.p = Progress(total, "sweep", "run", stream=stream, tty=None if total else False,
                          per_item=False, interval="default" if total else None)

    @property
    def n(self) -> int:
        return self.p.n

    def line(self, text: str) -> None:
        self.p.line(text)

    def done(self, st: dict) -> None:
        m = st.get("metrics") or {}
        fig = f", {m['speed_bl_per_min']:.2f} BL/min" if isinstance(m.get("speed_bl_per_min"), float) else ""
        why = f": {st.get('reason')}" if st.get("status") != "done" and st.get("reason") else ""
        text = (f"[{self.n + 1}/{self.total}] {st.get('status', '?'):<11} {st.get('run')} "
                f"({st.get('wall_time_s', 0.0):.1f} s{fig}){why}")
        self.p.update(1, line=text)

    def close(self) -> None:
        self.p.close()


def _crashed(run: Run, out: Path, exc: BaseException, started: float, status: str = "failed",
             signum: int = signals.SIGINT) -> dict:
    """Status of a run whose task died without writing its own (killed worker, lost node)."""
    st = read_status(out / run.name) or {"run": run.name, "kind": run.kind, "params": run.params,
                                          "cpus": run.cpus, "options": run.options, "started": started}
    if st.get("status") in ("done", "failed", "interrupted"):
        return st                                   # the task recorded it before dying
    first = (str(exc).strip().splitlines() or [""])[0]
    reason = (f"interrupted ({signal_label(signum)})" if status == "interrupted"
              else f"worker died ({type(exc).__name__}): {first}".strip())
    st.update(status=status, reason=reason, finished=time.time(), wall_time_s=time.time() - started)
    if (out / run.name).is_dir():
        write_status(out / run.name, st)
    return st


def run_sweep(spec: SweepSpec, out: str | os.PathLike, *, workers: int | None = None,
              address: str | None = None, serial: bool = False,
              on_status: Callable[[dict], None] | None = None, stream=None) -> SweepOutcome:
    """Run the runs of ``spec`` not yet done under ``out`` (see the module docstring):
    on Ray (``workers`` local CPUs, or the cluster at ``address``) or, with ``serial``, one
    after another in this process."""
    out = Path(out).resolve()
    plan(spec, out)                       # checks before anything is written
    out.mkdir(parents=True, exist_ok=True)
    with reserve(out / SWEEP_LOCK, f"sweep folder {out}"):      # a second sweep here is refused
        return _run_reserved(spec, out, workers, address, serial, on_status, stream)


def _run_reserved(spec: SweepSpec, out: Path, workers, address, serial, on_status, stream) -> SweepOutcome:
    todo, done = plan(spec, out, repair=True)
    t0 = time.perf_counter()
    progress = _Progress(len(todo), stream)
    if done:
        progress.line(f"{len(done)} of {len(spec.runs)} runs already done in {out}: skipped")
    statuses: dict[str, dict] = dict(done)
    outcome = SweepOutcome(statuses=statuses, skipped=sorted(done))

    def record(st: dict) -> None:
        statuses[st["run"]] = st
        progress.done(st)
        if on_status is not None:
            on_status(st)

    try:
        if serial:
            _run_serial(todo, out, record)
        else:
            outcome.signal = _run_ray(todo, out, workers, address, record, progress)
            outcome.interrupted = outcome.signal is not None
    except (KeyboardInterrupt, Terminated) as exc:
        outcome.interrupted, outcome.signal = True, signal_of(exc)
    finally:
        progress.close()
    for run in spec.runs:                 # what the files say is authoritative
        st = read_status(out / run.name)
        if st is not None:
            statuses[run.name] = st
    outcome.wall_time_s = time.perf_counter() - t0
    return outcome


def _run_serial(todo: list[Run], out: Path, record) -> None:
    for phase in (0, 1):
        for run in (r for r in todo if r.phase == phase):
            st = execute(run, out, threads=None)
            record(st)
            if st["status"] == "interrupted":
                raise KeyboardInterrupt


def _callers_signals() -> tuple[int, ...]:
    """Of SIGTERM and SIGHUP, those the caller handles (a Python function that is not Ray's own):
    :func:`_run_ray` holds them while Ray waits (:class:`StopSignals`, recording) and raises
    :class:`Terminated` between two waits. Ray's C++ wait lets a KeyboardInterrupt or a
    SystemExit raised by a handler through, and breaks on any other exception (SystemError)."""
    if threading.current_thread() is not threading.main_thread():
        return ()
    return tuple(s for s in COMMAND_SIGNALS if callable(h := signals.getsignal(s))
                 and not str(getattr(h, "__module__", "")).startswith("ray"))


def _run_ray(todo: list[Run], out: Path, workers, address, record, progress) -> int | None:
    """The runs ``todo`` on Ray; returns the signal that stopped them (SIGINT for Ctrl-C), or None."""
    if not todo:
        return None
    ray, started = start_ray(workers, address)
    remote = ray.remote(execute)
    pending: dict[Any, tuple[Run, float]] = {}
    held = StopSignals(holding=True, signals=_callers_signals())
    try:
        with held:
            for phase in (0, 1):
                for run in (r for r in todo if r.phase == phase):
                    ref = remote.options(num_cpus=run.cpus, max_retries=0, name=f"sweep:{run.name}").remote(run, out)
                    pending[ref] = (run, time.time())
                while pending:
                    ready, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
                    if held.held:
                        raise Terminated(held.held[0])
                    for ref in ready:
                        run, t_start = pending.pop(ref)
                        try:
                            st = ray.get(ref)
                        except ray.exceptions.TaskCancelledError as exc:
                            st = _crashed(run, out, exc, t_start, "interrupted")
                        except ray.exceptions.RayError as exc:      # killed worker, lost node, OOM
                            st = _crashed(run, out, exc, t_start)
                        record(st)
        return None
    except (KeyboardInterrupt, Terminated) as exc:
        signum = signal_of(exc) or signals.SIGINT
        # a second Ctrl-C or SIGTERM from here on ends the grace period's wait at once; the runs
        # still out are recorded interrupted all the same
        again = StopSignals(holding=True, signals=(signals.SIGINT, *_callers_signals()))
        with again:
            progress.line(f"interrupted ({signal_label(signum)}): stopping {len(pending)} runs in flight (they "
                          "save what they can)")
            for ref in pending:
                ray.cancel(ref)
            deadline = time.time() + CANCEL_GRACE_S
            while pending and time.time() < deadline and not again.held:
                ready, _ = ray.wait(list(pending), num_returns=len(pending), timeout=1.0)
                for ref in ready:
                    run, t_start = pending.pop(ref)
                    try:
                        st = ray.get(ref)
                    except ray.exceptions.RayError as err:
                        st = _crashed(run, out, err, t_start, "interrupted", signum)
                    record(st)
            for run, t_start in pending.values():
                record(_crashed(run, out, exc, t_start, "interrupted", signum))
        return signum
    finally:
        if started:
            ray.shutdown()
