"""The files of a calibration (``trajopt calibrate``, :mod:`trajopt.cli.calibrate_command`): marker
points read from a CSV, the new robot.toml with the fitted values, the before/after plot of the
tracks. The fit itself is :func:`trajopt.calibration.calibrate.fit_parameters`; the checks of the data and of
the fit are :mod:`trajopt.calibration.checks`."""
from __future__ import annotations

import csv
import io
import os
import time
from pathlib import Path

import numpy as np

from soft_envs.envs import MarkerSet, load_robot, parameter_values

from .calibrate import CalibrationFit, MarkerData
from ..results.files import atomic_write_bytes, atomic_write_png
from .tracks import read_utf8

__all__ = ["read_marker_points", "write_calibrated_robot", "plot_tracks", "tracks_figure", "HEADER"]

#: first line of every robot.toml that calibrate writes (it replaces only such files)
HEADER = "# Calibrated by trajopt calibrate"


def read_marker_points(path: str | Path, mesh) -> MarkerSet:
    """Markers from a CSV with the header ``marker,x,y,z`` (rest positions [m] in the robot's
    simulation frame), bound to ``mesh``; errors name the file and line."""
    path = Path(path)
    text = read_utf8(path, "marker points file")
    names, points = [], []
    with io.StringIO(text, newline="") as fh:
        reader = csv.reader(fh)
        header = [h.strip().lower() for h in next(reader, [])]
        if header != ["marker", "x", "y", "z"]:
            raise ValueError(f"{path}:1: the header must be marker,x,y,z, got {','.join(header)!r}")
        for row in reader:
            if not any(c.strip() for c in row):
                continue
            where = f"{path}:{reader.line_num}"
            if len(row) != 4:
                raise ValueError(f"{where}: expected 4 columns (marker,x,y,z), got {len(row)}")
            try:
                points.append([float(c) for c in row[1:]])
            except ValueError:
                raise ValueError(f"{where}: x, y, z must be numbers, got {row[1:]}") from None
            names.append(row[0].strip())
    if not names:
        raise ValueError(f"{path}: no markers")
    return MarkerSet.bind(mesh, names, points, source=str(path))


def write_calibrated_robot(source: Path, target: Path, robot, names, values) -> Path:
    """Write ``target``: the robot file ``source`` (comments and layout kept, through tomlkit)
    with the parameters ``names`` set to ``values`` (and ``[contact] model`` to ``robot``'s law
    when it was switched from the file's) and its mesh path made relative to the new
    file (absolute when the two share no folder but the root); checked by loading it back."""
    import tomlkit
    doc = tomlkit.parse(source.read_text())
    mesh = (source.parent / str(doc["robot"]["mesh"])).resolve()
    here = target.parent.resolve()
    near = os.path.commonpath([mesh, here]) != os.path.sep          # relative unless only / is shared
    doc["robot"]["mesh"] = os.path.relpath(mesh, here) if near else str(mesh)
    place = {"youngs_modulus": ("material", "youngs_modulus"), "poisson_ratio": ("material", "poisson_ratio"),
             "density": ("material", "density"), "payload_mass": ("payload", "mass"),
             "contact_stiffness": ("contact", "stiffness"), "friction": ("contact", "friction"),
             "friction_coefficient": ("contact", "friction_coefficient")}
    for n, v in zip(names, values):
        if n == "cable_stiffness":
            ratio = float(v) / parameter_values(robot, [n])[0]
            for table, tendon in zip(doc["tendons"], robot.tendons):
                table["stiffness"] = float(tendon.stiffness * ratio)
            continue
        table, key = place[n]
        if table not in doc:
            doc[table] = tomlkit.table()
        doc[table][key] = float(v)
    if robot.contact.model != load_robot(source).contact.model:      # fitted under another law (--contact)
        if "contact" not in doc:
            doc["contact"] = tomlkit.table()
        doc["contact"]["model"] = robot.contact.model
    fitted = ", ".join(f"{n} = {float(v):.6g}" for n, v in zip(names, values))
    text = f"{HEADER} from {source} on {time.strftime('%Y-%m-%d %H:%M')}: {fitted}\n" + tomlkit.dumps(doc)
    atomic_write_bytes(target, text.encode())
    check = parameter_values(load_robot(target), names)
    if not np.allclose(check, values, rtol=1e-12, atol=0):
        raise RuntimeError(f"{target}: the written values {check} differ from the fitted ones {values}")
    return target


def tracks_figure(data: MarkerData, fit: CalibrationFit, *, tracks_file: str | Path | None = None):
    """The figure of :func:`plot_tracks`: measured samples (dots) and simulated tracks (lines) per
    coordinate, before (left) and after (right) the fit, in the measurements' frame. The title
    names the robot and the tracks file; the legend (one line per marker) sits right of the
    axes, so it never covers a track."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t_sim = data.dt * np.arange(len(data.u) + 1)
    fig, axes = plt.subplots(3, 2, figsize=(12, 8), sharex=True, sharey="row")
    colors = plt.get_cmap("tab10")
    for col, (pred, label, rms) in enumerate(((fit.predicted_before, "before", fit.rms_before_mm),
                                               (fit.predicted_after, "after", fit.rms_after_mm))):
        for c, axis in enumerate("xyz"):
            ax = axes[c, col]
            for i, name in enumerate(data.markers.names):
                sel = data.marker_index == i
                ax.plot(data.times[sel], 1e3 * data.values[sel, c], ".", ms=2, color=colors(i % 10))
                ax.plot(t_sim, 1e3 * pred[:, i, c], "-", lw=1, color=colors(i % 10), label=name if c == 0 else None)
            ax.set_ylabel(f"{axis} [mm]")
            ax.grid(alpha=0.3)
        axes[0, col].set_title(f"{label} the fit: RMS {rms:.2f} mm")
        axes[2, col].set_xlabel("t [s]")
    n_markers = len(data.markers.names)
    axes[0, 1].legend(fontsize=7, ncol=1 + (n_markers > 12), loc="upper left", bbox_to_anchor=(1.02, 1.0),
                      borderaxespad=0.0, title="marker", title_fontsize=7)
    source = f" from {Path(tracks_file).name}" if tracks_file is not None else ""
    fig.suptitle(f"{data.robot.name}: measured markers{source} (dots) and simulated tracks (lines)")
    fig.tight_layout()       # makes room for the legend right of the axes
    return fig


def plot_tracks(data: MarkerData, fit: CalibrationFit, path: Path, *, tracks_file: str | Path | None = None) -> Path:
    """:func:`tracks_figure` written atomically as PNG to ``path``."""
    return atomic_write_png(tracks_figure(data, fit, tracks_file=tracks_file), path, dpi=100)


