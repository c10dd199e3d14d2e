"""The kinds of sweep runs as library calls: what options each takes and what it does.

:data:`KINDS` maps a kind (``optimize``, ``rl-train``, ``rl-evaluate``, ``evaluate``) to a
:class:`RunKind`: its positional argument, its options with their checks (the same
:mod:`trajopt.argtypes` checks as the ``trajopt`` command's, so a sweep file's ``speed =
"fast"`` is refused as ``trajopt optimize --speed fast`` is), the options the sweep sets
itself, and the trajopt command that does the same (for the log and ``--dry-run``). What a kind
does is a library function (:func:`trajopt.optimize_run.run_optimization`,
:func:`trajopt.rl.options.train_with_options`, :func:`trajopt.evaluation.evaluate_result`,
:func:`trajopt.rl.evaluate.evaluate_policy_metric`), called by :mod:`trajopt.sweep.task`.
The command line is not the sweep's API: a test keeps the option names here and the
command's in step.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Callable, Mapping

from ..argtypes import contact_law, cycles, difficulty_level, integer, nonnegative_float, number, positive_int, slope_deg, speed, steps
from ..optim.gait import INTERPOLATIONS
from ..optim.motor_limit import MOTOR_MODELS
from ..rl.envs import rl_target
from ..rl.hyperparams import ALGOS
from ..tasks.registry import command_line_tasks

__all__ = ["Option", "RunKind", "KINDS", "CONTACT_LAWS"]

#: the built-in contact laws (a run may choose any law of soft_envs.sim.contact.CONTACT_LAWS,
#: checked when the value is: :func:`trajopt.argtypes.contact_law`)
CONTACT_LAWS = ("paper", "coulomb")


def _choice(*allowed: str) -> Callable[[str], str]:
    def parse(text: str) -> str:
        if text not in allowed:
            raise ValueError(f"invalid choice: {text!r} (choose from {', '.join(map(repr, allowed))})")
        return text
    return parse


def _task(text: str) -> str:
    """A task of :data:`trajopt.tasks.TASKS` that makes its own target (read when checked, so a
    task registered later is known)."""
    return _choice(*command_line_tasks())(text)


def _text(text: str) -> str:
    return text


@dataclass(frozen=True)
class Option:
    """One option of a run kind: ``parse`` turns its text into the value (raising ValueError or
    argparse.ArgumentTypeError, whose message says what is wanted); ``flag``: true/false;
    ``repeatable``: a list of values."""

    parse: Callable[[str], Any] = _text
    flag: bool = False
    repeatable: bool = False

    def value(self, raw: Any) -> Any:
        """The option's value from a sweep file's ``raw`` value (checked as the command line
        checks its text)."""
        if self.flag:
            if not isinstance(raw, bool):
                raise ValueError(f"must be true or false, got {raw!r}")
            return raw
        if self.repeatable:
            items = raw if isinstance(raw, list) else [raw]
            return [self.parse(str(v)) for v in items]
        if isinstance(raw, (bool, list)):
            raise ValueError(f"expected one value, got {raw!r}")
        return self.parse(str(raw))


@dataclass(frozen=True)
class RunKind:
    """A kind of run: ``command`` (the ``trajopt`` words doing the same), its ``positional``
    argument (with its check), its ``options`` and the options the sweep sets itself
    (``reserved``); ``phase`` 1 runs start after every phase-0 run has ended."""

    name: str
    command: tuple[str, ...]
    positional: str
    options: Mapping[str, Option]
    reserved: frozenset[str] = frozenset()
    phase: int = 0
    positional_option: Option = field(default_factory=Option)

    def allowed(self) -> list[str]:
        """The option names a sweep file may set (besides the positional argument)."""
        return sorted(k for k in self.options if k not in self.reserved)

    def check(self, key: str, raw: Any) -> Any:
        """The value of option ``key`` (or the positional argument) from ``raw``; ValueError
        ``argument KEY: what is wrong``."""
        option = self.positional_option if key == self.positional else self.options[key]
        try:
            return option.value(raw)
        except (ValueError, argparse.ArgumentTypeError) as exc:
            raise ValueError(f"argument {key}: {exc}") from None

    def values(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """Checked values of the options and positional argument in ``params`` (other keys,
        ``_template`` parameters and ``contact_*``, are left out)."""
        return {k: self.check(k, v) for k, v in params.items() if k == self.positional or k in self.options}


_BOOL = Option(flag=True)
_SEED = Option(integer(0, 2**32 - 1))           # what NumPy's legacy seeding accepts

#: options of ``trajopt optimize`` (:class:`trajopt.optimize_run.OptimizeRun`)
_OPTIMIZE = {
    "task": Option(_task), "speed": Option(speed), "heading": Option(number()),
    "turn": Option(_choice("right", "left")), "angle": Option(slope_deg), "difficulty": Option(difficulty_level),
    "contact": Option(contact_law),
    "substeps": Option(positive_int), "ensemble": Option(positive_int, repeatable=True), "symmetry": _BOOL, "warm_start": Option(), "no_motor_limit": _BOOL,
    "motor_model": Option(_choice(*MOTOR_MODELS)), "iterations": Option(integer(0, 100_000)),
    "keyframes": Option(steps), "interpolation": Option(_choice(*INTERPOLATIONS)), "cycle_steps": Option(steps), "prep_steps": Option(integer(0, 100_000)),
    "seeds": Option(integer(0, 10_000)), "cycles": Option(cycles), "max_sim_steps": Option(positive_int),
    "out": Option(), "name": Option(), "resume": _BOOL, "overwrite": _BOOL, "quiet": _BOOL,
}
#: options of ``trajopt rl train`` (:func:`trajopt.rl.options.train_with_options`)
_RL_TRAIN = {
    "algo": Option(_choice(*ALGOS)), "timesteps": Option(positive_int), "seed": _SEED, "out": Option(),
    "name": Option(), "n_envs": Option(positive_int), "vec_env": Option(_choice("auto", "subproc", "dummy")),
    "frame_skip": Option(positive_int), "episode_steps": Option(positive_int), "incline": Option(slope_deg),
    "contact": Option(contact_law), "heading": Option(number()), "difficulty": Option(difficulty_level),
    "checkpoint_every": Option(positive_int),
    "hp": Option(repeatable=True), "overwrite": _BOOL, "no_progress": _BOOL, "verbose": _BOOL,
}

KINDS: Mapping[str, RunKind] = MappingProxyType({
    "optimize": RunKind("optimize", ("optimize",), "robot", MappingProxyType(_OPTIMIZE),
                        frozenset({"out", "name", "quiet", "resume"})),
    "rl-train": RunKind("rl-train", ("rl", "train"), "robot", MappingProxyType(_RL_TRAIN),
                        frozenset({"out", "name", "no_progress", "overwrite", "verbose"}),
                        positional_option=Option(rl_target)),
    "rl-evaluate": RunKind("rl-evaluate", ("rl", "evaluate"), "model", MappingProxyType({
        "cycles": Option(cycles), "seed": _SEED, "reset_noise": Option(nonnegative_float), "json": _BOOL,
        "fidelity": _BOOL, "task": _BOOL}),
        frozenset({"json"}), phase=1),
    "evaluate": RunKind("evaluate", ("evaluate",), "result", MappingProxyType({
        "cycles": Option(cycles), "ignore_robot_mismatch": _BOOL, "json": _BOOL, "fidelity": _BOOL}),
        frozenset({"json"}), phase=1),
})
