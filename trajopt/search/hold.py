"""Whether a gait's speed holds at other physics steps: the check ``--speed max`` chooses by.

An optimiser exploits whatever its model allows, and the fastest gait of a search is the one
most likely to exploit the physics step: the shipped Tripod's fastest (an 8-step cycle, 20.5
BL/min) walks 18.1 at 16.5 ms and 21.6 at 2.06 ms, a spread of 19 %, while the 12-step gait the
same search refines walks 16.2-16.7 at every step (3.0 %). :func:`hold_check` replays a
candidate's controls (prep and its evaluation cycles, from rest, the controls joined by straight
lines inside each control step) with its own physics steps per control step times each of
``factors`` (default: half, twice and four times, i.e. 16.5, 4.125 and 2.06 ms around the
default 8.25 ms: the headline's bar, ``benchmarks/bench_headline.py``) and reports

* ``substeps`` and ``speeds``: the physics steps per control step of each replay, its own
  included, in increasing order, and the speed [BL/min] at each (NaN where it fell);
* ``slowest``: the slowest of them (the gait's credible speed);
* ``spread``: ``(max - min) / slowest`` (inf when one fell);
* ``holds``: every replay upright, walking forwards (``slowest > 0``) and ``spread <= max_spread``
  (default 5 %);
* ``steps``: the simulation steps the replays took, counted in steps of the gait's own physics
  (a replay with twice the physics steps per control step counts twice its control steps).

A factor whose step count is not a whole number (half of one physics step) is left out.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..evaluation import evaluate_controls
from ..optim.ensemble import member_env
from ..replay import result_controls

__all__ = ["HOLD_FACTORS", "MAX_SPREAD", "FASTEST_HELD", "SLOWEST_BEST", "FASTEST_UPRIGHT", "hold_steps", "hold_check", "hold_replays", "credible_rank", "slowest_rank", "hold_cost", "hold_stage", "choose_gait", "describe_hold", "hold_verdict"]

#: the physics steps per control step a candidate is replayed with, as factors of its own
HOLD_FACTORS = (0.5, 2.0, 4.0)
#: the largest spread of a gait that holds (the headline's bar)
MAX_SPREAD = 0.05


def hold_steps(substeps: int, factors=HOLD_FACTORS) -> list[int]:
    """The physics steps per control step of the replays: ``substeps`` times each factor, where
    that is a whole number >= 1, without ``substeps`` itself, in increasing order."""
    out = set()
    for f in factors:
        n = substeps * float(f)
        if n >= 1 and float(n).is_integer() and int(n) != substeps:
            out.add(int(n))
    return sorted(out)


def hold_check(env: Any, res: Any, *, factors=HOLD_FACTORS, max_spread: float = MAX_SPREAD,
               n_cycles: int | None = None) -> dict[str, Any]:
    """Replay ``res`` (made on ``env``'s physics, its evaluation ``res.evaluation`` at that
    physics) at the other physics steps of ``factors`` over ``n_cycles`` cycles (default: its
    evaluation's) and say whether its speed holds (module docstring)."""
    cycles = int(res.settings["eval_cycles"]) if n_cycles is None else int(n_cycles)
    u, n_prep, n_cycle = result_controls(res, env.robot, cycles)
    return hold_replays(env, u, n_prep, n_cycle, res.evaluation, factors=factors, max_spread=max_spread,
                        heading_deg=float(res.settings.get("heading_deg", 0.0)))


def hold_replays(env: Any, u: np.ndarray, n_prep: int, n_cycle: int, own: dict, *, factors=HOLD_FACTORS,
                 max_spread: float = MAX_SPREAD, heading_deg: float = 0.0) -> dict[str, Any]:
    """:func:`hold_check` of the controls ``u`` (the prep phase's ``n_prep`` steps, then cycles of
    ``n_cycle``) whose evaluation at ``env``'s own physics is ``own``
    (:func:`~trajopt.evaluation.evaluate_controls`'s dict: ``speed_bl_per_min``, ``upright``)."""
    own_n = int(env.substeps)
    speeds = {own_n: float(own["speed_bl_per_min"]) if own.get("upright") and "sim_failure" not in own
              else float("nan")}
    steps = 0.0
    for n in hold_steps(own_n, factors):
        ev = evaluate_controls(member_env(env, n), u, n_prep=n_prep, n_cycle=n_cycle, heading_deg=heading_deg)
        speeds[n] = float(ev["speed_bl_per_min"]) if ev.get("upright") and "sim_failure" not in ev else float("nan")
        steps += len(u) * n / own_n
    values = [speeds[n] for n in sorted(speeds)]
    return {"substeps": [int(n) for n in sorted(speeds)], "speeds": values, **hold_verdict(values, max_spread),
            "max_spread": float(max_spread), "steps": int(math.ceil(steps))}


def credible_rank(check: dict[str, Any] | None) -> tuple[int, float]:
    """The order co-design ranks gaits by (:mod:`trajopt.codesign.screen`, :mod:`trajopt.codesign.joint`):
    ``(holds, slowest)`` of a :func:`hold_check`, compared as tuples, so that a gait whose speed holds
    beats every gait that does not, and among gaits alike in that the slowest speed decides. A gait
    that fell at any step, walks backwards (``slowest <= 0``), or was not checked (None) ranks
    ``(0, -inf)``, below every upright forward gait: it is never better."""
    if check is None:
        return 0, -math.inf
    slowest = float(check["slowest"])
    if not math.isfinite(slowest) or slowest <= 0:
        return 0, -math.inf
    return int(bool(check["holds"])), slowest


def slowest_rank(check: dict[str, Any] | None) -> tuple[int, float]:
    """The order of co-design's screening (:class:`trajopt.codesign.screen.ScreenSettings`
    ``rank="slowest"``): by the slowest speed alone, the credible speed, whether or not the gait
    holds within the spread; compared with :func:`credible_rank`'s tuples, every upright forward
    gait ranks ``(1, slowest)`` and one that fell, walks backwards or was not checked
    ``(0, -inf)``."""
    rank = credible_rank(check)
    return (1, rank[1]) if rank[1] > -math.inf else rank


def hold_verdict(speeds, max_spread: float = MAX_SPREAD) -> dict[str, Any]:
    """``{"slowest", "spread", "holds"}`` of the speeds [BL/min] of one gait at several physics
    steps (NaN: it fell there): the slowest (NaN when it fell anywhere), ``(max - min) / |slowest|``
    (inf then) and whether it holds: upright everywhere, forwards (``slowest > 0``: a gait walking
    steadily backwards does not) and ``spread <= max_spread``."""
    values = np.asarray(speeds, dtype=np.float64)
    slowest = float(values.min()) if np.isfinite(values).all() else float("nan")
    spread = float((values.max() - values.min()) / abs(slowest)) if math.isfinite(slowest) and slowest else math.inf
    return {"slowest": slowest, "spread": spread,
            "holds": bool(math.isfinite(slowest) and slowest > 0 and spread <= max_spread)}


def hold_cost(env: Any, settings: Any, gait_settings: dict) -> int:
    """The steps (in ``env``'s physics) of :func:`hold_stage`'s replays of one gait of a search with
    ``settings`` (:class:`~trajopt.search.settings.SearchSettings`)."""
    own = int(env.substeps)
    steps = int(gait_settings["n_prep"]) + settings.eval_cycles * int(gait_settings["n_cycle"])
    return int(math.ceil(steps * sum(n / own for n in hold_steps(own, settings.hold_factors))))


def hold_stage(search: Any, settings: Any, model: str) -> None:
    """The search's last stage (:mod:`trajopt.fastest`): every upright refined gait of ``search``
    (its ``env``, its ``runs`` of ``(row, result)``, its step count ``total``, ``cap(share)`` and
    ``say(line)``) made under ``model``, replayed at other physics steps (:func:`hold_check`);
    its row and ``evaluation["hold"]`` say whether its speed holds. A replay that does not fit
    the budget is skipped (``holds`` says so)."""
    if not hold_steps(int(search.env.substeps), settings.hold_factors):
        return
    for row, res in search.runs:
        if row["stage"] != "fine" or row["motor_model"] != model or not row["upright"]:
            continue
        cost = hold_cost(search.env, settings, res.settings)
        if search.total + cost > search.cap(1.0):
            row["holds"] = "skipped: budget"
            continue
        check = hold_check(search.env, res, factors=settings.hold_factors, max_spread=settings.max_spread)
        search.total += check["steps"]
        res.evaluation["hold"] = check
        row.update(slowest_bl_per_min=check["slowest"], spread=check["spread"], holds=check["holds"],
                   hold_sim_steps=check["steps"])
        search.say(f"hold cycle {row['n_cycle']} keyframes {row['n_keyframes']}: {describe_hold(check)}")


def describe_hold(check: dict[str, Any]) -> str:
    """One line of a :func:`hold_check`: the speeds, where it fell, the spread and the verdict."""
    speeds = ", ".join("fell" if not math.isfinite(v) else f"{v:.2f}" for v in check["speeds"])
    fell = [n for n, v in zip(check["substeps"], check["speeds"]) if not math.isfinite(v)]
    spread = (f"fell at {', '.join(map(str, fell))} physics steps per control step" if fell
              else f"spread {100 * check['spread']:.1f} %")
    return (f"{speeds} BL/min at {', '.join(map(str, check['substeps']))} physics steps per control step, {spread}: "
            f"{'holds' if check['holds'] else 'does not hold'}")


#: ``choose_gait``'s rule when a gait held (``settings["search"]["chosen_by"]``)
FASTEST_HELD = "the fastest gait whose speed holds at other physics steps, by its slowest speed"
#: ``choose_gait``'s rule when none held but some were replayed upright at every physics step
SLOWEST_BEST = "the gait with the highest slowest speed over the physics steps"
#: ``choose_gait``'s rule otherwise
FASTEST_UPRIGHT = "the fastest upright gait"


def choose_gait(upright: list[tuple[dict, Any]], max_spread: float = MAX_SPREAD) -> tuple[dict, Any, str]:
    """``(row, result, rule)``: of the upright runs ``(row, result)`` of a search, the one whose
    speed holds (``row["holds"] is True``, :func:`hold_check`) with the highest slowest speed
    (``row["slowest_bl_per_min"]``); when none holds, the one with the highest slowest speed among
    those replayed upright and forwards at every physics step (the credible speed, as
    :func:`credible_rank` orders co-design's gaits); when none was (a budget cut the replays, or
    every replayed gait fell or went backwards at some step), the fastest
    (``row["credible_bl_per_min"]``: its speed, or an ensemble's slowest member's). ``rule`` is :data:`FASTEST_HELD`, :data:`SLOWEST_BEST` or
    :data:`FASTEST_UPRIGHT` (the last two saying how many were checked and did not hold)."""
    if not upright:
        raise ValueError("no upright gait to choose from")
    held = [p for p in upright if p[0].get("holds") is True]
    if held:
        row, res = max(held, key=lambda p: p[0]["slowest_bl_per_min"])
        return row, res, FASTEST_HELD
    checked = sum(isinstance(p[0].get("holds"), bool) for p in upright)
    why = (f": none of the {checked} gait(s) checked holds its speed within {100 * max_spread:g} % at other "
           "physics steps" if checked else "")
    replayed = [p for p in upright if p[0].get("holds") is False
                and credible_rank({"slowest": p[0]["slowest_bl_per_min"], "holds": False})[1] > -math.inf]
    if replayed:
        row, res = max(replayed, key=lambda p: p[0]["slowest_bl_per_min"])
        return row, res, SLOWEST_BEST + why
    row, res = max(upright, key=lambda p: p[0]["credible_bl_per_min"])
    return row, res, FASTEST_UPRIGHT + why
