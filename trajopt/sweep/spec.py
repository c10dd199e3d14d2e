"""Sweep files: which runs a sweep holds (TOML, read with :mod:`tomllib`).

A sweep file lists blocks of runs; each block has a kind, fixed arguments, a parameter grid
(every combination is one run) and a name template for the run directories::

    [sweep]
    description = "target speeds, both robots"       # optional

    [[runs]]
    kind = "optimize"                  # optimize | rl-train | rl-evaluate | evaluate
    name = "{robot}_v{speed:g}"        # str.format over the run's parameters
    cpus = 1                           # CPUs a run of this block takes (Ray resources)
    [runs.args]                        # fixed arguments: the command's options
    task = "walk"
    iterations = 8
    [runs.grid]                        # one run per combination, in this order
    robot = ["tripod", "puppy"]
    speed = [4.0, 6.0, 8.0]
    [runs.quick]                       # replaces arguments with --quick or SOFT_ENVS_QUICK=1
    iterations = 1

Arguments are the options of the kind (:data:`trajopt.sweep.kinds.KINDS`: those of the command
doing the same, ``trajopt optimize``, ``trajopt rl train``, ``trajopt rl evaluate``, ``trajopt
evaluate``; a run calls the library, not the command), spelt with ``-`` or ``_``
(``cycle_steps``); ``true``/``false`` for flags (``symmetry = false`` is ``--no-symmetry``), a
list for a repeatable option (``hp = ["gamma=0.95"]``); the positional argument by its name
(``robot``, ``model``, ``result``). Optimisations also take ``contact_<field>`` (``stiffness``,
``friction``, ``blend``): the run then uses a copy of the robot's robot.toml with those
``[contact]`` values. Parameters whose name starts with ``_`` only fill templates (they are
not passed to the command). ``rl-train`` blocks may set ``export = true`` (default: score the policy
with trajopt's metric, ``trajopt rl export``) and ``evaluate_checkpoints = true`` (the
speed-vs-steps curve). ``rl-train`` and ``optimize`` blocks may set ``task_score = true``: the
run is then also scored on its benchmark task's id with the task's own score
(:mod:`trajopt.tasks.play`: an RL run trained on a task id, a gait optimised for a task of
:data:`trajopt.tasks.TASKS` with an ``env_task``), in its metrics and ``task_score.json``. String arguments may hold ``{out}`` (the sweep directory) and the
run's parameters, e.g. ``result = "{out}/opt_v{_speed}/opt_v{_speed}.npz"`` (in templates
``{robot}`` is the robot's name, also for a robot.toml path: :func:`robot_name`); evaluation runs start
after all optimisations and trainings of the sweep. Relative paths are relative to the
sweep file. Every problem is a ``ValueError`` naming the file and the field (a file that is
not UTF-8: the byte offset).
"""
from __future__ import annotations

import fnmatch
import itertools
import os
import re
import string
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..results.files import decode_utf8
from .kinds import KINDS

__all__ = ["KINDS", "Run", "SweepSpec", "load_spec", "quick_requested"]

CONTACT_PREFIX = "contact_"
_BLOCK_KEYS = {"kind", "name", "cpus", "args", "grid", "quick", "export", "evaluate_checkpoints", "task_score"}
_NAME_OK = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+=-]*$")


def quick_requested(flag: bool = False) -> bool:
    """True for ``--quick`` or the project-wide ``SOFT_ENVS_QUICK=1``."""
    return bool(flag) or os.environ.get("SOFT_ENVS_QUICK", "") not in ("", "0")


@dataclass(frozen=True)
class Run:
    """One run of a sweep: ``kind``, its directory ``name`` and its ``params`` (the
    command's arguments, keys with underscores, plus ``contact_*``)."""

    name: str
    kind: str
    params: dict[str, Any]
    cpus: int = 1
    options: dict[str, Any] = field(default_factory=dict)     # export, evaluate_checkpoints
    source: str = ""                                           # "FILE: runs[i]" for messages

    @property
    def phase(self) -> int:
        return KINDS[self.kind].phase

    def contact(self) -> dict[str, Any]:
        return {k[len(CONTACT_PREFIX):]: v for k, v in self.params.items() if k.startswith(CONTACT_PREFIX)}

    def arguments(self) -> dict[str, Any]:
        """The run's arguments, checked and converted as the command line converts its text
        (:meth:`trajopt.sweep.kinds.RunKind.values`; no ``_template`` or ``contact_*`` keys)."""
        return KINDS[self.kind].values(self.params)

    def argv(self, robot_file: Path | None = None) -> list[str]:
        """The ``trajopt`` command line doing what this run does, without the sweep's own
        options (for the run's log and ``--dry-run``; the run itself calls the library,
        :mod:`trajopt.sweep.task`). ``robot_file`` replaces the robot (a derived robot.toml
        with the contact parameters)."""
        kind = KINDS[self.kind]
        words, positional = kind.command, kind.positional
        args = list(words)
        params = dict(self.params)
        if robot_file is not None:
            params["robot"] = str(robot_file)
        args.append(str(params.pop(positional)))
        for key, value in params.items():
            if key.startswith(CONTACT_PREFIX) or key.startswith("_"):
                continue
            opt = "--" + key.replace("_", "-")
            if isinstance(value, bool):
                if key == "symmetry":
                    args.append("--symmetry" if value else "--no-symmetry")
                elif value:
                    args.append(opt)
            elif isinstance(value, list):
                for v in value:
                    args += [opt, str(v)]
            else:
                args += [opt, str(value)]
        return args


@dataclass
class SweepSpec:
    path: Path
    description: str
    runs: list[Run]
    text: str

    def names(self) -> list[str]:
        return [r.name for r in self.runs]

    def only(self, patterns: list[str] | None) -> "SweepSpec":
        """The same sweep restricted to the runs whose name matches one of the shell-style
        ``patterns`` (``tripod_*``, ``*_seed[01]``), in the file's order; ``None`` or an empty
        list keeps every run. A pattern that matches no run is refused with the runs' names."""
        if not patterns:
            return self
        for pat in patterns:
            if not any(fnmatch.fnmatchcase(r.name, pat) for r in self.runs):
                raise ValueError(f"{self.path}: --only {pat!r} matches no run; the runs are "
                                 + ", ".join(self.names()))
        runs = [r for r in self.runs if any(fnmatch.fnmatchcase(r.name, pat) for pat in patterns)]
        return replace(self, runs=runs)


def _norm(key: str) -> str:
    return key.replace("-", "_")


def _check_value(value: Any, where: str) -> Any:
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list) and all(isinstance(v, (bool, int, float, str)) for v in value):
        return list(value)
    raise ValueError(f"{where} must be a number, string, boolean or a list of them, got {value!r}")


def _table(block: dict, key: str, where: str) -> dict[str, Any]:
    t = block.get(key, {})
    if not isinstance(t, dict):
        raise ValueError(f"{where}.{key} must be a table ([runs.{key}]), got {type(t).__name__}")
    return t


def _validate(run: Run, where: str) -> None:
    """Every parameter of ``run`` is an option of its kind with a valid value (the kind's
    library-level description, :data:`trajopt.sweep.kinds.KINDS`)."""
    kind = KINDS[run.kind]
    for key in run.params:
        if key.startswith("_"):
            continue
        if key.startswith(CONTACT_PREFIX):
            if run.kind != "optimize":
                raise ValueError(f"{where}: {key} (contact parameters) applies to kind 'optimize' only")
            continue
        if key in kind.reserved:
            raise ValueError(f"{where}: argument {key!r} is set by the sweep itself; remove it")
        if key != kind.positional and key not in kind.options:
            raise ValueError(f"{where}: unknown argument {key!r} for kind {run.kind!r} "
                             f"(allowed: {kind.positional}, {', '.join(kind.allowed())}, contact_<field> for optimize)")
    if kind.positional not in run.params:
        raise ValueError(f"{where}: argument {kind.positional!r} is missing (in args or grid)")
    try:
        run.arguments()
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _default_template(kind: str, grid: dict) -> str:
    return kind + "".join(f"_{k}{{{k}}}" for k in grid)


def _format(template: str, values: dict[str, Any], where: str, what: str) -> str:
    try:
        return template.format(**values)
    except KeyError as exc:
        raise ValueError(f"{where}.{what}: {{{exc.args[0]}}} is not a parameter of this run "
                         f"(known: {', '.join(sorted(values))})") from None
    except (ValueError, IndexError, AttributeError) as exc:
        raise ValueError(f"{where}.{what}: bad template {template!r} ({exc})") from None


def _uses_fields(text: str) -> bool:
    return any(f for _, f, _, _ in string.Formatter().parse(text) if f is not None)


def robot_name(robot: Any, base: Path) -> Any:
    """What ``{robot}`` expands to: a shipped robot's name as it is, a robot.toml path by the
    ``[robot] name`` it holds (its folder's name when the file cannot be read, or its stem
    when that is not ``robot``): never a path with slashes."""
    if not isinstance(robot, str) or not robot.endswith(".toml"):
        return robot
    path = Path(robot) if os.path.isabs(robot) else base / robot
    try:
        name = tomllib.loads(path.read_text(encoding="utf-8"))["robot"]["name"]
        if isinstance(name, str) and _NAME_OK.match(name):
            return name
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return path.stem if path.stem != "robot" else path.resolve().parent.name


def _template_values(params: dict[str, Any], base: Path) -> dict[str, Any]:
    """The run's parameters as name templates see them (``{robot}``: :func:`robot_name`)."""
    return {**params, "robot": robot_name(params["robot"], base)} if "robot" in params else dict(params)


def _resolve_paths(params: dict[str, Any], base: Path) -> None:
    for key in ("robot", "warm_start", "result", "model"):
        v = params.get(key)
        if isinstance(v, str) and (key != "robot" or v.endswith(".toml")) and not os.path.isabs(v):
            params[key] = str((base / v).resolve())


def _expand_block(block: Any, index: int, src: str, base: Path, quick: bool, out_token: str) -> list[Run]:
    where = f"{src}: runs[{index}]"
    if not isinstance(block, dict):
        raise ValueError(f"{where} must be a table ([[runs]])")
    unknown = set(block) - _BLOCK_KEYS
    if unknown:
        raise ValueError(f"{where}: unknown key {sorted(unknown)[0]!r} (allowed: {', '.join(sorted(_BLOCK_KEYS))})")
    kind = block.get("kind")
    if kind not in KINDS:
        raise ValueError(f"{where}.kind must be one of {sorted(KINDS)}, got {kind!r}")
    cpus = block.get("cpus", 1)
    if isinstance(cpus, bool) or not isinstance(cpus, int) or cpus < 1:
        raise ValueError(f"{where}.cpus must be a positive integer, got {cpus!r}")
    options = {}
    for key in ("export", "evaluate_checkpoints"):
        if key in block:
            if kind != "rl-train" or not isinstance(block[key], bool):
                raise ValueError(f"{where}.{key} must be true or false and applies to kind 'rl-train' only")
            options[key] = block[key]
    if "task_score" in block:
        if kind not in ("rl-train", "optimize") or not isinstance(block["task_score"], bool):
            raise ValueError(f"{where}.task_score must be true or false and applies to kinds 'rl-train' and "
                             f"'optimize' only")
        options["task_score"] = block["task_score"]
    if kind == "rl-train":
        options.setdefault("export", True)
        options.setdefault("evaluate_checkpoints", False)
    args = {_norm(k): _check_value(v, f"{where}.args.{k}") for k, v in _table(block, "args", where).items()}
    grid_raw = _table(block, "grid", where)
    grid: dict[str, list] = {}
    for k, v in grid_raw.items():
        if not isinstance(v, list) or not v:
            raise ValueError(f"{where}.grid.{k} must be a non-empty list of values, got {v!r}")
        grid[_norm(k)] = [_check_value(x, f"{where}.grid.{k}") for x in v]
    both = set(args) & set(grid)
    if both:
        raise ValueError(f"{where}: {sorted(both)[0]!r} is both in args and in grid")
    overrides = {_norm(k): _check_value(v, f"{where}.quick.{k}") for k, v in _table(block, "quick", where).items()}
    template = block.get("name", _default_template(kind, grid))
    if not isinstance(template, str) or not template:
        raise ValueError(f"{where}.name must be a non-empty string template, got {template!r}")
    runs = []
    for combo in itertools.product(*grid.values()):
        params = {**args, **dict(zip(grid, combo))}
        names = _template_values(params, base)
        name = _format(template, names, where, "name")       # quick keeps the names
        if quick:
            params.update(overrides)
        if not _NAME_OK.match(name) or name in (".", ".."):
            raise ValueError(f"{where}.name: run name {name!r} is not a plain directory name "
                             "(letters, digits, . _ + = -; no '/')")
        values = {**params, **_template_values(params, base), "out": out_token, "name": name}
        for k, v in params.items():
            if isinstance(v, str) and _uses_fields(v):
                params[k] = _format(v, values, where, f"args.{k}")
        _resolve_paths(params, base)
        run = Run(name=name, kind=kind, params=params, cpus=cpus, options=dict(options), source=where)
        _validate(run, f"{where} (run {name!r})")
        runs.append(run)
    return runs


def load_spec(path: str | os.PathLike, out: str | os.PathLike = "OUT", *, quick: bool = False) -> SweepSpec:
    """Read and check a sweep file; ``out`` is the sweep directory (``{out}`` in arguments),
    ``quick`` applies the blocks' ``[runs.quick]`` arguments."""
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise ValueError(f"{src}: sweep file not found")
    text = decode_utf8(path.read_bytes(), src, hint="save the sweep file as UTF-8")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{src}: not valid TOML: {exc}") from None
    unknown = set(doc) - {"sweep", "runs"}
    if unknown:
        raise ValueError(f"{src}: unknown table {sorted(unknown)[0]!r} (allowed: [sweep], [[runs]])")
    meta = doc.get("sweep", {})
    if not isinstance(meta, dict) or set(meta) - {"description"}:
        raise ValueError(f"{src}: [sweep] may hold only description = \"...\"")
    blocks = doc.get("runs")
    if not isinstance(blocks, list) or not blocks:
        raise ValueError(f"{src}: no runs: add at least one [[runs]] table")
    out_token = str(Path(out).resolve())
    runs: list[Run] = []
    for i, block in enumerate(blocks):
        runs += _expand_block(block, i, src, path.parent.resolve(), quick, out_token)
    seen: dict[str, str] = {}
    for r in runs:
        if r.name in seen:
            raise ValueError(f"{src}: run name {r.name!r} is made twice ({seen[r.name]} and {r.source}); "
                             "put the differing parameters in the name templates")
        seen[r.name] = r.source
    return SweepSpec(path=path, description=str(meta.get("description", "")), runs=runs, text=text)
