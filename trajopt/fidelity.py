"""How credible a gait's speed is: the same controls replayed with finer physics steps.

A speed is a property of the robot only if it holds when the physics is resolved more finely.
:func:`fidelity` replays a result's evaluation (prep + its cycles, the controls joined by
straight lines in time inside each 0.033 s control step) with ``f`` times the physics steps it
was made with (:attr:`~soft_envs.envs.GradientEnv.substeps`), for every factor ``f`` of
``factors`` (default 2, 4 and 8; a factor below 1, such as 0.5, replays with coarser steps), and reports each speed, the deviation of each from the speed
at the result's own physics and the spread of all of them, ``(max - min) / |speed at the
result's physics|``. ``trajopt evaluate --fidelity`` prints it; every result ``trajopt
optimize`` writes records the 4x-finer figure (:func:`fidelity_record`,
``evaluation["fidelity"]``). Why the default physics has sub-steps: docs/fidelity.md.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .evaluation import evaluate_controls
from .optim.gait import DEFAULT_EVAL_CYCLES

__all__ = ["FIDELITY_FACTORS", "RECORDED_FACTOR", "fidelity", "fidelity_record", "fidelity_rows", "speed_at",
           "substeps_at"]

#: the finer physics ``trajopt evaluate --fidelity`` replays at: 2x, 4x and 8x the physics steps
FIDELITY_FACTORS = (2, 4, 8)
#: the factor every result records (the converged-physics bar: within 3 % at 4x finer steps)
RECORDED_FACTOR = 4


def substeps_at(substeps: int, factor: float) -> int:
    """``factor`` times ``substeps`` physics steps per control step, a whole number (a factor
    below 1 replays with coarser steps: 0.5 of 4 is 2, 16.5 ms); anything else is refused."""
    n = substeps * factor
    if n < 1 or abs(n - round(n)) > 1e-9:
        raise ValueError(f"a factor of {factor:g} on {substeps} physics step(s) per control step is no whole "
                         "number of steps")
    return int(round(n))


def speed_at(res, substeps: int, n_cycles: int | None = None, *, ignore_robot_mismatch: bool = False
             ) -> dict[str, Any]:
    """The evaluation (:func:`~trajopt.evaluation.evaluate_controls`) of ``res`` replayed with
    ``substeps`` physics steps per control step, over ``n_cycles`` cycles (default: as it was
    evaluated)."""
    from .replay import env_for_result, result_controls
    cycles = int(res.settings.get("eval_cycles", DEFAULT_EVAL_CYCLES)) if n_cycles is None else int(n_cycles)
    env = env_for_result(res, ignore_robot_mismatch=ignore_robot_mismatch, substeps=substeps)
    u, n_prep, n_cycle = result_controls(res, env.robot, cycles)
    return evaluate_controls(env, u, n_prep=n_prep, n_cycle=n_cycle,
                             heading_deg=float(res.settings.get("heading_deg", 0.0)))


def _deviation(speed: float, reference: float) -> float:
    return float((speed - reference) / abs(reference)) if reference else float("nan")


def fidelity(res, factors=FIDELITY_FACTORS, n_cycles: int | None = None, *, reference: dict | None = None,
             ignore_robot_mismatch: bool = False) -> dict[str, Any]:
    """The speed of ``res`` at its own physics and at ``factors`` times finer physics steps
    (module docstring): ``{"substeps": n, "rows": [{"factor", "substeps", "physics_dt_ms",
    "speed_bl_per_min", "upright", "deviation"}, ...], "spread": ...}``. ``reference``: the
    evaluation at the result's own physics when already made (not replayed again)."""
    from .replay import result_substeps
    n = result_substeps(res)
    steps = {f: substeps_at(n, f) for f in (1, *factors)}            # a factor that is no whole step fails first
    evs = {f: reference if (f == 1 and reference is not None) else speed_at(
        res, steps[f], n_cycles, ignore_robot_mismatch=ignore_robot_mismatch) for f in (1, *factors)}
    return fidelity_rows(n, 1e3 * res.dt, evs)


def fidelity_rows(substeps: int, control_dt_ms: float, evaluations: dict[int, dict]) -> dict[str, Any]:
    """:func:`fidelity`'s dict from the evaluations at ``factor -> evaluation`` (factor 1: the
    own physics of ``substeps`` steps per control step of ``control_dt_ms``)."""
    rows = []
    for f, ev in evaluations.items():
        n = substeps_at(substeps, f)
        rows.append({"factor": f, "substeps": n, "physics_dt_ms": control_dt_ms / n,
                     "speed_bl_per_min": float(ev["speed_bl_per_min"]), "upright": bool(ev.get("upright", False)),
                     "sim_failure": ev.get("sim_failure")})
    base = rows[0]["speed_bl_per_min"]
    for r in rows:
        r["deviation"] = _deviation(r["speed_bl_per_min"], base)
    speeds = np.array([r["speed_bl_per_min"] for r in rows])
    spread = float((speeds.max() - speeds.min()) / abs(base)) if base and np.isfinite(speeds).all() else float("nan")
    return {"substeps": substeps, "control_dt_ms": control_dt_ms, "rows": rows, "spread": spread}


def fidelity_record(res, reference: dict | None = None) -> dict[str, Any]:
    """What a result's ``evaluation["fidelity"]`` records: its speed with :data:`RECORDED_FACTOR`
    times finer physics steps, the deviation from its own speed and the spread of the two."""
    out = fidelity(res, (RECORDED_FACTOR,), reference=reference or res.evaluation)
    finer = out["rows"][1]
    return {"factor": RECORDED_FACTOR, "substeps": finer["substeps"], "speed_bl_per_min": finer["speed_bl_per_min"],
            "upright": finer["upright"], "deviation": finer["deviation"], "spread": out["spread"]}
