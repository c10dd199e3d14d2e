"""The table of a ``--speed max`` search: one row per optimisation (:data:`TABLE_COLUMNS`),
written beside the result as ``NAME.search.csv`` and ``NAME.search.md``. ``credible_bl_per_min``
is what the search ranks by: the slowest member's speed of a gait optimised on an ensemble of
physics (:mod:`trajopt.optim.ensemble`; NaN and not upright when a member fell), else its speed.
A refined gait replayed at other physics steps (:mod:`trajopt.search.hold`) has its slowest speed
there (``slowest_bl_per_min``), the spread and whether it ``holds`` (empty: not checked), and the
replays' steps (``hold_sim_steps``, counted in ``total_sim_steps`` of the search's end)."""
from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np

from ..optim.gait import GaitSpec
from ..results.files import atomic_write_bytes
from ..results.result import Result

__all__ = ["TABLE_COLUMNS", "table_row", "search_table_paths", "write_search_table"]

#: the columns of the search table (one row per optimisation)
TABLE_COLUMNS = ("stage", "motor_model", "n_cycle", "n_keyframes", "horizon_cycles", "start", "target_bl_per_min", "iterations",
                 "status", "speed_bl_per_min", "credible_bl_per_min", "upright", "max_tilt_deg", "optimization_sim_steps",
                 "evaluation_sim_steps", "total_sim_steps", "wall_time_s", "slowest_bl_per_min", "spread", "holds",
                 "hold_sim_steps", "chosen")


def table_row(stage: str, res: Result | None, gait: GaitSpec, start: str, target: float, opt_steps: int,
              eval_steps: int, total: int, seconds: float, failure: str = "", motor_model: str = "") -> dict[str, Any]:
    """The row of one optimisation (``res`` None: skipped or failed, ``failure`` says which)."""
    ev = res.evaluation if res is not None else {}
    speed = float(ev.get("speed_bl_per_min", float("nan")))
    credible = float(ev.get("credible_bl_per_min", speed))    # an ensemble's slowest member, else the speed
    return {"stage": stage, "motor_model": motor_model, "n_cycle": gait.n_cycle, "n_keyframes": gait.n_keyframes,
            "horizon_cycles": gait.n_cycles, "start": start, "target_bl_per_min": round(target, 3),
            "iterations": len(res.history) if res is not None else 0,
            "status": res.status if res is not None else failure,
            "speed_bl_per_min": speed, "credible_bl_per_min": credible,
            "upright": bool(ev.get("upright", False)) and bool(np.isfinite(credible)), "max_tilt_deg": float(ev.get("max_tilt_deg", float("nan"))),
            "optimization_sim_steps": opt_steps, "evaluation_sim_steps": eval_steps, "total_sim_steps": total,
            "wall_time_s": round(seconds, 2), "slowest_bl_per_min": float("nan"), "spread": float("nan"),
            "holds": "", "hold_sim_steps": 0, "chosen": False}


#: what the table's target column is (printed under the Markdown table)
TARGET_NOTE = ("target_bl_per_min: the speed of the target COM path each optimisation tracked; the optimiser "
               "tracks that path and does not enforce its speed (speed_bl_per_min is what the gait did).")


def search_table_paths(result_file: str | Path) -> tuple[Path, Path]:
    """``(NAME.search.csv, NAME.search.md)`` beside the result ``NAME.npz``."""
    p = Path(result_file)
    stem = p.name.removesuffix(".npz")
    return p.with_name(stem + ".search.csv"), p.with_name(stem + ".search.md")


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.3f}" if np.isfinite(v) else "nan"
    return str(v)


def write_search_table(rows: list[dict], result_file: str | Path) -> tuple[Path, Path]:
    """Write the search table beside ``result_file`` as CSV and Markdown (atomically); the paths."""
    csv_path, md_path = search_table_paths(result_file)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=TABLE_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_bytes(csv_path, buf.getvalue().encode())
    lines = ["| " + " | ".join(TABLE_COLUMNS) + " |", "|" + "---|" * len(TABLE_COLUMNS)]
    lines += ["| " + " | ".join(_cell(r[c]) for c in TABLE_COLUMNS) + " |" for r in rows]
    lines += ["", TARGET_NOTE]
    atomic_write_bytes(md_path, ("\n".join(lines) + "\n").encode())
    return csv_path, md_path
