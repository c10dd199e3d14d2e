"""What a gait's control trajectory looks like: :class:`GaitSpec`, with the paper's defaults.

``u = (u_prep, u_cycle, ..., u_cycle)`` (paper III-B, eq. 12): ``n_prep`` steps that ease from
rest into the cycle, then ``n_cycles`` repetitions of a cycle of ``n_cycle`` simulation steps;
each motor's cycle is a periodic spline through ``n_keyframes`` keyframes (``interpolation``:
the paper's zero-tangent Hermite spline, or straight lines, :data:`INTERPOLATIONS`); with ``symmetry``,
a motor's mirror motor plays the same signal half a period later. The paper: 24 + 2 x 72 steps
(168 steps, 5.5 s at h = 0.033 s), 4 keyframes, symmetric walks and an asymmetric turn. A gait is
evaluated over :data:`DEFAULT_EVAL_CYCLES` cycles after the prep phase.

A task changes these defaults (``gait_defaults`` of :class:`trajopt.tasks.Task`): the turn has
:data:`~trajopt.tasks.TURN_KEYFRAMES` keyframes per cycle instead of 4: with 4, a leg
makes one stride per 72-step cycle, and the Puppy cannot both walk and turn a quarter circle in
two such strides (the optimised turn reached 43-56 degrees in 10 cycles); 12 keyframes let
each leg make up to three strides per cycle, and the walk's 4 keyframes warm-start it as three strides
(:meth:`~trajopt.optim.parameterization.GaitParameterization.keyframes_from`); and its keyframes are
joined by straight lines (:data:`~trajopt.tasks.TURN_INTERPOLATION`), which under the motors'
speed limit turn further than the spline.

This module imports nothing heavy: the command line reads its defaults from here.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..tasks.registry import TASKS, TURN_KEYFRAMES

__all__ = ["GaitSpec", "DEFAULT_EVAL_CYCLES", "TURN_KEYFRAMES", "INTERPOLATIONS"]

#: how a cycle passes through its keyframes (:func:`trajopt.optim.parameterization.cycle_basis`):
#: ``"hermite"``, the paper's zero-tangent cubic Hermite spline (eq. 12; the default); its
#: slope peaks at 1.5 times its mean between keyframes, so under the motors' speed limit a
#: cable averages at most 2/3 of the motor's speed; ``"linear"``, straight lines between
#: keyframes: constant slope, so a cable can move at the motor's full speed (``trajopt optimize
#: --speed max``, :mod:`trajopt.fastest`). Both stay within the range of their keyframes.
INTERPOLATIONS = ("hermite", "linear")

#: cycles played after the prep phase when a gait is evaluated (speed in BL/min, upright)
DEFAULT_EVAL_CYCLES = 6


@dataclass(frozen=True)
class GaitSpec:
    """Phase lengths [simulation steps], cycles, keyframes per cycle and bilateral symmetry of a
    gait (see the module docstring). ``GaitSpec()`` is the paper's walking gait."""

    n_prep: int = 24
    n_cycle: int = 72
    n_cycles: int = 2
    n_keyframes: int = 4
    symmetry: bool = True
    interpolation: str = "hermite"

    def __post_init__(self):
        for name in ("n_prep", "n_cycle", "n_cycles", "n_keyframes"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int):
                raise ValueError(f"GaitSpec.{name} must be an integer, got {v!r}")
        if self.n_prep < 0:
            raise ValueError(f"GaitSpec.n_prep must be >= 0, got {self.n_prep}")
        if self.n_cycles < 1:
            raise ValueError(f"GaitSpec.n_cycles must be >= 1, got {self.n_cycles}")
        if not 1 <= self.n_keyframes <= self.n_cycle:
            raise ValueError(f"GaitSpec needs 1 <= n_keyframes <= n_cycle, got {self.n_keyframes} keyframes "
                             f"and {self.n_cycle} cycle steps")
        if not isinstance(self.symmetry, bool):
            raise ValueError(f"GaitSpec.symmetry must be True or False, got {self.symmetry!r}")
        if self.interpolation not in INTERPOLATIONS:
            raise ValueError(f"GaitSpec.interpolation must be one of {INTERPOLATIONS}, got {self.interpolation!r}")

    @classmethod
    def for_task(cls, task: str, *, symmetry: bool | None = None, **fields: Any) -> "GaitSpec":
        """The gait of a task: the ``gait_defaults`` of its :class:`~trajopt.tasks.Task` over the
        paper's (the turn: asymmetric, paper IV-B, with :data:`~trajopt.tasks.TURN_KEYFRAMES`
        keyframes). ``symmetry`` and the ``fields`` that are not None override them."""
        task_defaults = TASKS[task].gait_defaults if task in TASKS else {}
        fields = dict(task_defaults) | {k: v for k, v in fields.items() if v is not None}
        if symmetry is not None:
            fields["symmetry"] = bool(symmetry)
        return cls(**fields)

    def n_steps(self, n_cycles: int | None = None) -> int:
        """Simulation steps of the prep phase and ``n_cycles`` cycles (default ``self.n_cycles``)."""
        return self.n_prep + (self.n_cycles if n_cycles is None else int(n_cycles)) * self.n_cycle

    def replace(self, **changes: Any) -> "GaitSpec":
        return dataclasses.replace(self, **changes)

    def to_settings(self) -> dict[str, Any]:
        """The fields as a result's ``settings`` entries."""
        return dataclasses.asdict(self)

    @classmethod
    def from_settings(cls, settings: Mapping[str, Any]) -> "GaitSpec":
        """The gait recorded in a result's ``settings`` (results written before ``n_cycles`` was
        recorded optimised two cycles)."""
        default = cls()
        return cls(n_prep=int(settings.get("n_prep", default.n_prep)),
                   n_cycle=int(settings.get("n_cycle", default.n_cycle)),
                   n_cycles=int(settings.get("n_cycles", default.n_cycles)),
                   n_keyframes=int(settings.get("n_keyframes", default.n_keyframes)),
                   symmetry=bool(settings.get("symmetry", default.symmetry)),
                   interpolation=str(settings.get("interpolation", default.interpolation)))
