"""The checkpoint of a ``--speed max`` search (``trajopt optimize --speed max --resume``): every
finished optimisation of the search in ``NAME.search.partial/`` beside the result, and what a
search must match to resume from it (:func:`search_identity`)."""
from __future__ import annotations

import json
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ..optim.motor_limit import SPEED
from ..optim.start import newton_tol_of
from ..results.files import atomic_write_bytes
from ..results.result import Result
from .settings import SearchSettings
from .table import TABLE_COLUMNS

__all__ = ["SearchCheckpoint", "search_checkpoint_dir", "search_identity", "finish_search"]


def search_checkpoint_dir(result_file: str | Path) -> Path:
    """``NAME.search.partial/`` beside the result ``NAME.npz``: an unfinished search's runs."""
    p = Path(result_file)
    return p.with_name(p.name.removesuffix(".npz") + ".search.partial")


class SearchCheckpoint:
    """The finished optimisations of a search in ``folder``: ``state.json`` (what the search
    is: its settings, pinned cycle, heading, robot and contact law; its rows; ``status``
    running or interrupted) and ``run_NNN.npz`` (+ ``.json``) per finished optimisation.
    :meth:`load` reads and checks them (ValueError naming the file and the field);
    :func:`~trajopt.fastest.fastest_gait` replays them and saves each new one."""

    STATE = "state.json"

    def __init__(self, folder: str | Path, identity: dict[str, Any] | None = None):
        self.folder = Path(folder)
        self.identity = identity or {}

    @property
    def state_file(self) -> Path:
        return self.folder / self.STATE

    def _run_file(self, i: int) -> Path:
        return self.folder / f"run_{i:03d}.npz"

    def _state(self, rows: list[dict], status: str) -> None:
        data = {"identity": self.identity, "status": status, "rows": rows}
        atomic_write_bytes(self.state_file, (json.dumps(data, indent=1, default=float) + "\n").encode())

    def start(self, rows: list[dict]) -> None:
        """Mark the search running (its ``rows`` replayed so far kept)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        self._state(rows, "running")

    def save_run(self, rows: list[dict], res: Result | None) -> None:
        """After optimisation ``len(rows) - 1``: its result (if any), then the rows."""
        if res is not None:
            res.save(self._run_file(len(rows) - 1))
        self._state(rows, "running")

    def mark(self, rows: list[dict], status: str) -> None:
        self._state(rows, status)

    def remove(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)

    def load(self) -> tuple[list[tuple[dict, Result | None]], str]:
        """``(finished runs, status)``: each run's row and result (None: skipped or failed), in
        the order the search made them. Refuses (ValueError naming the file and the field) a
        damaged state or one of another search (its settings, robot, contact law)."""
        path = self.state_file
        hint = "continue with the same options, or start afresh with --overwrite"
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except UnicodeDecodeError as err:
            raise ValueError(f"{path}: not UTF-8 ({err.reason} at byte {err.start}); {hint}") from None
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: not JSON ({err.msg}, line {err.lineno}); {hint}") from None
        if not isinstance(data, dict):
            raise ValueError(f"{path}: expected a JSON object, got {type(data).__name__}; {hint}")
        identity, rows, status = data.get("identity"), data.get("rows"), data.get("status")
        if not isinstance(identity, dict):
            raise ValueError(f"{path}: field 'identity' is missing or not an object; {hint}")
        if not isinstance(rows, list) or not all(isinstance(r, dict) and set(TABLE_COLUMNS) <= set(r) for r in rows):
            raise ValueError(f"{path}: field 'rows' must be a list of search-table rows ({', '.join(TABLE_COLUMNS)}); "
                             f"{hint}")
        expected = json.loads(json.dumps(self.identity, default=float))
        changed = [k for k in sorted(set(expected) | set(identity)) if expected.get(k) != identity.get(k)]
        if changed:
            what = []
            for k in changed:
                a, b = identity.get(k), expected.get(k)
                if isinstance(a, dict) and isinstance(b, dict):
                    what += [f"{k}.{f}: {a.get(f)!r} -> {b.get(f)!r}" for f in sorted(set(a) | set(b))
                             if a.get(f) != b.get(f)]
                else:
                    what.append(f"{k}: {a!r} -> {b!r}")
            raise ValueError(f"{path}: cannot resume: this search differs from the interrupted one "
                             f"({'; '.join(what[:4])}); run it with the interrupted search's options, or start afresh "
                             "with --overwrite")
        runs: list[tuple[dict, Result | None]] = []
        for i, row in enumerate(rows):
            res = None
            if not str(row.get("status", "")).startswith(("skipped", "failed")):
                file = self._run_file(i)
                if not file.is_file():
                    raise ValueError(f"{file}: missing: the checkpoint's row {i} has no result; {hint}")
                res = Result.load(file)
            runs.append((row, res))
        return runs, str(status)


def search_identity(env: Any, settings: SearchSettings, cycle_steps: int | None, heading_deg: float,
                    motor_model: str = SPEED) -> dict:
    """What a search checkpoint must match to be resumed: the settings, the pinned cycle, the
    heading, the robot (its fingerprint), the contact law, the physics steps per control step, the
    motor model and the Newton tolerance of a physics step."""
    from soft_envs.envs import robot_fingerprint
    fp = robot_fingerprint(env.robot) or {}
    return json.loads(json.dumps({"settings": asdict(settings), "cycle_steps": cycle_steps,
                                  "heading_deg": float(heading_deg), "robot": fp.get("sha256", env.robot.name),
                                  "contact": env.contact_model, "substeps": int(env.substeps),
                                  "motor_model": motor_model, "newton_tol": newton_tol_of(env)}, default=float))


def finish_search(checkpoint: str | Path) -> None:
    """Remove a finished search's checkpoint folder (after its result and table are written)."""
    SearchCheckpoint(checkpoint).remove()

