"""ParaView export: one ``.vtu`` per time step through meshio plus a ``.pvd`` collection.

Point data: ``displacement`` (from the rest shape) and ``velocity`` (backward difference, zero
at the first step), plus any ``point_data`` given; cell data as given (e.g. the strain energy
density). Cables go to a second series (``<basename>_cables``) of line cells with their own
``.pvd``. Every file is written atomically.
"""
from __future__ import annotations

import io
from pathlib import Path
from typing import Mapping, Sequence
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from .files import atomic_output, atomic_write_bytes

__all__ = ["export_vtu_series"]


def _write_vtu(path: Path, mesh: meshio.Mesh) -> None:
    with atomic_output(path, sync=False) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")


def _pvd(entries: Sequence[tuple[float, str]]) -> bytes:
    buf = io.StringIO()
    buf.write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
              "  <Collection>\n")
    for t, name in entries:
        buf.write(f'    <DataSet timestep="{float(t)!r}" group="" part="0" file={quoteattr(name)}/>\n')
    buf.write("  </Collection>\n</VTKFile>\n")
    return buf.getvalue().encode()


def export_vtu_series(directory: str | Path, tets: np.ndarray, rest_points: np.ndarray, positions: np.ndarray,
                      dt: float, *, point_data: Mapping[str, np.ndarray] | None = None,
                      cell_data: Mapping[str, np.ndarray] | None = None,
                      cables: Sequence[np.ndarray] | None = None, basename: str = "robot") -> Path:
    """Write the series and return the path of the body's ``.pvd``.

    ``positions`` (T, n, 3); ``point_data[name]`` (T, n) or (T, n, k); ``cell_data[name]``
    (T, n_tets); ``cables``: one (T, p, 3) array per cable."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    X = np.asarray(positions, dtype=np.float64)
    tets = np.asarray(tets, dtype=np.int64)
    rest = np.asarray(rest_points, dtype=np.float64)
    if X.ndim != 3 or X.shape[2] != 3:
        raise ValueError(f"positions must have shape (T, n, 3), got {X.shape}")
    T, n, _ = X.shape
    if rest.shape != (n, 3):
        raise ValueError(f"rest_points must have shape ({n}, 3), got {rest.shape}")
    if tets.ndim != 2 or tets.shape[1] != 4 or tets.max() >= n:
        raise ValueError(f"tets must be (m, 4) indices below {n}, got shape {tets.shape}")
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    for name, arr in (point_data or {}).items():
        if np.shape(arr)[:2] != (T, n):
            raise ValueError(f"point_data[{name!r}] must start with shape ({T}, {n}), got {np.shape(arr)}")
    for name, arr in (cell_data or {}).items():
        if np.shape(arr) != (T, len(tets)):
            raise ValueError(f"cell_data[{name!r}] must have shape ({T}, {len(tets)}), got {np.shape(arr)}")
    for i, c in enumerate(cables or []):
        if np.ndim(c) != 3 or np.shape(c)[0] != T or np.shape(c)[2] != 3:
            raise ValueError(f"cables[{i}] must have shape ({T}, p, 3), got {np.shape(c)}")
    vel = np.zeros_like(X)
    vel[1:] = (X[1:] - X[:-1]) / dt
    body, lines = [], []
    for k in range(T):
        pd = {"displacement": X[k] - rest, "velocity": vel[k]}
        pd.update({name: np.asarray(arr)[k] for name, arr in (point_data or {}).items()})
        cd = {name: [np.asarray(arr)[k]] for name, arr in (cell_data or {}).items()}
        name = f"{basename}_{k:05d}.vtu"
        _write_vtu(out / name, meshio.Mesh(X[k], [("tetra", tets)], point_data=pd, cell_data=cd))
        body.append((k * dt, name))
        if cables:
            pts = np.concatenate([np.asarray(c)[k] for c in cables])
            offs = np.cumsum([0] + [np.shape(c)[1] for c in cables])
            segs = np.concatenate([np.stack([np.arange(a, b - 1), np.arange(a + 1, b)], axis=1)
                                   for a, b in zip(offs[:-1], offs[1:])])
            cable_id = np.concatenate([np.full(b - a - 1, i) for i, (a, b) in enumerate(zip(offs[:-1], offs[1:]))])
            cname = f"{basename}_cables_{k:05d}.vtu"
            _write_vtu(out / cname, meshio.Mesh(pts, [("line", segs)], cell_data={"cable": [cable_id]}))
            lines.append((k * dt, cname))
    pvd = out / f"{basename}.pvd"
    atomic_write_bytes(pvd, _pvd(body))
    if lines:
        atomic_write_bytes(out / f"{basename}_cables.pvd", _pvd(lines))
    return pvd
