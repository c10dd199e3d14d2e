"""A robustness study (``trajopt robustness``, whose printing is :mod:`trajopt.cli.robustness_command`):
the run (resumable, :func:`run_robustness_study`), its files and its plot. The replays
themselves are :mod:`trajopt.robustness`.

``DIR/settings.json`` (the gait file's hash, cycles, seed, ranges), ``DIR/samples.jsonl`` (one
line per finished sample, appended as they finish), ``DIR/report.json`` and ``DIR/samples.csv``
(written atomically at the end), ``DIR/robustness.png``. A resumed run refuses damaged files
(``settings.json`` not an object or not JSON, a ``samples.jsonl`` line that is not a sample) with
one error naming the file and the line, and cuts away a last line left without its newline by a
run killed while appending it (with a warning; that sample runs again).
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from soft_envs.envs import load_robot

from ..results.files import atomic_write_png, decode_utf8
from ..optim.motor_limit import motor_model_of
from ..replay import env_for_result, result_controls, result_task_keywords
from ..results.robot_match import locate_robot
from ..results.result import Result, atomic_write_bytes
from .study import (DERIVED_NAMES, PERTURBATIONS, SampleJob, draw_perturbation, map_samples, run_sample,
                         summarize)

__all__ = ["run_robustness_study", "plot_robustness", "robustness_jobs"]


def robustness_jobs(res: Result, cycles: int, samples: int, seed: int) -> tuple[SampleJob, list[SampleJob]]:
    """``(nominal job, perturbed jobs)`` of a result played for ``cycles`` cycles."""
    if cycles < 1 or samples < 1:
        raise ValueError(f"--cycles and --samples must be >= 1, got {cycles} and {samples}")
    env = env_for_result(res)
    u, n_prep, n_cycle = result_controls(res, env.robot, cycles)
    s = res.settings
    robot = locate_robot(res)                 # its file: the task's ground and box are built on it
    where = result_task_keywords(res, load_robot(robot))
    common = dict(robot=robot, u=u, dt=float(res.dt), n_prep=n_prep, n_cycle=n_cycle,
                  heading_deg=float(s.get("heading_deg", 0.0)), incline_deg=float(s.get("incline_deg", 0.0)),
                  seed=int(seed), contact=env.contact_model, substeps=int(env.substeps),
                  motor_model=motor_model_of(s), ground=where.get("ground"), box=where.get("box"))
    return (SampleJob(index=-1, **common),
            [SampleJob(index=i, perturbation=draw_perturbation(seed, i), **common) for i in range(samples)])


def _settings(result_path: Path, cycles: int, seed: int) -> dict[str, Any]:
    try:
        digest = hashlib.sha256(Path(result_path).read_bytes()).hexdigest()
    except OSError as exc:
        raise ValueError(f"{result_path}: cannot read the result file ({exc.strerror})") from None
    return {"result": str(result_path), "result_sha256": digest, "cycles": int(cycles), "seed": int(seed),
            "ranges": {k: list(v) for k, v in PERTURBATIONS.items()}}


#: the fields every line of samples.jsonl has (run_sample's), and what they must be
_SAMPLE_NUMBERS = ("speed_bl_per_min", "heading_drift_deg_per_cycle", "max_tilt_deg", *PERTURBATIONS)


def _read_json(path: Path, what: str) -> Any:
    try:
        return json.loads(decode_utf8(path.read_bytes(), f"{path} ({what})"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: {what} is not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno}): "
                         "the run's files are damaged; use --overwrite to start the run again") from None


def _sample_of(line: str, where: str) -> dict:
    """A line of samples.jsonl as a sample; ValueError naming ``where`` (file and line) otherwise."""
    try:
        s = json.loads(line)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: not valid JSON ({exc.msg}, column {exc.colno})") from None
    if not isinstance(s, dict):
        raise ValueError(f"{where}: a sample must be a JSON object, got {type(s).__name__}")
    index = s.get("index")
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        raise ValueError(f"{where}: field 'index' must be a sample number >= 0, got {index!r}")
    for key in _SAMPLE_NUMBERS:
        v = s.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"{where}: field {key!r} must be a number, got "
                             f"{'nothing (missing)' if key not in s else repr(v)}")
    if not isinstance(s.get("upright"), bool):
        raise ValueError(f"{where}: field 'upright' must be true or false, got {s.get('upright')!r}")
    return s


def _done_samples(out: Path, settings: dict) -> dict[int, dict]:
    """The samples already finished in ``out`` by a run with the same settings. A ValueError
    naming the file (and the line) when ``out`` holds a run with other settings, or damaged
    files; nothing is changed then. A last line without its newline (a run killed while appending
    it) is cut away, with a warning, and its sample runs again."""
    sfile, lines = out / "settings.json", out / "samples.jsonl"
    if not sfile.exists():
        return {}
    old = _read_json(sfile, "the run's settings")
    if not isinstance(old, dict):
        raise ValueError(f"{sfile}: the run's settings must be a JSON object, got {type(old).__name__}; use "
                         "--overwrite to start the run again")
    if {k: v for k, v in old.items() if k != "result"} != {k: v for k, v in settings.items() if k != "result"}:
        raise ValueError(f"{out} holds a robustness run with other settings (gait file, cycles, seed or ranges): "
                         "use another --out, or --overwrite to replace it")
    if not lines.exists():
        return {}
    data = lines.read_bytes()
    text = decode_utf8(data, lines)
    rows = text.split("\n")
    cut = rows.pop()                       # "" when the file ends with its newline
    done = {}
    for n, line in enumerate(rows, start=1):
        s = _sample_of(line, f"{lines} line {n}")
        done[s["index"]] = s
    if cut:
        print(f"warning: {lines} line {len(rows) + 1} was cut (a run stopped while writing it): removed, its "
              "sample runs again", file=sys.stderr)
        with lines.open("r+b") as fh:
            fh.truncate(len(data) - len(cut.encode("utf-8")))
            fh.flush()
            os.fsync(fh.fileno())
    return done


def _append(path: Path, sample: dict) -> None:
    """Append one sample as one whole line (written with one write, then fsynced)."""
    line = (json.dumps(sample) + "\n").encode()
    with path.open("ab") as fh:
        fh.write(line)
        fh.flush()
        os.fsync(fh.fileno())


def plot_robustness(report: dict, samples: list[dict], path: Path) -> Path:
    """Histogram of the speeds (nominal, median, 5th and 95th percentiles marked) and the speed
    against each perturbation; written atomically as PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    speed = np.array([s["speed_bl_per_min"] for s in samples], dtype=float)
    up = np.array([bool(s["upright"]) for s in samples])
    names = list(DERIVED_NAMES)
    fig, axes = plt.subplots(3, 5, figsize=(17, 9))
    ax = axes.flat[0]
    ok = np.isfinite(speed)
    ax.hist(speed[ok], bins=max(5, min(30, ok.sum() // 3)), color="0.6")
    nominal = report["nominal"].get("speed_bl_per_min", np.nan)
    ax.axvline(nominal, color="C3", lw=2, label=f"nominal {nominal:.2f}")
    q = report["speed_bl_per_min"]
    for key, style in (("median", "-"), ("p5", "--"), ("p95", "--")):
        ax.axvline(q[key], color="k", ls=style, lw=1, label=f"{key} {q[key]:.2f}")
    ax.set_xlabel("speed [BL/min]")
    ax.set_title(f"{len(samples)} replays, {100 * report['upright_fraction']:.0f} % upright")
    ax.legend(fontsize=7)
    for ax, name in zip(axes.flat[1:], names):
        x = np.array([s.get(name, np.nan) for s in samples], dtype=float)
        ax.scatter(x[up & ok], speed[up & ok], s=8, color="C0", label="upright")
        ax.scatter(x[~up & ok], speed[~up & ok], s=8, color="C3", marker="x", label="fell")
        ax.axhline(nominal, color="C3", lw=1)
        rho = report["speed_rank_correlation"].get(name)
        ax.set_title(f"{name}" + (f" (rank corr. {rho:+.2f})" if rho is not None else ""), fontsize=9)
        ax.set_ylabel("BL/min", fontsize=8)
    axes.flat[1].legend(fontsize=7)
    for ax in axes.flat[1 + len(names):]:
        ax.axis("off")
    gait, n = Path(str(report.get("result", "the gait"))).name, report.get("cycles")
    cycles = "" if n is None else f" of {n} cycle{'s' * (n != 1)}"
    fig.suptitle(f"robustness of the gait {gait}: its speed over {len(samples)} perturbed replays{cycles}",
                 fontsize=12)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    return atomic_write_png(fig, path, dpi=90)


def _write_csv(path: Path, samples: list[dict]) -> None:
    cols = ["index", *DERIVED_NAMES, "speed_bl_per_min", "upright", "heading_drift_deg_per_cycle", "max_tilt_deg",
            "sim_failure"]
    buf = io.StringIO()
    w = csv.DictWriter(buf, cols, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for s in samples:
        w.writerow(s)
    atomic_write_bytes(path, buf.getvalue().encode())


def run_robustness_study(result: str | os.PathLike, out: str | os.PathLike, *, samples: int = 32, cycles: int = 4,
                         seed: int = 0, workers: int = 1, overwrite: bool = False) -> tuple[dict[str, Any], list[Path]]:
    """Replay the gait of the result file ``result`` ``samples`` times under perturbations for
    ``cycles`` cycles and write the study to ``out`` (see the module docstring): ``(report,
    files written)``. Resumes the samples of a study with the same settings there (``overwrite``:
    discard them); a second study into the same ``out`` is refused while this one runs."""
    from ..results.reservation import reserve       # a second study into the same --out is refused
    with reserve(Path(out) / "robustness.lock", f"robustness folder {out}"):
        return _run_study(Path(result), Path(out), samples, cycles, seed, workers, overwrite)


def _run_study(result: Path, out: Path, samples: int, cycles: int, seed: int, workers: int,
               overwrite: bool) -> tuple[dict[str, Any], list[Path]]:
    res = Result.load(result)
    nominal_job, jobs = robustness_jobs(res, cycles, samples, seed)
    settings = _settings(result, cycles, seed)
    if overwrite:      # a new run from scratch: its samples replace the old ones
        (out / "samples.jsonl").unlink(missing_ok=True)
        (out / "settings.json").unlink(missing_ok=True)
    done = _done_samples(out, settings)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(out / "settings.json", json.dumps(settings, indent=1).encode())
    todo = [j for j in jobs if j.index not in done]
    results, where = map_samples(todo, workers)
    print(f"{res.summary()}\n{len(jobs)} replays of {cycles} cycles ({len(jobs) - len(todo)} done before), "
          f"running {where}")
    from ..progress import Progress      # a bar on a terminal; off it, a line after 30 s of silence
    with Progress(len(todo), "robustness", "replay", per_item=False) as progress:
        nominal = run_sample(nominal_job)
        for sample in results:
            done[sample["index"]] = sample
            _append(out / "samples.jsonl", sample)
            progress.update(1)
    samples_done = [done[j.index] for j in jobs]
    report = summarize(nominal, samples_done)
    report.update(result=str(result), cycles=cycles, seed=seed, backend=where)
    atomic_write_bytes(out / "report.json", json.dumps(report, indent=1).encode())
    _write_csv(out / "samples.csv", samples_done)
    png = plot_robustness(report, samples_done, out / "robustness.png")
    return report, [out / "report.json", out / "samples.csv", png]
