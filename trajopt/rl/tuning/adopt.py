"""A study's best made the robot's tuned values (``trajopt rl tune ID --check 3 --adopt``): written
into ``trajopt/rl/zoo/tuned.toml`` (:mod:`.tuned`) only when its check on the suite's seeds
(:mod:`.check`) found it better than the defaults."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from .check import CHECK, _read_summary
from .tuned import TUNED_FILE, read_tuned, tuned_text

__all__ = ["adopt"]


def adopt(out: str | os.PathLike, path: str | os.PathLike | None = None) -> dict[str, Any]:
    """Write the best of the study in ``out`` into ``path`` as its robot's table for its algorithm
    (replacing that table, keeping the others). Refused (ValueError) unless the study's best was
    checked (``out/check.json``, :func:`~.check.check_best`) and beat the defaults there: its mean
    over the suite's seeds higher than theirs. Returns the table."""
    from ...results.files import atomic_write_bytes
    from ..envs import robot_name
    out, path = Path(out), Path(TUNED_FILE if path is None else path)
    summary = _read_summary(out)
    try:
        check = json.loads((out / CHECK).read_text())
    except FileNotFoundError:
        raise ValueError(f"{out / CHECK}: the best is not checked yet (trajopt rl tune ID --out {out} --check 3)") \
            from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"{out / CHECK}: {exc}") from None
    best = summary["best"]
    if check.get("best") is None or check["best"].get("trial") != best["number"]:
        raise ValueError(f"{out / CHECK}: checks {'no trial' if check.get('best') is None else 'trial ' + str(check['best'].get('trial'))}, "
                         f"not the study's best (trial {best['number']}): check it again")
    if not check["difference"] > 0:
        raise ValueError(f"{out}: the best (trial {best['number']}) scored {check['best']['mean']:.3f} on the suite's "
                         f"seeds, the defaults {check['defaults']['mean']:.3f}: the defaults stay")
    algo, robot = summary["algo"], robot_name(summary["env_id"])
    table = {"study": summary["env_id"], "trials": int(summary["n_finished"]), "trial": int(best["number"]),
             "study_score": float(best["score"]), "defaults_score": float(summary["defaults"]["score"]),
             "check_seeds": [int(s) for s in check["seeds"]], "check_best_mean": float(check["best"]["mean"]),
             "check_defaults_mean": float(check["defaults"]["mean"]), "score_unit": str(summary.get("score_unit")),
             "params": dict(best["params"])}
    tables = read_tuned(path)
    tables[(algo, robot)] = table
    atomic_write_bytes(path, tuned_text(tables).encode())
    return table
