"""The task suite's ledger: what every run of ``examples/suite.toml`` scored, kept in the
repository (``benchmarks/results/suite_runs.json``), so that the report is made from every run ever
made, not only from the runs in this machine's sweep folder (``results/`` is not tracked: a new
machine, or a folder cleaned, would otherwise take ~40 core-hours of runs with it).

One record per run, keyed by its name in the sweep file::

    {"task", "robot", "method",          # its row of the report (bench_suite.group_of)
     "kind", "params",                   # the sweep file's run; a record of other params is not used
     "score", "episode_std",             # its task score (mean over the evaluation episodes), their std
     "success_rate", "score_unit", "score_name", "sim_steps", "wall_time_s",
     "hold": {"slowest", "spread", "holds"} | null,    # task_hold.json's replays (slowest null: a fall)
     "rl": {"algo", "target", "n_envs", "timesteps", "hyperparams", "hyperparams_source"} | null,
     "made": "YYYY-MM-DD", "machine",
     "from": "..."}                      # optional: where a record not made from its run's folder came from

and, for runs whose records were not kept one by one, one aggregate per row (``"aggregates"``,
keyed ``task/robot/method``: ``n``, ``mean``, ``std``, ``credible``, ``replayed``, ``hold``,
``success``, ``sim_steps``, ``wall``, ``rl`` (without ``target``), ``runs`` (name -> params),
``from``). A row with a record of any of its runs is made from the records alone (its aggregate
is dropped then: the runs were made again).

A run in the sweep folder replaces its record (the run on disk is the one that counts); the
ledger is written atomically whenever ``bench_suite.py`` writes its report.
"""
from __future__ import annotations

import json
import math
import platform
import time
from pathlib import Path
from typing import Any

from trajopt.results.files import atomic_write_bytes
from trajopt.rl.hyperparams import jsonable

VERSION = 1
RUN_FIELDS = ("task", "robot", "method", "kind", "params", "score", "episode_std", "success_rate", "score_unit",
              "score_name", "sim_steps", "wall_time_s", "hold", "rl", "made", "machine")
AGGREGATE_FIELDS = ("task", "robot", "method", "n", "mean", "std", "credible", "replayed", "hold", "success",
                    "sim_steps", "wall", "score_unit", "score_name", "rl", "runs", "from")
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
            where = f"{path}: {section}[{key!r}]"
            if not isinstance(rec, dict):
                raise ValueError(f"{where} must be a table, got {type(rec).__name__}")
            missing = [f for f in fields if f not in rec]
            if missing:
                raise ValueError(f"{where} lacks the field(s) {', '.join(missing)}")
            for f in ("score", "mean", "std", "episode_std", "success_rate", "success", "sim_steps", "wall_time_s",
                      "wall", "credible"):
                if f in rec and rec[f] is not None and not _is_number(rec[f]):
                    raise ValueError(f"{where}.{f} must be a number, got {rec[f]!r}")
            hold = rec.get("hold")
            if section == "runs" and hold is not None and (
                    not isinstance(hold, dict) or {"slowest", "spread", "holds"} - set(hold)):
                raise ValueError(f"{where}.hold must be null or a table with slowest, spread and holds, got {hold!r}")
    return data


def save(path: Path, ledger: dict[str, Any]) -> None:
    """Write ``ledger`` to ``path`` atomically (sorted, one record per few lines: diffs read well)."""
    out = {"about": ABOUT, "version": VERSION,
           "runs": {k: ledger["runs"][k] for k in sorted(ledger["runs"])},
           "aggregates": {k: ledger["aggregates"][k] for k in sorted(ledger["aggregates"])}}
    atomic_write_bytes(Path(path), (json.dumps(out, indent=1, allow_nan=False) + "\n").encode())


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _finite_or_none(x: Any) -> float | None:
    return float(x) if x is not None and math.isfinite(float(x)) else None


def run_record(group: tuple[str, str, str], run: Any, status: dict[str, Any], task_score: dict[str, Any],
               hold: dict[str, Any] | None, rl: dict[str, Any] | None) -> dict[str, Any]:
    """The record of one run done (its sweep ``status``, its ``task_score.json``, its replays
    ``hold`` or None, its RL configuration ``rl`` or None)."""
    import numpy as np
    task = status["metrics"]["task"]
    episodes = [float(e["score"]) for e in task_score.get("episodes", [])]
    return {"task": group[0], "robot": group[1], "method": group[2], "kind": run.kind, "params": jsonable(run.params),
            "score": float(task["score"]),
            "episode_std": float(np.std(episodes, ddof=1)) if len(episodes) > 1 else 0.0,
            "success_rate": float(task["success_rate"]), "score_unit": task["score_unit"],
            "score_name": task["score_name"], "sim_steps": float(status["metrics"].get("sim_steps") or 0),
            "wall_time_s": float(status.get("wall_time_s", 0.0)),
            "hold": None if hold is None else {"slowest": _finite_or_none(hold["slowest"]),
                                               "spread": _finite_or_none(hold["spread"]), "holds": bool(hold["holds"])},
            "rl": rl, "made": time.strftime("%Y-%m-%d", time.localtime(status.get("finished", time.time()))),
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


def update(ledger: dict[str, Any], records: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``ledger`` with ``records`` (by run name) in place of its own, and without the aggregates
    of the rows they belong to (a new ledger; ``ledger`` is left as it was)."""
    runs = {**ledger["runs"], **records}
    rows = {"/".join((r["task"], r["robot"], r["method"])) for r in records.values()}
    aggregates = {k: v for k, v in ledger["aggregates"].items() if k not in rows}
    return {"about": ABOUT, "version": VERSION, "runs": runs, "aggregates": aggregates}
