"""What a ``--speed max`` search (:func:`trajopt.fastest.fastest_gait`) tries: its candidates
``(n_cycle, n_keyframes)``, each candidate's gait, the iterations of each stage, the target speed
rule and the budget (:class:`SearchSettings`; the stages are described in :mod:`trajopt.fastest`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..optim.gait import GaitSpec
from .hold import HOLD_FACTORS, MAX_SPREAD

__all__ = ["SEARCH_EVAL_CYCLES", "SearchSettings"]

#: cycles played after the prep phase when a candidate is evaluated (the issue's "10 cycles")
SEARCH_EVAL_CYCLES = 10


@dataclass(frozen=True)
class SearchSettings:
    """What :func:`~trajopt.fastest.fastest_gait` searches (:mod:`trajopt.fastest`'s docstring).
    ``cycle_steps``: the cycle lengths [simulation steps]; ``keyframes``: keyframe counts per
    cycle (a count is tried on a cycle of at least ``min_steps_per_keyframe`` steps per
    keyframe); ``seeds``: random starts screened besides the mid-range and square-wave starts;
    Gauss-Newton iterations per stage; ``n_fine``: candidates refined (three: :mod:`trajopt.fastest`); the target speed rule;
    the interpolation of the keyframes; bilateral symmetry;
    ``revisit``: the shorter cycles again from the fastest coarse gait (:mod:`trajopt.fastest`).
    ``explore_under_speed``: under the torque-speed model, the coarse and revisit stages run
    under the speed limit alone and the fine stage tightens them to the line (:mod:`trajopt.fastest`).
    ``ensemble``: physics steps per control step of other physics every candidate is optimised
    on as well (:mod:`trajopt.optim.ensemble`; empty: the default physics alone); the search then
    ranks the candidates by their credible speed, the slowest member's.
    ``hold_factors``: the refined gaits are replayed with their physics steps per control step
    times each of these (:mod:`trajopt.search.hold`), and the search returns the fastest of those
    whose speed holds within ``max_spread`` at every one, by their slowest speed (the fastest
    upright gait when none holds; empty: no check, the fastest upright gait).
    ``max_sim_steps``: a budget of simulation steps (None: none) the search never exceeds: the
    coarse stage keeps within ``coarse_share`` of it, the fine stage within all of it; a run
    that would not fit is skipped (listed in the table), and one that runs stops early rather
    than risk its next iteration and evaluation passing the budget."""

    cycle_steps: tuple[int, ...] = (8, 12, 16, 24, 36, 72)
    keyframes: tuple[int, ...] = (4, 8)
    min_steps_per_keyframe: int = 2
    seeds: int = 1
    coarse_iterations: int = 3
    fine_iterations: int = 6
    n_fine: int = 3
    min_target: float = 20.0
    target_margin: float = 1.25
    min_horizon_steps: int = 48
    n_prep: int = 24
    interpolation: str = "linear"
    symmetry: bool = True
    eval_cycles: int = SEARCH_EVAL_CYCLES
    max_sim_steps: int | None = None
    coarse_share: float = 0.75
    revisit: bool = True
    explore_under_speed: bool = True
    ensemble: tuple[int, ...] = ()
    hold_factors: tuple[float, ...] = HOLD_FACTORS
    max_spread: float = MAX_SPREAD

    @classmethod
    def quick(cls) -> SearchSettings:
        """A search small enough for tests and CI (a few seconds)."""
        return cls(cycle_steps=(8, 12), keyframes=(4,), seeds=0, coarse_iterations=1, fine_iterations=1,
                   n_fine=1, min_horizon_steps=16, n_prep=4, eval_cycles=2)

    def candidates(self, cycle_steps: int | None = None) -> list[tuple[int, int]]:
        """``(n_cycle, n_keyframes)`` in search order: shortest cycle first, fewer keyframes first
        (``cycle_steps``: that cycle only)."""
        cycles = (int(cycle_steps),) if cycle_steps is not None else self.cycle_steps
        out = [(c, k) for c in sorted(cycles) for k in sorted(self.keyframes) if c >= self.min_steps_per_keyframe * k]
        if not out:
            raise ValueError(f"no (cycle, keyframes) candidate: cycles {cycles} are shorter than "
                             f"{self.min_steps_per_keyframe} steps per keyframe for keyframes {self.keyframes}")
        return out

    def gait(self, n_cycle: int, n_keyframes: int) -> GaitSpec:
        """The gait of a candidate: horizon of at least ``min_horizon_steps`` cycle steps."""
        n_cycles = max(2, math.ceil(self.min_horizon_steps / n_cycle))
        return GaitSpec(n_prep=self.n_prep, n_cycle=n_cycle, n_cycles=n_cycles, n_keyframes=n_keyframes,
                        symmetry=self.symmetry, interpolation=self.interpolation)

    def target(self, best: float) -> float:
        """The tracking target [BL/min] when the fastest upright gait so far makes ``best``."""
        return max(self.min_target, self.target_margin * best)

