"""Optimisation results: everything needed to replay, evaluate, render or play a gait.

A :class:`Result` is saved as ``NAME.npz`` (arrays plus the metadata as JSON; authoritative)
and ``NAME.json`` (the same metadata, for people and other tools), each written atomically
(temporary file + ``os.replace``), so an interrupted save never leaves a broken file.
"""
from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Result", "atomic_write_bytes", "FORMAT_VERSION"]

FORMAT_VERSION = 1
_ARRAYS = ("z", "u", "u_post", "target", "com")


def atomic_write_bytes(path: Path, data: bytes) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


@dataclass
class Result:
    """A gait.

    robot : shipped robot name or path of its robot.toml.
    task : "walk" | "turn" | "incline" | "custom" | "rl".
    motor_names, dt : controls' columns and the simulation time step [s] (one row of u per step).
    z : parameters (keyframes); u : (K, n_motors) optimised controls (prep + 2 cycles) [m];
    u_post : the zero-slack controls (paper III-B-2), what hardware plays.
    target : (K+1, 2) target horizontal COM path; com : (K+1, 3) simulated COM.
    settings : everything that made it (parameterisation, weights, incline, speed ...).
    history : one dict per Gauss-Newton iteration. evaluation : see trajopt.evaluation.
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

    # ------------------------------------------------------------------ derived
    @property
    def n_steps(self) -> int:
        return len(self.u)

    def metadata(self) -> dict[str, Any]:
        return {"format_version": FORMAT_VERSION, "robot": self.robot, "task": self.task,
                "motor_names": list(self.motor_names), "dt": self.dt, "settings": self.settings,
                "history": self.history, "evaluation": self.evaluation, "status": self.status}

    # ------------------------------------------------------------------ files
    def save(self, path: str | Path) -> Path:
        """Write ``path`` (.npz added if missing) and its .json sibling atomically."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        meta = json.dumps(_finite(self.metadata()), default=_json_default, indent=1, allow_nan=False)
        import io
        buf = io.BytesIO()
        np.savez(buf, meta=np.array(meta), **{k: np.asarray(getattr(self, k)) for k in _ARRAYS})
        atomic_write_bytes(path, buf.getvalue())
        atomic_write_bytes(path.with_suffix(".json"), meta.encode())
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
        try:
            meta = json.loads(str(arrays["meta"]))
        except json.JSONDecodeError as exc:
            raise ValueError(f"{src}: field 'meta' is not valid JSON ({exc})") from exc
        if not isinstance(meta, dict):
            raise ValueError(f"{src}: field 'meta' must be a JSON object")
        for key in ("robot", "task", "motor_names", "dt"):
            if key not in meta:
                raise ValueError(f"{src}: metadata field {key!r} is missing")
        types = {"robot": str, "task": str, "motor_names": list, "dt": (int, float), "settings": dict,
                 "history": list, "evaluation": dict, "status": str, "format_version": int}
        for key, typ in types.items():
            if key in meta and (isinstance(meta[key], bool) or not isinstance(meta[key], typ)):
                raise ValueError(f"{src}: metadata field {key!r} has the wrong type ({type(meta[key]).__name__})")
        if not all(isinstance(h, dict) for h in meta.get("history", [])):
            raise ValueError(f"{src}: metadata field 'history' must be a list of objects")
        if meta.get("format_version", 0) > FORMAT_VERSION:
            raise ValueError(f"{src}: format_version {meta['format_version']} is newer than this "
                             f"library reads ({FORMAT_VERSION})")
        res = cls(robot=meta["robot"], task=meta["task"], motor_names=list(meta["motor_names"]),
                  dt=float(meta["dt"]), settings=meta.get("settings", {}), history=meta.get("history", []),
                  evaluation=meta.get("evaluation", {}), status=meta.get("status", ""),
                  **{k: arrays[k].astype(np.float64) for k in _ARRAYS})
        res.validate(src)
        return res

    def validate(self, src: str = "<result>") -> None:
        M = len(self.motor_names)
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"{src}: field 'dt' must be positive, got {self.dt}")
        for key in ("u", "u_post"):
            arr = getattr(self, key)
            if arr.ndim != 2 or arr.shape[1] != M:
                raise ValueError(f"{src}: field {key!r} must have shape (K, {M}), got {arr.shape}")
            if not np.isfinite(arr).all():
                raise ValueError(f"{src}: field {key!r} contains NaN or inf")
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
            kf = np.asarray(s["keyframes"], dtype=object)
            if kf.shape != (M, s["n_keyframes"]):
                raise ValueError(f"{src}: settings field 'keyframes' must have shape ({M}, {s['n_keyframes']}), "
                                 f"got {kf.shape}")

    def summary(self) -> str:
        ev = self.evaluation
        speed = ev.get("speed_bl_per_min")
        parts = [f"{self.robot} {self.task}", f"{len(self.u)} steps x {len(self.motor_names)} motors"]
        if speed is not None:
            parts.append(f"{speed:.2f} BL/min over {ev.get('cycles')} cycles")
            parts.append("upright" if ev.get("upright") else "FELL")
        if "heading_change_deg" in ev:
            parts.append(f"heading change {ev['heading_change_deg']:+.1f} deg")
        if self.history:
            last = self.history[-1]
            parts.append(f"{len(self.history)} GN iterations, objective "
                         f"{last.get('objective_after', last.get('objective', float('nan'))):.4g}")
        return ", ".join(parts)


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
