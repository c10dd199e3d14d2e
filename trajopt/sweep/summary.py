"""The sweep's summary: ``summary.csv``, ``summary.md`` and ``summary.png`` (the main figure,
speed in body lengths per minute, of every run), all written atomically."""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

from ..results.files import atomic_write_png
from ..results.result import atomic_write_bytes
from .spec import SweepSpec
from .task import read_status

__all__ = ["summary_rows", "statuses_on_disk", "write_summary", "METRIC_COLUMNS"]

METRIC_COLUMNS = ("speed_bl_per_min", "upright", "target_bl_per_min", "objective", "gn_iterations",
                  "sim_steps", "timesteps", "result_status")


def summary_rows(spec: SweepSpec, statuses: dict[str, dict]) -> list[dict[str, Any]]:
    """One row per run of the spec: name, kind, status, reason, wall time, its grid
    parameters and its figures (empty where a run has none)."""
    params = sorted({k for r in spec.runs for k in r.params})
    rows = []
    for run in spec.runs:
        st = statuses.get(run.name) or {"status": "not started"}
        m = st.get("metrics") or {}
        row = {"run": run.name, "kind": run.kind, "status": st.get("status", "?"),
               "wall_time_s": st.get("wall_time_s")}
        row.update({p: run.params.get(p) for p in params})
        row.update({c: m.get(c) for c in METRIC_COLUMNS})
        task = m.get("task") or {}                  # task_score = true: the score on the task's id
        row["task_score"] = None if not task else f"{task.get('score'):.4g} {task.get('score_unit')}"
        row["reason"] = st.get("reason", "") if st.get("status") != "done" else ""
        rows.append(row)
    return rows


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.4g}"
    if isinstance(v, list):
        return " ".join(map(str, v))
    return str(v)


def statuses_on_disk(spec: SweepSpec, out: str | Path, statuses: dict[str, dict]) -> dict[str, dict]:
    """``statuses`` completed with the status.json of the spec's other runs under ``out`` (those a
    sweep restricted with ``--only`` left out), so that the summary lists the whole sweep."""
    out = Path(out)
    full = {}
    for run in spec.runs:
        st = statuses.get(run.name) or read_status(out / run.name)
        if st is not None:
            full[run.name] = st
    return full


def write_summary(spec: SweepSpec, statuses: dict[str, dict], out: str | Path, *, plot: bool = True) -> list[Path]:
    """Write summary.csv, summary.md and (``plot``) summary.png under ``out``."""
    out = Path(out)
    rows = summary_rows(spec, statuses)
    keys = list(rows[0]) if rows else ["run"]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r[k] is None else r[k]) for k in keys})
    written = [out / "summary.csv"]
    atomic_write_bytes(written[0], buf.getvalue().encode())

    shown = [k for k in keys if k in ("run", "kind", "status") or any(r.get(k) not in (None, "") for r in rows)]
    counts = {s: sum(r["status"] == s for r in rows) for s in ("done", "failed", "interrupted", "not started")}
    md = [f"# Sweep {spec.path.name}", ""]
    if spec.description:
        md += [spec.description, ""]
    md += [", ".join(f"{n} {s}" for s, n in counts.items() if n) + f" of {len(rows)} runs.", "",
           "| " + " | ".join(shown) + " |", "|" + "|".join("---" for _ in shown) + "|"]
    for r in rows:
        md.append("| " + " | ".join(_cell(r.get(k)).replace("|", "\\|") for k in shown) + " |")
    if plot and rows:
        written.append(_plot(rows, out / "summary.png", spec.path.name))
        md += ["", f"![speed per run]({written[-1].name})"]
    written.insert(1, out / "summary.md")
    atomic_write_bytes(out / "summary.md", ("\n".join(md) + "\n").encode())
    return written


def _plot(rows: list[dict], path: Path, sweep_name: str) -> Path:
    """The main figure of every run (its speed along the target in body lengths per minute,
    against its target) as one bar per run, titled with what that figure is and the sweep file."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = len(rows)
    fig, ax = plt.subplots(figsize=(7.0, 1.2 + 0.32 * n))
    colors = {"optimize": "tab:blue", "rl-train": "tab:orange", "rl-evaluate": "tab:green", "evaluate": "tab:purple"}
    for i, r in enumerate(rows):
        y = n - 1 - i
        v = r.get("speed_bl_per_min")
        if r["status"] == "done" and isinstance(v, (int, float)) and math.isfinite(v):
            ax.barh(y, v, color=colors.get(r["kind"], "grey"), alpha=0.85 if r.get("upright") is not False else 0.35)
            if isinstance(r.get("target_bl_per_min"), (int, float)):
                ax.plot([r["target_bl_per_min"]] * 2, [y - 0.4, y + 0.4], color="k", lw=1.5)
        else:
            ax.text(0, y, f" {r['status']}", va="center", color="tab:red", fontsize=8)
    ax.set_yticks(range(n))
    ax.set_yticklabels([r["run"] for r in reversed(rows)], fontsize=8)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("speed along the target [body lengths / min] (black tick: target; pale: fell)")
    ax.set_title(f"sweep {sweep_name}: each run's main figure, its speed along the target [BL/min]", fontsize=9)
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    return atomic_write_png(fig, path, dpi=110)
