"""A study's best made the robot's tuned values (``trajopt rl tune ID --check 3 --adopt``): written
into ``trajopt/rl/zoo/tuned.toml`` (:mod:`.tuned`) only when its check on the suite's seeds
(:mod:`.check`) found it better than the defaults."""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from .check import CHECK, _read_summary
from . import tuned
from .tuned import read_tuned, tuned_text

__all__ = ["adopt"]


#: check seeds an adoption needs at least (the suite's 3)
MIN_CHECK_SEEDS = 3


def adopt(out: str | os.PathLike, path: str | os.PathLike | None = None) -> dict[str, Any]:
    """Write the best of the study in ``out`` into ``path`` (default :data:`~.tuned.TUNED_FILE`) as
    its robot's table for its algorithm (replacing that table, keeping the others). Refused
    (ValueError, the file untouched) unless:

    * the study's trials had the suite's budget and environments (values found on short trials
      would be used on the suite's 30,000-step runs);
    * its best was checked (``out/check.json``, :func:`~.check.check_best`) on at least
      :data:`MIN_CHECK_SEEDS` of the suite's seeds and beat the defaults there: its mean higher by
      more than the standard error of the difference, ``hypot(std_best, std_defaults) / sqrt(n)``
      (the seeds' spread is large: one lucky seed is not a gain), and its *credible* mean too (each
      run's lowest score over its replays at other physics steps): a gain that lives in the
      physics step's error is not a gain;
    * where the robot already has a table for the algorithm, it beat that table's best on the
      check too (both checks score the suite's seeds the same way): remove the table to replace it
      with a worse one.

    Returns the table."""
    from ...results.files import atomic_write_bytes
    from ..envs import robot_name
    from ..hyperparams import SUITE_N_ENVS, SUITE_TIMESTEPS
    out, path = Path(out), Path(tuned.TUNED_FILE if path is None else path)
    summary = _read_summary(out)
    if (int(summary["timesteps"]), int(summary["n_envs"])) != (SUITE_TIMESTEPS, SUITE_N_ENVS):
        raise ValueError(f"{out}: its trials had {summary['timesteps']} steps and {summary['n_envs']} environments, "
                         f"not the suite's {SUITE_TIMESTEPS} and {SUITE_N_ENVS}: not adopted")
    try:
        check = json.loads((out / CHECK).read_text())
        seeds, difference = list(check["seeds"]), float(check["difference"])
    except FileNotFoundError:
        raise ValueError(f"{out / CHECK}: the best is not checked yet (trajopt rl tune ID --out {out} --check 3)") \
            from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{out / CHECK}: not a check ({type(exc).__name__}: {exc})") from None
    best = summary["best"]
    if best["number"] == summary["defaults"]["number"]:
        raise ValueError(f"{out}: the defaults are the study's best: nothing to adopt")
    if check.get("best") is None or check["best"].get("trial") != best["number"]:
        raise ValueError(f"{out / CHECK}: checks {'no trial' if check.get('best') is None else 'trial ' + str(check['best'].get('trial'))}, "
                         f"not the study's best (trial {best['number']}): check it again")
    if len(seeds) < MIN_CHECK_SEEDS:
        raise ValueError(f"{out / CHECK}: checked on {len(seeds)} seed(s); adopting needs {MIN_CHECK_SEEDS} (--check 3)")
    n = len(seeds)
    margin = math.hypot(float(check["best"].get("std", 0.0)), float(check["defaults"].get("std", 0.0))) / math.sqrt(n)
    if not difference > margin:
        raise ValueError(f"{out}: the best (trial {best['number']}) scored {check['best']['mean']:.3f} on the suite's "
                         f"seeds, the defaults {check['defaults']['mean']:.3f}: a difference of {difference:+.3f}, not "
                         f"above its standard error {margin:.3f}: the defaults stay")
    if "credible_difference" not in check:
        raise ValueError(f"{out / CHECK}: made without the replays at other physics steps (a check made before they "
                         f"were part of it): check it again (trajopt rl tune ID --out {out} --check 3)")
    credible = float(check["credible_difference"])
    c_margin = math.hypot(float(check["best"].get("credible_std", 0.0)),
                          float(check["defaults"].get("credible_std", 0.0))) / math.sqrt(n)
    if not credible > c_margin:
        raise ValueError(f"{out}: the best (trial {best['number']}) scored credibly {check['best']['credible_mean']:.3f} "
                         f"(the lowest over the replays at other physics steps), the defaults "
                         f"{check['defaults']['credible_mean']:.3f}: a difference of {credible:+.3f}, not above its "
                         f"standard error {c_margin:.3f}: the defaults stay")
    algo, robot = summary["algo"], robot_name(summary["env_id"])
    tables = read_tuned(path)
    old = tables.get((algo, robot))
    if old is not None and not float(check["best"]["mean"]) > old["check_best_mean"]:
        raise ValueError(f"{path}: [{algo}.{robot}] (study {old['study']}, trial {old['trial']}) scored "
                         f"{old['check_best_mean']:.3f} on its check, this best {check['best']['mean']:.3f}: it stays")
    table = {"study": summary["env_id"], "trials": int(summary["n_finished"]), "trial": int(best["number"]),
             "study_score": float(best["score"]), "defaults_score": float(summary["defaults"]["score"]),
             "check_seeds": [int(s) for s in seeds], "check_best_mean": float(check["best"]["mean"]),
             "check_defaults_mean": float(check["defaults"]["mean"]),
             "check_best_credible": float(check["best"]["credible_mean"]),
             "check_defaults_credible": float(check["defaults"]["credible_mean"]),
             "score_unit": str(summary.get("score_unit")),
             "params": dict(best["params"])}
    tables[(algo, robot)] = table
    atomic_write_bytes(path, tuned_text(tables).encode())
    return table
