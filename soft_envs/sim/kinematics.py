"""Rigid-body read-outs of a deformed body: best-fit rotation, heading, tilt."""
from __future__ import annotations

import numpy as np

__all__ = ["best_fit_rotation", "heading_deg", "tilt_deg"]


def best_fit_rotation(rest: np.ndarray, x: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Rotation R (3x3, det +1) minimising ``sum_i w_i |R (X_i - X_c) - (x_i - x_c)|^2`` (Kabsch),
    with mass-weighted centres. ``x`` may be (n, 3) or (..., n, 3)."""
    w = np.ones(rest.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    X = rest - w @ rest
    xs = np.asarray(x, dtype=np.float64)
    xc = xs - np.einsum("n,...ni->...i", w, xs)[..., None, :]
    Hm = np.einsum("n,...ni,nj->...ij", w, xc, X)                    # sum w x X^T
    U, _, Vt = np.linalg.svd(Hm)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones(U.shape[:-1])
    D[..., -1] = d
    return (U * D[..., None, :]) @ Vt


def heading_deg(R: np.ndarray) -> np.ndarray:
    """Heading of the body's forward axis (R e_x) in the ground plane, degrees from +x towards +z."""
    f = R[..., :, 0]
    return np.degrees(np.arctan2(f[..., 2], f[..., 0]))


def tilt_deg(R: np.ndarray) -> np.ndarray:
    """Angle between the body's up axis (R e_y) and +y, in degrees."""
    return np.degrees(np.arccos(np.clip(R[..., 1, 1], -1.0, 1.0)))
