r"""Physics sub-steps: ``n`` implicit-Euler steps of ``h / n`` inside every control step of ``h``.

A control trajectory has one row per control step of ``h`` seconds (the motor controllers', the
keyframes' and the environments' period, 0.033 s). The physics may take ``n`` smaller steps per
row: the controls are joined by straight lines in time, from the controls the state was
reached with (``u_{k-1}``; ``State.u``, the rest state's controls at the start) to ``u_k``,

.. math::
    u_{k,j} = (1 - w_j)\, u_{k-1} + w_j\, u_k, \qquad w_j = (j + 1) / n, \quad j = 0 .. n-1,

so the last sub-step of row k is at ``u_k`` and a motor that moves ``u_k - u_{k-1}`` in a control
step does so at a constant speed, as a motor driven towards its target at its speed does.
With ``n = 1`` nothing changes: ``u_{k,0} = u_k`` (the arrays are returned as given).

Everything here is linear in the controls, so derivatives follow the same maps:
:func:`substep_jacobian` carries ``du/dz`` to the sub-steps and :func:`control_step_gradient`
carries a gradient with respect to the sub-steps' controls back to the rows (the adjoint).
Why sub-steps, and how many: docs/fidelity.md.
"""
from __future__ import annotations

import numpy as np

__all__ = ["substep_weights", "substep_controls", "substep_jacobian", "control_step_gradient", "check_substeps",
           "newton_tolerance", "SUBSTEP_TOLERANCE"]

#: [m] the Newton tolerance of a physics step of a sub-stepped simulator (one step of 33 ms
#: keeps 1e-8, and with it every figure made before sub-steps). Implicit Euler's own error in
#: an 8.25 ms step is about h^2 |a|, 7e-5 m at 1 m/s^2: 1e-6 is 70 times below it. Measured
#: (docs/fidelity.md, "Cost"): the main job takes 0.71x the CPU time of 1e-7 (the value until
#: 2026-12-07; 1e-8 before it cost 13 % more again), and results made at 1e-7 replay at 1e-6
#: with speeds and headings within 0.012 % (Tripod and Puppy walks, slopes, turns, the fastest
#: gaits). Re-optimised, they move: a Gauss-Newton path moves with the tolerance.
SUBSTEP_TOLERANCE = 1e-6


def check_substeps(n) -> int:
    """``n`` as an int >= 1 (ValueError naming the value otherwise)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"substeps must be an integer >= 1 (physics steps per control step), got {n!r}")
    return int(n)


def newton_tolerance(n: int) -> float:
    """The default Newton tolerance [m] of a simulator with ``n`` physics steps per control step:
    ``NewtonOptions().tol`` (1e-8) for one, :data:`SUBSTEP_TOLERANCE` for more."""
    from .newton_options import NewtonOptions
    return NewtonOptions().tol if n == 1 else SUBSTEP_TOLERANCE


def substep_weights(n: int) -> np.ndarray:
    """(n,) the weights ``w_j = (j + 1) / n`` of ``u_k`` in sub-step j (module docstring)."""
    return np.arange(1, n + 1, dtype=np.float64) / n


def substep_controls(u: np.ndarray, u_start: np.ndarray, n: int) -> np.ndarray:
    """(K n, M) the controls of every sub-step of the rows ``u`` (K, M), starting from
    ``u_start`` (M,), the controls of the state the rows start from."""
    if n == 1:
        return u
    u = np.asarray(u, dtype=np.float64)
    before = np.vstack([np.asarray(u_start, dtype=np.float64)[None, :], u[:-1]])
    w = substep_weights(n)[None, :, None]
    return ((1.0 - w) * before[:, None, :] + w * u[:, None, :]).reshape(len(u) * n, u.shape[1])


def substep_jacobian(dudz: np.ndarray, n: int) -> np.ndarray:
    """(K n, M, nz) ``du/dz`` of the sub-steps from ``dudz`` (K, M, nz) of the rows (the start's
    controls do not depend on z)."""
    if n == 1:
        return dudz
    before = np.concatenate([np.zeros_like(dudz[:1]), dudz[:-1]])
    w = substep_weights(n)[None, :, None, None]
    return ((1.0 - w) * before[:, None] + w * dudz[:, None]).reshape(len(dudz) * n, *dudz.shape[1:])


def control_step_gradient(g: np.ndarray, n: int) -> np.ndarray:
    """(K, M) ``dO/du_k`` from ``g`` (K n, M) = ``dO/du`` of every sub-step's controls: the
    transpose of :func:`substep_controls` (row k enters its own sub-steps with ``w_j`` and the
    next row's with ``1 - w_j``)."""
    if n == 1:
        return g
    K = len(g) // n
    blocks = np.asarray(g).reshape(K, n, -1)
    w = substep_weights(n)[None, :, None]
    out = (w * blocks).sum(axis=1)
    out[:-1] += ((1.0 - w) * blocks[1:]).sum(axis=1)
    return out
