"""Optimisation results: everything needed to replay, evaluate, render or play a gait.

A :class:`Result` is saved as ``NAME.npz`` (arrays plus the metadata as JSON) and ``NAME.json``
(the same metadata, for people and other tools). The two are one unit:

* the ``.npz`` is authoritative: it carries ``content_sha256``, a SHA-256 of its metadata and
  arrays, checked when it is read (a damaged or hand-edited file is refused);
* the ``.json`` repeats that hash. Each file is written atomically (:mod:`trajopt.results.files`), the
  ``.npz`` first; a save killed between the two leaves the new ``.npz`` beside the old (or no)
  ``.json``, and :meth:`Result.load` reports that (:class:`ResultFileWarning`), reads the
  ``.npz`` and rewrites the ``.json`` from it;
* a result records the fingerprint of its robot (:mod:`trajopt.results.robot_match`), so that it is
  never replayed on another or an edited robot by mistake;
* a result's controls are checked against its keyframes (:mod:`trajopt.results.checks`), so an
  edited ``u`` or ``u_post`` whose hash was recomputed is refused too;
* ``format_version`` 2 requires ``content_sha256`` and ``robot_fingerprint``: removing either is
  refused. Older files (version 1 or none) may lack them only if they lack every field that came
  with them (:func:`_check_format`).

Only what :meth:`Result.validate` accepts is written, so :meth:`Result.load` never meets values
that :meth:`Result.save` wrote (NaN controls, wrong shapes).
"""
from __future__ import annotations

import hashlib
import io
import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .files import atomic_write_bytes
from ..optim.gait import GaitSpec
from .checks import check_controls
from ..tasks.registry import speed_along_path

__all__ = ["Result", "ResultFileWarning", "atomic_write_bytes", "result_path", "partial_path", "robot_file_name",
           "FORMAT_VERSION"]

#: 2: content_sha256 (in the .npz) and robot_fingerprint (in the metadata) are required; 1 and
#: files without a version (0) predate them (see :func:`_check_format`)
FORMAT_VERSION = 2
_ARRAYS = ("z", "u", "u_post", "target", "com")


class ResultFileWarning(UserWarning):
    """A result's ``.json`` is missing or does not match its ``.npz`` (an interrupted save); the
    ``.npz`` was read and the ``.json`` rewritten from it."""


def result_path(path: str | Path) -> Path:
    """``path`` as a result file: ``NAME.npz``. A literal ``.npz`` is kept, a ``.json`` (the
    sidecar) becomes ``.npz``; any other dot belongs to the name (``tripod_walk_v5.5`` is saved
    as ``tripod_walk_v5.5.npz``, not ``tripod_walk_v5.npz``)."""
    path = Path(path)
    if path.suffix == ".npz":
        return path
    if path.suffix == ".json":
        return path.with_suffix(".npz")
    return path.with_name(path.name + ".npz")


def partial_path(path: str | Path) -> Path:
    """Where the checkpoints of a run that will write ``path`` go until it finishes:
    ``NAME.partial.npz`` beside ``NAME.npz``."""
    path = result_path(path)
    return path.with_name(f"{path.stem}.partial.npz")


def content_hash(meta_text: str, arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of a result's metadata text and arrays (name, dtype, shape and bytes of each)."""
    h = hashlib.sha256(meta_text.encode())
    for key in _ARRAYS:
        a = np.ascontiguousarray(arrays[key])
        h.update(f"\0{key}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    return h.hexdigest()


@dataclass
class Result:
    """A gait.

    robot : shipped robot name or path of its robot.toml.
    task : a task of :data:`trajopt.tasks.TASKS` ("walk", "turn", "incline", "custom"), or "rl".
    motor_names, dt : controls' columns and the simulation time step [s] (one row of u per step).
    z : parameters (keyframes); u : (K, n_motors) optimised controls (prep + 2 cycles) [m];
    u_post : the zero-slack controls (paper III-B-2), what hardware plays.
    target : (K+1, 2) target horizontal COM path; com : (K+1, 3) simulated COM.
    settings : everything that made it (parameterisation, weights, incline, speed ...).
    history : one dict per Gauss-Newton iteration. evaluation : see trajopt.evaluation.
    status : how the run ended (:data:`trajopt.cli.commands.STATUS_MEANING`); "running" or
    "interrupted" for a checkpoint.
    robot_fingerprint : the robot it was made for (:func:`trajopt.results.robot_match.fingerprint_of`);
    empty for robots built in Python and for files of older versions.
    """

    robot: str
    task: str
    motor_names: list[str]
    dt: float
    z: np.ndarray
    u: np.ndarray
    u_post: np.ndarray
    target: np.ndarray
    com: np.ndarray
    settings: dict[str, Any] = field(default_factory=dict)
    history: list[dict] = field(default_factory=list)
    evaluation: dict[str, Any] = field(default_factory=dict)
    status: str = ""
    robot_fingerprint: dict[str, Any] = field(default_factory=dict)
    #: the file it was last loaded from or saved to ("" for a result in memory); not saved
    path: str = field(default="", compare=False, repr=False)

    # ------------------------------------------------------------------ derived
    @property
    def n_steps(self) -> int:
        return len(self.u)

    def metadata(self) -> dict[str, Any]:
        return {"format_version": FORMAT_VERSION, "robot": self.robot, "task": self.task,
                "motor_names": list(self.motor_names), "dt": self.dt, "settings": self.settings,
                "history": self.history, "evaluation": self.evaluation, "status": self.status,
                "robot_fingerprint": self.robot_fingerprint}

    # ------------------------------------------------------------------ files
    def save(self, path: str | Path, *, overwrite: bool = True) -> Path:
        """Write ``path`` (.npz added if missing) and its .json sibling (see the module
        docstring); ``overwrite=False`` refuses an existing ``path``. A result that
        :meth:`validate` refuses (NaN controls, wrong shapes) is not written."""
        path = result_path(path)
        self.validate(str(path))
        if not overwrite and path.exists():
            raise ValueError(f"{path}: exists already; pass --overwrite (overwrite=True) to replace it")
        meta = json.dumps(_finite(self.metadata()), default=_json_default, indent=1, allow_nan=False)
        arrays = {k: np.asarray(getattr(self, k), dtype=np.float64) for k in _ARRAYS}
        digest = content_hash(meta, arrays)
        buf = io.BytesIO()
        np.savez(buf, meta=np.array(meta), content_sha256=np.array(digest), **arrays)
        atomic_write_bytes(path, buf.getvalue())
        atomic_write_bytes(path.with_suffix(".json"), _sidecar_text(meta, digest).encode())
        self.path = str(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Result":
        """Read a result; every problem is a ValueError naming the file and the field."""
        path = Path(path)
        if path.suffix != ".npz" and path.with_suffix(".npz").is_file():
            path = path.with_suffix(".npz")
        src = str(path)
        if not path.is_file():
            raise ValueError(f"{src}: result file not found")
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: np.array(data[k]) for k in data.files}
        except Exception as exc:
            raise ValueError(f"{src}: not a readable .npz result file ({exc})") from exc
        for key in ("meta", *_ARRAYS):
            if key not in arrays:
                raise ValueError(f"{src}: field {key!r} is missing")
        digest = _check_digest(arrays, src)
        try:
            meta = json.loads(str(arrays["meta"]))
        except json.JSONDecodeError as exc:
            raise ValueError(f"{src}: field 'meta' is not valid JSON ({exc})") from exc
        if not isinstance(meta, dict):
            raise ValueError(f"{src}: field 'meta' must be a JSON object")
        _check_format(meta, digest, path)
        for key in ("robot", "task", "motor_names", "dt"):
            if key not in meta:
                raise ValueError(f"{src}: metadata field {key!r} is missing")
        types = {"robot": str, "task": str, "motor_names": list, "dt": (int, float), "settings": dict,
                 "history": list, "evaluation": dict, "status": str, "format_version": int,
                 "robot_fingerprint": dict}
        for key, typ in types.items():
            if key in meta and (isinstance(meta[key], bool) or not isinstance(meta[key], typ)):
                raise ValueError(f"{src}: metadata field {key!r} has the wrong type ({type(meta[key]).__name__})")
        if not all(isinstance(h, dict) for h in meta.get("history", [])):
            raise ValueError(f"{src}: metadata field 'history' must be a list of objects")
        res = cls(robot=meta["robot"], task=meta["task"], motor_names=list(meta["motor_names"]),
                  dt=float(meta["dt"]), settings=meta.get("settings", {}), history=meta.get("history", []),
                  evaluation=meta.get("evaluation", {}), status=meta.get("status", ""),
                  robot_fingerprint=meta.get("robot_fingerprint", {}), path=src,
                  **{k: arrays[k].astype(np.float64) for k in _ARRAYS})
        res.validate(src)
        if digest is not None:
            _check_sidecar(path, digest, str(arrays["meta"]))
        return res

    def validate(self, src: str = "<result>") -> None:
        """Raise ValueError naming ``src`` and the field for anything :meth:`load` would refuse."""
        if not (isinstance(self.motor_names, (list, tuple)) and all(isinstance(m, str) for m in self.motor_names)):
            raise ValueError(f"{src}: field 'motor_names' must be a list of names")
        for key in _ARRAYS:
            try:
                setattr(self, key, np.asarray(getattr(self, key), dtype=np.float64))
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{src}: field {key!r} must be an array of numbers ({exc})") from None
        M = len(self.motor_names)
        if isinstance(self.dt, bool) or not isinstance(self.dt, (int, float, np.floating)) \
                or not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"{src}: field 'dt' must be positive, got {self.dt}")
        for key in ("u", "u_post"):
            arr = getattr(self, key)
            if arr.ndim != 2 or arr.shape[1] != M:
                raise ValueError(f"{src}: field {key!r} must have shape (K, {M}), got {arr.shape}")
            bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
            if bad.size:
                raise ValueError(f"{src}: field {key!r} contains NaN or inf (steps {bad[:5].tolist()})")
        if self.u_post.shape != self.u.shape:
            raise ValueError(f"{src}: field 'u_post' has shape {self.u_post.shape}, u has {self.u.shape}")
        if self.target.size and self.target.shape != (len(self.u) + 1, 2):
            raise ValueError(f"{src}: field 'target' must have shape ({len(self.u) + 1}, 2), got {self.target.shape}")
        if self.com.size and self.com.shape != (len(self.u) + 1, 3):
            raise ValueError(f"{src}: field 'com' must have shape ({len(self.u) + 1}, 3), got {self.com.shape}")
        if self.z.ndim != 1 or not np.isfinite(self.z).all():
            raise ValueError(f"{src}: field 'z' must be a finite vector, got shape {self.z.shape}")
        s = self.settings
        if "keyframes" in s:
            for key in ("n_prep", "n_cycle", "n_keyframes", "symmetry"):
                if key not in s:
                    raise ValueError(f"{src}: settings field {key!r} is missing (needed with keyframes)")
            for key in ("n_prep", "n_cycle", "n_keyframes"):
                if isinstance(s[key], bool) or not isinstance(s[key], int) or s[key] < 0:
                    raise ValueError(f"{src}: settings field {key!r} must be a non-negative integer, got {s[key]!r}")
            try:
                GaitSpec.from_settings(s)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{src}: settings: {exc}") from None
            kf = np.asarray(s["keyframes"], dtype=object)
            if kf.shape != (M, s["n_keyframes"]):
                raise ValueError(f"{src}: settings field 'keyframes' must have shape ({M}, {s['n_keyframes']}), "
                                 f"got {kf.shape}")
            try:
                kf = kf.astype(np.float64)
            except (TypeError, ValueError):
                raise ValueError(f"{src}: settings field 'keyframes' must be numbers") from None
            if not np.isfinite(kf).all():
                raise ValueError(f"{src}: settings field 'keyframes' contains NaN or inf")
            check_controls(self, src)

    def summary(self) -> str:
        ev = self.evaluation
        speed = ev.get("speed_bl_per_min")
        parts = [f"{self.robot} {self.task}", f"{len(self.u)} steps x {len(self.motor_names)} motors"]
        if "sim_failure" in ev:
            parts.append(f"its evaluation's simulation failed ({ev['sim_failure']})")
        elif speed_along_path(self.task) and ev.get("cycle_path_speed_bl_per_min") is not None:
            parts.append(f"{ev['cycle_path_speed_bl_per_min']:.2f} BL/min along its path "
                         f"over {ev.get('cycles')} cycles")
            parts.append("upright" if ev.get("upright") else "FELL")
        elif speed is not None:
            parts.append(f"{speed:.2f} BL/min over {ev.get('cycles')} cycles")
            parts.append("upright" if ev.get("upright") else "FELL")
        if "heading_change_deg" in ev:
            parts.append(f"heading change {ev['heading_change_deg']:+.1f} deg")
        if self.history:
            last = self.history[-1]
            parts.append(f"{len(self.history)} GN iterations, objective "
                         f"{last.get('objective_after', last.get('objective', float('nan'))):.4g}")
        return ", ".join(parts)


def _check_digest(arrays: dict[str, np.ndarray], src: str) -> str | None:
    """The content hash of a file that carries one (checked), None for files of older versions."""
    if "content_sha256" not in arrays:
        return None
    stored = str(arrays["content_sha256"])
    if content_hash(str(arrays["meta"]), {k: arrays[k] for k in _ARRAYS}) != stored:
        raise ValueError(f"{src}: its content does not match its content_sha256 (the file is damaged, or "
                         "was changed by something other than Result.save)")
    return stored


def _check_format(meta: dict, digest: str | None, path: Path) -> None:
    """Refuse a file whose ``content_sha256`` or ``robot_fingerprint`` was removed. Version 2
    files must carry both. A file of version 1 or without a version may lack them only when it
    lacks every field that came with them (the hash in the .npz, ``robot_fingerprint`` in the
    metadata, the hash in the .json): version-1 files were written both before and after
    hashing, so its version alone does not say that it predates them."""
    src = str(path)
    version = meta.get("format_version", 0)
    if isinstance(version, bool) or not isinstance(version, int):
        raise ValueError(f"{src}: metadata field 'format_version' has the wrong type ({type(version).__name__})")
    if version > FORMAT_VERSION:
        raise ValueError(f"{src}: format_version {version} is newer than this library reads ({FORMAT_VERSION})")
    has_fp = "robot_fingerprint" in meta
    if version >= 2:
        missing = [name for name, there in (("content_sha256", digest is not None),
                                            ("robot_fingerprint", has_fp)) if not there]
        if missing:
            raise ValueError(f"{src}: field {missing[0]!r} is missing (required from format_version 2; this file "
                             f"has format_version {version}): the file was edited")
        return
    newer = [name for name, there in (("content_sha256", digest is not None), ("robot_fingerprint", has_fp),
                                      ("content_sha256 in the .json", _sidecar_hash(path) is not None)) if there]
    lacking = [name for name in ("content_sha256", "robot_fingerprint") if name not in newer]
    if newer and lacking:
        raise ValueError(f"{src}: field {lacking[0]!r} is missing, but the file has {newer[0]}, so it does not "
                         "predate it: the file was edited")


def _sidecar_hash(path: Path) -> str | None:
    try:
        doc = json.loads(path.with_suffix(".json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    digest = doc.get("content_sha256") if isinstance(doc, dict) else None
    return digest if isinstance(digest, str) else None


def _sidecar_text(meta_text: str, digest: str) -> str:
    return json.dumps({"content_sha256": digest, **json.loads(meta_text)}, indent=1)


def _check_sidecar(path: Path, digest: str, meta_text: str) -> None:
    """Rewrite the .json beside ``path`` from the .npz, with a :class:`ResultFileWarning`, when it is
    missing or differs from what :meth:`Result.save` writes for it (a save interrupted between the
    two renames, or a .json edited or replaced)."""
    sidecar = path.with_suffix(".json")
    expected = _sidecar_text(meta_text, digest)
    try:
        current = sidecar.read_text(encoding="utf-8")
    except (OSError, ValueError):
        current = None
    if current == expected:
        return
    what = "is missing" if current is None else "does not match"
    try:
        atomic_write_bytes(sidecar, expected.encode())
        done = "it was rewritten from the .npz"
    except OSError as exc:
        done = f"it could not be rewritten ({exc})"
    warnings.warn(f"{sidecar} {what} {path} (a save was interrupted, or one of the two was replaced): {path} "
                  f"is authoritative and was read; {done}", ResultFileWarning, stacklevel=3)


def _finite(o):
    """NaN and infinities become null: the .json files stay valid JSON for other tools."""
    if isinstance(o, float) and not np.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, np.ndarray):
        return _finite(o.tolist())
    if isinstance(o, np.floating):
        return _finite(float(o))
    return o


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def robot_file_name(robot: str) -> str:
    """A shipped robot's name, or a robot file's ``[robot] name`` (``quadruped`` for
    ``results/my_robot/robot.toml``); the file's stem when it names none usable."""
    if not robot.endswith(".toml"):
        return robot
    import tomllib
    try:
        with open(robot, "rb") as fh:
            name = tomllib.load(fh).get("robot", {}).get("name")
    except (OSError, tomllib.TOMLDecodeError, AttributeError):
        name = None
    ok = (isinstance(name, str) and name.strip() == name and name not in ("", ".", "..")
          and not set(name) & set("/\\\0"))
    return name if ok else Path(robot).stem
