"""A tuning study's best checked on the suite's own seeds (:mod:`trajopt.rl.tuning`).

The best of N trials on one held-out training seed is an optimistic figure (it was chosen for
being high). :func:`check_best` trains the best trial's hyper-parameters *and* the defaults with
the suite's training seeds 0, 1, ..., as the suite trains (examples/suite.toml: the same budget
and environments), and scores each with the suite's evaluation (its episodes 0-2): whether the
best beats the defaults on seeds it was not chosen on. Each run is also replayed at other physics
steps, as the suite's runs are (:func:`trajopt.tasks.play.policy_task_hold`: half, twice and four
times its physics steps per control step, the control step unchanged): its *credible* score is
the lowest of them, and a gain that lives in the physics step's error is not a gain. The runs go
in ``out/check/`` (a run already made with the same hyper-parameters is scored again, not trained
again; its replays, in its ``task_hold.json``, are kept while its score is the same) and the
figures in ``out/check.json`` (written atomically).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from .study import SUMMARY
from .space import hyperparams_of

__all__ = ["CHECK", "HOLD", "check_best"]

#: the check's figures, inside the study's folder
CHECK = "check.json"
#: a check run's replays at other physics steps, inside its folder (the suite's name for them)
HOLD = "task_hold.json"


def _read_summary(out: Path) -> dict[str, Any]:
    path = out / SUMMARY
    try:
        summary = json.loads(path.read_text())
        _ = summary["env_id"], summary["algo"], summary["timesteps"], summary["n_envs"], summary["trials"]
    except FileNotFoundError:
        raise ValueError(f"{path}: no study here (trajopt rl tune ID --out {out})") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not a study's summary ({type(exc).__name__}: {exc})") from None
    if not summary.get("best") or not summary.get("defaults"):
        raise ValueError(f"{path}: the study has no scored {'defaults' if summary.get('best') else 'trial'} "
                         "to check (run the study on)")
    return summary


def _same_run(run_dir: Path, hp: dict[str, Any]) -> bool:
    """A finished run in ``run_dir`` trained with ``hp`` (as its rl_config.json records them)."""
    from ..hyperparams import jsonable
    from ..training import CONFIG_NAME, MODEL_NAME
    try:
        cfg = json.loads((run_dir / CONFIG_NAME).read_text())
    except (OSError, ValueError):
        return False
    return cfg.get("status") == "done" and (run_dir / MODEL_NAME).exists() and \
        jsonable(cfg.get("hyperparams")) == jsonable(hp)


def _check_run(env: str, algo: str, timesteps: int, n_envs: int, hp: dict[str, Any], seed: int,
               run_dir: str) -> dict[str, Any]:
    """One run of the check: trained (unless made already) and scored as the suite scores."""
    from ...tasks.play import policy_on_task
    from ..training import train
    run_dir = Path(run_dir)
    if not _same_run(run_dir, hp):
        run = train(env, algo, timesteps=timesteps, seed=seed, out=run_dir.parent, name=run_dir.name, n_envs=n_envs,
                    vec_env="dummy", max_episode_steps=None, hyperparams=hp, checkpoint_every=timesteps,
                    progress_bar=False, overwrite=True)
        if run.status != "done":
            raise KeyboardInterrupt
    ev = policy_on_task(run_dir)
    hold = _hold(run_dir, ev)
    return {"seed": seed, "score": float(ev["score"]), "episode_scores": [float(e["score"]) for e in ev["episodes"]],
            "run": str(run_dir), "credible": float(hold["slowest"]), "holds": bool(hold["holds"]),
            "spread": float(hold["spread"]), "hold_scores": [float(v) for v in hold["scores"]],
            "physics_dt_ms": [float(v) for v in hold["physics_dt_ms"]]}


def _hold(run_dir: Path, ev: dict[str, Any]) -> dict[str, Any]:
    """The run's replays at other physics steps (:func:`~trajopt.tasks.play.policy_task_hold`,
    with ``ev`` its score at its own): those in its :data:`HOLD` file when they were made from
    the same score (the same trained policy), else made and written there."""
    from ...results.files import atomic_write_bytes
    from ...tasks.play import policy_task_hold
    try:
        kept = json.loads((run_dir / HOLD).read_text())
        if kept["own_score"] == float(ev["score"]) and kept["episodes"] == len(ev["episodes"]):
            return kept
    except (OSError, ValueError, KeyError, TypeError):
        pass
    hold = policy_task_hold(run_dir, reference=ev)
    atomic_write_bytes(run_dir / HOLD, json.dumps(hold, indent=1, allow_nan=True).encode())
    return hold


def check_best(out: str | os.PathLike, *, seeds: int = 3, workers: int = 1) -> dict[str, Any]:
    """Train the study's best and the defaults in ``out`` with training seeds ``0 .. seeds-1`` and
    score them as the suite does (the module docstring), ``workers`` runs at a time. Returns (and
    writes to ``out/check.json``): per side (``best``, ``defaults``) the trial's number, each
    seed's score, their mean and standard deviation (the sample's, as the suite's ±);
    ``difference`` (best's mean minus the defaults'), ``wins`` (seeds where the best scored
    higher) and ``score_unit``; the same of the credible scores (each run's lowest over its replays
    at other physics steps: ``credible`` per seed, ``credible_mean``, ``credible_std``, ``holds``
    the runs whose score holds) and ``credible_difference``. When the defaults are the best trial
    there is nothing to check: ``difference`` 0 and no runs."""
    from ...results.files import atomic_write_bytes
    out = Path(out)
    for name, value in (("seeds", seeds), ("workers", workers)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    summary = _read_summary(out)
    env, algo, T, n = summary["env_id"], summary["algo"], int(summary["timesteps"]), int(summary["n_envs"])
    sides = {"best": summary["best"], "defaults": summary["defaults"]}
    result: dict[str, Any] = {"env_id": env, "algo": algo, "timesteps": T, "seeds": list(range(seeds)),
                              "score_unit": summary.get("score_unit")}
    if sides["best"]["number"] == sides["defaults"]["number"]:
        result.update(best=None, defaults=None, difference=0.0, wins=0, note="the defaults are the study's best")
    else:
        jobs = [(label, (env, algo, T, n, hyperparams_of(trial["params"], algo, n_envs=n, timesteps=T), s,
                         str(out / "check" / f"{label}_seed{s}")))
                for label, trial in sides.items() for s in range(seeds)]
        rows = _run(jobs, workers)
        for label, trial in sides.items():
            runs = [r for lab, r in rows if lab == label]
            scores, credible = [r["score"] for r in runs], [r["credible"] for r in runs]
            result[label] = {"trial": trial["number"], "runs": runs,
                             "scores": scores, "mean": float(np.mean(scores)), "std": _std(scores),
                             "credible": credible, "credible_mean": float(np.mean(credible)),
                             "credible_std": _std(credible), "holds": int(sum(r["holds"] for r in runs))}
        result["difference"] = result["best"]["mean"] - result["defaults"]["mean"]
        result["credible_difference"] = result["best"]["credible_mean"] - result["defaults"]["credible_mean"]
        result["wins"] = int(sum(b > d for b, d in zip(result["best"]["scores"], result["defaults"]["scores"])))
    atomic_write_bytes(out / CHECK, json.dumps(result, indent=1, allow_nan=True).encode())
    return result


def _std(values: list[float]) -> float:
    """The sample's standard deviation (the suite's ±), 0 for one value."""
    return float(np.std(values, ddof=1)) if len(values) > 1 else 0.0


def _run(jobs: list[tuple[str, tuple]], workers: int) -> list[tuple[str, dict[str, Any]]]:
    """:func:`_check_run` of each job, ``workers`` processes at a time (in order of the jobs)."""
    if workers == 1 or len(jobs) == 1:
        return [(label, _check_run(*args)) for label, args in jobs]
    from ...workers import worker_pool
    with worker_pool(min(workers, len(jobs)), "soft_envs.envs.threads:limit_threads") as pool:
        futures = [(label, pool.submit(_check_run, *args)) for label, args in jobs]
        return [(label, fut.result()) for label, fut in futures]
