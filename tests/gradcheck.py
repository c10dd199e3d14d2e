"""Finite-difference checks of rollout derivatives: a test helper (was ``soft_envs.sim.gradcheck``;
copy it, or run tests/test_sensitivity.py, when adding an energy term).

Central differences of whole rollouts in random directions of the parameters z:

    (traj(z + h d) - traj(z - h d)) / 2h   vs   J d,

with u(z) = u0 + dudz . z (an affine parameterisation, so the check isolates the simulator's
derivatives). Newton must be converged far below the perturbation (use
``NewtonOptions(tol=1e-11)``); ``h`` is in the units of z, and ``h * |dudz d|`` should be about
1e-7 m of contraction (or 1e-4 N of tension): small enough for truncation error, large
enough against the Newton tolerance.
"""
from __future__ import annotations

import numpy as np

__all__ = ["rollout_jacobian_errors", "relative_error"]


def relative_error(a: np.ndarray, b: np.ndarray) -> float:
    """``|a - b| / |b|`` in the Frobenius norm (``|a - b|`` when b vanishes)."""
    nb = np.linalg.norm(b)
    return float(np.linalg.norm(a - b) / nb) if nb > 0 else float(np.linalg.norm(a - b))


def rollout_jacobian_errors(sim, u0: np.ndarray, dudz: np.ndarray, x0: np.ndarray | None = None,
                            n_dirs: int = 2, h: float = 1e-4, rng: np.random.Generator | None = None,
                            full_state: bool = True) -> dict[str, float]:
    """Largest relative error over ``n_dirs`` random unit directions of the rollout Jacobians
    ``dxdz`` (if ``full_state``), ``dcomdz`` and ``dgammadz`` against central differences."""
    rng = np.random.default_rng(0) if rng is None else rng
    x0 = sim.rest_state() if x0 is None else x0
    traj = sim.rollout(u0, x0=x0, dudz=dudz, store_dxdz=full_state)
    worst = {"dxdz": 0.0, "dcomdz": 0.0, "dgammadz": 0.0}
    K = len(u0)
    for _ in range(n_dirs):
        d = rng.normal(size=dudz.shape[2])
        d /= np.linalg.norm(d)
        du = dudz @ d
        tp = sim.rollout(u0 + h * du, x0=x0, check_bounds=False)     # may step across a bound
        tm = sim.rollout(u0 - h * du, x0=x0, check_bounds=False)
        if full_state:
            fd = (tp.x - tm.x).reshape(K + 1, -1) / (2 * h)
            worst["dxdz"] = max(worst["dxdz"], relative_error(traj.dxdz @ d, fd))
        worst["dcomdz"] = max(worst["dcomdz"], relative_error(traj.dcomdz @ d, (tp.com - tm.com) / (2 * h)))
        fdg = (tp.cable_deformation - tm.cable_deformation) / (2 * h)
        worst["dgammadz"] = max(worst["dgammadz"], relative_error(traj.dgammadz @ d, fdg))
    if not full_state:
        worst.pop("dxdz")
    return worst
