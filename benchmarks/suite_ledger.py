"""The task suite's ledger: what every run of ``examples/suite.toml`` scored, kept in the
repository (``benchmarks/results/suite_runs.json``), so that the report is made from every run ever
made, not only from the runs in this machine's sweep folder (``results/`` is not tracked: a new
machine, or a folder cleaned, would otherwise take ~40 core-hours of runs with it).

One record per run, keyed by its name in the sweep file::

    {"task", "robot", "method",          # its row of the report (bench_suite.group_of)
     "kind", "params",                   # the sweep file's run; a record of other params is not used
     "score", "episode_std",             # its task score (mean over the evaluation episodes), their std
     "success_rate", "score_unit", "score_name", "sim_steps", "wall_time_s",   # steps, time: null if not kept
     "hold": {"slowest", "spread", "holds"} | null,    # task_hold.json's replays (slowest null: a
                                                       # simulation failed; spread null: not kept or infinite)
     "rl": {"algo", "target", "n_envs", "timesteps", "hyperparams", "hyperparams_source"} | null,
     "finished": UNIX time | null, "made": "YYYY-MM-DD" | null, "machine",
     "from": "..."}                      # optional: where a record not made from its run's folder came from

and, for runs whose records were not kept one by one, one aggregate per row (``"aggregates"``,
keyed ``task/robot/method``: ``n``, ``mean``, ``std``, ``credible``, ``replayed``, ``hold``,
``success``, ``sim_steps``, ``wall``, ``rl`` (without ``target``), ``runs`` (name -> params),
``from``). A row with a record of any of its runs is made from the records alone (its aggregate
is dropped then: the runs were made again).

A run in the sweep folder replaces its record unless the record is of a run finished later
(another machine made it again since); the ledger is updated under a file lock and written
atomically whenever ``bench_suite.py`` writes its report.
"""
from __future__ import annotations

import contextlib
import json
import math
import platform
import time
from pathlib import Path
from typing import Any, Iterator

from trajopt.results.files import FileLock, atomic_write_bytes
from trajopt.rl.hyperparams import jsonable

VERSION = 1
RUN_FIELDS = ("task", "robot", "method", "kind", "params", "score", "episode_std", "success_rate", "score_unit",
              "score_name", "sim_steps", "wall_time_s", "hold", "rl", "finished", "made", "machine")
AGGREGATE_FIELDS = ("task", "robot", "method", "n", "mean", "std", "credible", "replayed", "hold", "success",
                    "sim_steps", "wall", "score_unit", "score_name", "rl", "runs", "from")
_NUMBERS = {"runs": (("score", "episode_std", "success_rate"), ("sim_steps", "wall_time_s", "finished")),
            "aggregates": (("mean", "std", "success"), ("credible", "sim_steps", "wall"))}   # (required, or null)
_TEXTS = ("task", "robot", "method", "score_unit", "score_name")
_RL_FIELDS = {"algo": str, "n_envs": int, "timesteps": int, "hyperparams": dict, "hyperparams_source": str}
ABOUT = ("The task suite's runs (examples/suite.toml), one record each, from which "
         "benchmarks/bench_suite.py makes benchmarks/results/suite.md; see benchmarks/suite_ledger.py.")


def empty() -> dict[str, Any]:
    return {"about": ABOUT, "version": VERSION, "runs": {}, "aggregates": {}}


def load(path: Path) -> dict[str, Any]:
    """The ledger at ``path`` (an empty one when there is no file), its every record checked:
    a ValueError names the file, the record and the field."""
    path = Path(path)
    if not path.exists():
        return empty()
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable JSON file ({exc})") from exc
    if not isinstance(data, dict) or data.get("version") != VERSION:
        raise ValueError(f"{path}: not a suite ledger of version {VERSION} (its 'version' is "
                         f"{data.get('version') if isinstance(data, dict) else None!r})")
    for section, fields in (("runs", RUN_FIELDS), ("aggregates", AGGREGATE_FIELDS)):
        records = data.get(section)
        if not isinstance(records, dict):
            raise ValueError(f"{path}: '{section}' must be a table of records, got {type(records).__name__}")
        for key, rec in records.items():
            _check_record(f"{path}: {section}[{key!r}]", section, fields, rec)
    return data


def _check_record(where: str, section: str, fields: tuple[str, ...], rec: Any) -> None:
    if not isinstance(rec, dict):
        raise ValueError(f"{where} must be a table, got {type(rec).__name__}")
    missing = [f for f in fields if f not in rec]
    if missing:
        raise ValueError(f"{where} lacks the field(s) {', '.join(missing)}")
    required, nullable = _NUMBERS[section]
    for f in required + nullable:
        if not (_is_number(rec[f]) or (f in nullable and rec[f] is None)):
            raise ValueError(f"{where}.{f} must be a number{' or null' if f in nullable else ''}, got {rec[f]!r}")
    for f in _TEXTS:
        if not isinstance(rec[f], str):
            raise ValueError(f"{where}.{f} must be a text, got {rec[f]!r}")
    if section == "runs":
        if not isinstance(rec["params"], dict) or not isinstance(rec["kind"], str):
            raise ValueError(f"{where}: kind must be a text and params a table, got {rec['kind']!r}, {rec['params']!r}")
        hold = rec["hold"]
        if hold is not None and not (isinstance(hold, dict) and not {"slowest", "spread", "holds"} - set(hold)
                                     and all(hold[k] is None or _is_number(hold[k]) for k in ("slowest", "spread"))
                                     and isinstance(hold["holds"], bool)):
            raise ValueError(f"{where}.hold must be null or a table of slowest and spread (numbers or null) and "
                             f"holds (true or false), got {hold!r}")
    else:
        for f in ("n", "replayed", "hold"):
            if not (isinstance(rec[f], int) and not isinstance(rec[f], bool) and rec[f] >= 0):
                raise ValueError(f"{where}.{f} must be a whole number >= 0, got {rec[f]!r}")
        if not (rec["hold"] <= rec["replayed"] <= rec["n"]) or rec["n"] < 1:
            raise ValueError(f"{where}: hold <= replayed <= n and n >= 1 must be, got {rec['hold']}, "
                             f"{rec['replayed']}, {rec['n']}")
        if not isinstance(rec["runs"], dict) or not all(isinstance(p, dict) for p in rec["runs"].values()):
            raise ValueError(f"{where}.runs must be a table of run names to their params, got {rec['runs']!r}")
    rl = rec["rl"]
    if rl is not None:
        if not isinstance(rl, dict):
            raise ValueError(f"{where}.rl must be null or a table, got {rl!r}")
        for f, kind in _RL_FIELDS.items():
            if not isinstance(rl.get(f), kind) or isinstance(rl.get(f), bool):
                raise ValueError(f"{where}.rl.{f} must be a {kind.__name__}, got {rl.get(f)!r}")


def save(path: Path, ledger: dict[str, Any]) -> None:
    """Write ``ledger`` to ``path`` atomically (sorted, one field per line: diffs read well)."""
    out = {"about": ABOUT, "version": VERSION,
           "runs": {k: ledger["runs"][k] for k in sorted(ledger["runs"])},
           "aggregates": {k: ledger["aggregates"][k] for k in sorted(ledger["aggregates"])}}
    for section, fields in (("runs", RUN_FIELDS), ("aggregates", AGGREGATE_FIELDS)):
        for key, rec in out[section].items():
            try:
                _check_record(f"{path}: {section}[{key!r}]", section, fields, rec)
            except ValueError as exc:
                raise ValueError(f"{exc} (the ledger is not written)") from None
    atomic_write_bytes(Path(path), (json.dumps(out, indent=1, allow_nan=False) + "\n").encode())


@contextlib.contextmanager
def locked(path: Path) -> Iterator[None]:
    """Hold the lock of the ledger at ``path`` (``PATH.lock`` beside it): two reports written at
    once each read, update and write the ledger in turn, and neither loses the other's records."""
    lock = FileLock(Path(path).with_name(Path(path).name + ".lock"))
    try:
        with lock:
            yield
    finally:
        lock.close()


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _finite_or_none(x: Any) -> float | None:
    return float(x) if x is not None and math.isfinite(float(x)) else None


def run_record(group: tuple[str, str, str], run: Any, status: dict[str, Any], task_score: dict[str, Any],
               hold: dict[str, Any] | None, rl: dict[str, Any] | None) -> dict[str, Any]:
    """The record of one run done (its sweep ``status``, its ``task_score.json``, its replays
    ``hold`` or None, its RL configuration ``rl`` or None); a ValueError names the run when its
    score is not a finite number."""
    import numpy as np
    task = status["metrics"]["task"]
    episodes = [float(e["score"]) for e in task_score.get("episodes", [])]
    if not _is_number(task.get("score")) or not all(math.isfinite(e) for e in episodes):
        raise ValueError(f"run {run.name!r}: its task score {task.get('score')!r} (episodes {episodes}) is not "
                         "a finite number: its record is not kept")
    finished = status.get("finished")
    return {"task": group[0], "robot": group[1], "method": group[2], "kind": run.kind, "params": jsonable(run.params),
            "score": float(task["score"]),
            "episode_std": float(np.std(episodes, ddof=1)) if len(episodes) > 1 else 0.0,
            "success_rate": float(task["success_rate"]), "score_unit": task["score_unit"],
            "score_name": task["score_name"], "sim_steps": _finite_or_none(status["metrics"].get("sim_steps") or 0),
            "wall_time_s": _finite_or_none(status.get("wall_time_s", 0.0)),
            "hold": None if hold is None else {"slowest": _finite_or_none(hold["slowest"]),
                                               "spread": _finite_or_none(hold["spread"]), "holds": bool(hold["holds"])},
            "rl": rl, "finished": _finite_or_none(finished),
            "made": time.strftime("%Y-%m-%d", time.localtime(finished)) if _is_number(finished) else None,
            "machine": platform.node()}


def current(ledger: dict[str, Any], run: Any) -> dict[str, Any] | None:
    """The ledger's record of ``run`` when it was made with the sweep file's arguments now, else None."""
    rec = ledger["runs"].get(run.name)
    if rec is None or rec["kind"] != run.kind or rec["params"] != jsonable(run.params):
        return None
    return rec


def aggregate(ledger: dict[str, Any], group: tuple[str, str, str], runs: list[Any]) -> dict[str, Any] | None:
    """The ledger's aggregate of the row ``group`` when its runs are the sweep file's ``runs`` with
    their arguments now (by name), else None."""
    agg = ledger["aggregates"].get("/".join(group))
    if agg is None:
        return None
    planned = {r.name: jsonable(r.params) for r in runs}
    if any(planned.get(name) != params for name, params in agg["runs"].items()):
        return None
    return agg


def newer(local: dict[str, Any] | None, kept: dict[str, Any] | None) -> dict[str, Any] | None:
    """Of a run's record from the sweep folder (``local``) and the ledger's (``kept``), the one to
    use: the local one, unless the ledger's is of a run finished later (made again elsewhere)."""
    if local is None or kept is None:
        return local or kept
    return kept if (kept.get("finished") or 0) > (local.get("finished") or 0) else local


def update(ledger: dict[str, Any], records: dict[str, dict[str, Any]]) -> tuple[dict[str, Any], list[str]]:
    """``ledger`` with ``records`` (by run name) in place of its own, but where its own is of a run
    finished later (made again elsewhere since), and without the aggregates whose runs all have a
    record now, made with the aggregate's arguments (a row made again run by run keeps its
    aggregate until the last): a new ledger (``ledger`` is left as it was) and what was kept or
    replaced, to say."""
    runs, said = dict(ledger["runs"]), []
    for name, rec in records.items():
        old = runs.get(name)
        if old is not None and newer(rec, old) is old:
            said.append(f"{name}: the ledger's record (made {old.get('made')} on {old.get('machine')}) is newer "
                        f"than the run in the sweep folder (made {rec.get('made')}): kept")
            continue
        if old is not None and old != rec:
            said.append(f"{name}: its record replaced by the run in the sweep folder "
                        f"({old['score']:+.4g} -> {rec['score']:+.4g} {rec['score_unit']})")
        runs[name] = rec
    aggregates = {k: v for k, v in ledger["aggregates"].items()
                  if not all(n in runs and runs[n]["params"] == params for n, params in v["runs"].items())}
    return {"about": ABOUT, "version": VERSION, "runs": runs, "aggregates": aggregates}, said
