"""The figures of a finished co-design (:mod:`trajopt.codesign.run`): every gait's credible speed,
the summary ``DIR/codesign.json``, its line, and the report ``DIR/codesign.md`` / ``.png``.

A gait's credible figures are the hold stage's replays (:func:`trajopt.search.hold.hold_check`:
its speed at 16.5, 8.25, 4.125 and 2.06 ms physics steps, by default), the *slowest* of them, the
*spread* ``(max - min) / slowest`` and whether it *holds* (spread <= 5 %, upright, forwards). The
primary figures of a co-design are the ratios of the slowest speeds,

    credible_ratio = slowest(co-designed gait) / slowest(shipped design's --speed max gait),
    reoptimised_credible_ratio = slowest(the written robot's --speed max gait) / the same,

the shipped design's and the re-optimised gait's slowest speeds those of their searches' hold
stages; the ratios of the speeds at the own physics (``ratio``, ``reoptimised_ratio``) follow.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..results.result import Result
from ..search.hold import hold_check
from .screen import ScreenSettings

__all__ = ["credible_check", "summarise", "describe_credible", "write_report"]


def credible_check(env, res: Result, screen: ScreenSettings) -> dict:
    """The replays of ``res`` (a gait on ``env``'s physics) at the screening's other physics steps
    (:func:`~trajopt.search.hold.hold_check` over ``screen.eval_cycles`` cycles at
    ``screen.hold_factors``): its ``evaluation["hold"]`` when its search's hold stage made them so,
    else replayed here."""
    made = res.evaluation.get("hold")
    search = (res.settings.get("search") or {}).get("settings") or {}
    if (made and int(res.settings.get("eval_cycles", -1)) == screen.eval_cycles
            and tuple(search.get("hold_factors", ())) == tuple(screen.hold_factors)
            and float(made.get("max_spread", -1)) == float(screen.max_spread)):
        return made
    return hold_check(env, res, factors=screen.hold_factors, max_spread=screen.max_spread,
                      n_cycles=screen.eval_cycles)


def summarise(run, env, baseline, result, reopt, state, changes, checks, wall, holds) -> dict:
    """The figures of a co-design (``codesign.json``): per gait (``before``: the shipped design's
    fastest, ``after``: the co-designed, ``reoptimised``: the written robot's from scratch) its
    speed at the own physics and its credible figures (``holds[gait]``, the replays); the ratios
    of the own speeds (``ratio``, ``reoptimised_ratio``) and, the primary figures, of the slowest
    speeds (``credible_ratio``, ``reoptimised_credible_ratio``)."""
    before = float(baseline.evaluation["speed_bl_per_min"])
    after = float(result.evaluation["speed_bl_per_min"])
    out = {"robot": env.robot.name, "contact": env.contact_model, "vary": list(run.vary),
           "n_cycle": baseline.settings["n_cycle"], "n_keyframes": baseline.settings["n_keyframes"],
           "before_bl_per_min": before, "after_bl_per_min": after, "ratio": after / before,
           "after_upright": bool(result.evaluation.get("upright")),
           "iterations": len(state.history), "stages": state.stage_rows,
           "joint_ensemble": list(run.joint.ensemble),
           "codesign_sim_steps": state.sim_steps, "codesign_wall_time_s": state.wall_time_s,
           "wall_time_s": wall, "changes": len(changes), "checks_passed": all(c.passed for c in checks)}
    if reopt is not None:
        v = float(reopt.evaluation["speed_bl_per_min"])
        out.update(reoptimised_bl_per_min=v, reoptimised_ratio=v / before,
                   reoptimised_cycle=[reopt.settings["n_cycle"], reopt.settings["n_keyframes"]],
                   reoptimised_chosen_by=(reopt.settings.get("search") or {}).get("chosen_by"))
    for gait, check in holds.items():
        if gait == "reoptimised" and reopt is None:
            continue
        out.update({f"{gait}_slowest_bl_per_min": float("nan") if check is None else float(check["slowest"]),
                    f"{gait}_spread": float("nan") if check is None else float(check["spread"]),
                    f"{gait}_holds": bool(check and check["holds"]),
                    f"{gait}_speeds": None if check is None else [float(v) for v in check["speeds"]],
                    f"{gait}_substeps": None if check is None else list(check["substeps"])})
    base = out["before_slowest_bl_per_min"]
    out["credible_ratio"] = out["after_slowest_bl_per_min"] / base
    if reopt is not None:
        out["reoptimised_credible_ratio"] = out["reoptimised_slowest_bl_per_min"] / base
    return out


def describe_credible(summary: dict) -> str:
    """The co-design's primary figures in a line: the slowest speeds over the physics steps, their
    ratios to the shipped design's, and whether each gait holds; then the own-physics speeds."""
    def gait(key: str) -> str:
        if not np.isfinite(summary[f"{key}_slowest_bl_per_min"]):
            return "falls at a physics step (or walks backwards)"
        return (f"{summary[f'{key}_slowest_bl_per_min']:.2f} at the slowest step, spread "
                f"{100 * summary[f'{key}_spread']:.1f} % ({'holds' if summary[f'{key}_holds'] else 'does not hold'})")
    text = (f"credible speeds: shipped {gait('before')}; co-designed {gait('after')}, "
            f"{summary['credible_ratio']:.2f}x")
    if "reoptimised_credible_ratio" in summary:
        text += f"; re-optimised from the files {gait('reoptimised')}, {summary['reoptimised_credible_ratio']:.2f}x"
    text += (f" (own physics: {summary['before_bl_per_min']:.2f} -> {summary['after_bl_per_min']:.2f}, "
             f"{summary['ratio']:.2f}x")
    if "reoptimised_ratio" in summary:
        text += f"; re-optimised {summary['reoptimised_bl_per_min']:.2f}, {summary['reoptimised_ratio']:.2f}x"
    return text + ")"


def write_report(run, shipped, designed, summary, changes, checks, settings) -> Path:
    """``DIR/codesign.md`` and ``DIR/codesign.png`` of a :func:`summarise` (the credible figures
    first: :func:`~trajopt.codesign.report.write_codesign_report`); returns the report's path."""
    from .report import plot_robots_side_by_side, write_codesign_report
    picture = run.out / "codesign.png"
    plot_robots_side_by_side(shipped, designed, picture,
                             speeds=(summary["before_bl_per_min"], summary["after_bl_per_min"]))
    def credible(gait: str) -> dict:
        return {key: summary[f"{gait}_{key}"] for key in ("slowest_bl_per_min", "spread", "holds")}

    before = {"speed_bl_per_min": summary["before_bl_per_min"], **credible("before"), "n_cycle": summary["n_cycle"],
              "n_keyframes": summary["n_keyframes"]}
    after = {"speed_bl_per_min": summary["after_bl_per_min"], **credible("after"), "n_cycle": summary["n_cycle"],
             "n_keyframes": summary["n_keyframes"], "upright": summary["after_upright"],
             "simulation_steps": summary["codesign_sim_steps"], "wall_time_s": summary["codesign_wall_time_s"],
             "iterations": summary["iterations"]}
    reopt = None if "reoptimised_bl_per_min" not in summary else {
        "speed_bl_per_min": summary["reoptimised_bl_per_min"], **credible("reoptimised"),
        "n_cycle": summary["reoptimised_cycle"][0], "n_keyframes": summary["reoptimised_cycle"][1]}
    path = run.out / "codesign.md"
    write_codesign_report(path, robot_name=shipped.name, before=before, after=after, reoptimised=reopt,
                          changes=changes, checks=checks, picture=str(picture), settings=settings)
    return path
