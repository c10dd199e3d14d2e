r"""The gait objective as a residual vector with its Jacobian (for Gauss-Newton).

.. math::
    O(z) = \tfrac12 |r(z)|^2, \qquad r = [r_{com}; r_{heading}; r_{slack}; r_{mag}; r_{smooth}]

* COM tracking (paper eq. 5): ``r_com,k = sqrt(w_com / K) (c_k - c_hat_k) / BL`` for the
  horizontal COM ``c_k = (x, z)`` of states k = 1..K, in body lengths (BL).
* Heading tracking (the turn; off unless ``w_heading > 0`` and a target heading is given):
  ``r_heading,k = sqrt(w_heading / K) (yaw_k - yaw_hat_k)`` [rad] for the yaw of the body's
  best-fit rotation (:class:`~trajopt.optim.heading.HeadingMeasure`) at states k = 1..K, with its exact
  Jacobian through the rollout's ``dxdz``. COM tracking alone lets the body follow a curve
  partly sideways; this term asks it to face along the path.
* Slack eating (paper eq. 13, :func:`slack_eating_residual`): ``r_slack,k,t = sqrt(w_slack / (K T)) max(eps - Gamma_kt, 0) / range``:
  its square is the one-sided quadratic Q(eps - Gamma); it drives every cable to be at least
  slightly taut (eps, default 0.05 mm), removing the flat slack regions of the landscape.
  ``range`` is the mean contraction range of the motors.
* Magnitude and smoothness regularisers on the keyframes (small; normalised by each motor's
  range): ``sqrt(w_mag / nz) (z - u_min) / range`` and ``sqrt(w_smooth / nz) (z_{j+1} - z_j) / range``
  (periodic in j).

Jacobians use ``traj.dcomdz``, ``traj.dgammadz`` (and ``traj.dxdz`` for the heading) from the
simulator's sensitivity analysis.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .heading import HeadingMeasure
from ..tasks.registry import TASKS, TURN_HEADING_WEIGHT

__all__ = ["ObjectiveWeights", "HeadingTarget", "gait_residuals", "slack_eating_residual", "objective_stop",
           "TURN_HEADING_WEIGHT"]


@dataclass(frozen=True)
class ObjectiveWeights:
    """Weights of the objective's terms (each term is normalised by its size, see module doc)."""

    com: float = 1.0
    slack: float = 0.05
    slack_eps: float = 5e-5        # [m] the epsilon of eq. 13
    magnitude: float = 1e-3
    smoothness: float = 1e-3
    heading: float = 0.0           # [1/rad^2] heading tracking (the turn's default: TURN_HEADING_WEIGHT)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def for_task(cls, task: str) -> "ObjectiveWeights":
        """The default weights of ``task``: the ``weight_defaults`` of its :class:`~trajopt.tasks.Task` over
        these (the turn also tracks the heading)."""
        return cls(**TASKS[task].weight_defaults) if task in TASKS else cls()


@dataclass(frozen=True)
class HeadingTarget:
    """Target headings ``yaw`` (K+1,) [rad] and the ``measure`` of the body's heading."""

    measure: HeadingMeasure
    yaw: np.ndarray


def _heading_residual(traj, heading: HeadingTarget, s: float, need_jac: bool):
    if need_jac:
        if traj.dxdz is None:
            raise ValueError("the heading term needs the rollout's dxdz (rollout(..., store_dxdz=True))")
        yaw, dyaw = heading.measure.jacobian(traj.x, traj.dxdz)
        return s * (yaw[1:] - heading.yaw[1:]), s * dyaw[1:]
    return s * (heading.measure.yaws(traj.x)[1:] - heading.yaw[1:]), None


def slack_eating_residual(gamma: np.ndarray, dgammadz: np.ndarray | None, eps: float, scale: float):
    r"""The slack-eating regulariser (paper eq. 13) as residuals: ``(r, J)`` with
    ``r = scale max(eps - Gamma, 0)`` for every cable deformation ``gamma`` (K, T) [m], so that
    ``0.5 |r|^2 = scale^2 sum_k,t Q(eps - Gamma_kt)`` with the one-sided quadratic
    ``Q(s) = max(s, 0)^2 / 2``: it pulls every cable to be at least ``eps`` taut, removing the
    flat slack regions of the objective. ``J = -scale dGamma/dz`` on the active entries, from
    ``dgammadz`` (K, T, nz) (None: no Jacobian)."""
    active = gamma < eps
    r = (scale * np.where(active, eps - gamma, 0.0)).ravel()
    if dgammadz is None:
        return r, None
    return r, (-scale * np.where(active[:, :, None], dgammadz, 0.0)).reshape(r.size, dgammadz.shape[-1])


def gait_residuals(traj, target: np.ndarray, z: np.ndarray, param, body_length: float,
                   weights: ObjectiveWeights, need_jac: bool = True, heading: HeadingTarget | None = None):
    """``(r, J, terms)``: residual vector, its Jacobian (or None) and the objective's terms
    ``{name: 0.5 |r_name|^2}``; the heading term needs ``heading`` and ``weights.heading > 0``."""
    K = len(traj.x) - 1
    com = traj.com[1:, [0, 2]]
    s_com = np.sqrt(weights.com / K) / body_length
    r_com = (s_com * (com - target[1:])).ravel()
    use_heading = heading is not None and weights.heading > 0
    r_hd, J_hd = (_heading_residual(traj, heading, np.sqrt(weights.heading / K), need_jac) if use_heading
                  else (np.zeros(0), np.zeros((0, len(z)))))
    lo, hi = param.bounds()
    gam = traj.cable_deformation[1:]
    s_sl = np.sqrt(weights.slack / max(gam.size, 1)) / float(np.mean(hi - lo))
    r_sl, J_sl = slack_eating_residual(gam, traj.dgammadz[1:] if need_jac else None, weights.slack_eps, s_sl)
    nz = len(z)
    rng_z = hi - lo
    s_mag = np.sqrt(weights.magnitude / nz)
    r_mag = s_mag * (z - lo) / rng_z
    Kf = param.n_keyframes
    D = (np.roll(np.eye(Kf), 1, axis=1) - np.eye(Kf))          # z_{j+1} - z_j, periodic
    Dz = np.kron(np.eye(nz // Kf), D) / rng_z[None, :] if nz else np.zeros((0, 0))
    s_sm = np.sqrt(weights.smoothness / nz) if nz else 0.0
    r_sm = s_sm * (Dz @ z) if nz else np.zeros(0)
    r = np.concatenate([r_com, r_hd, r_sl, r_mag, r_sm])
    terms = {"com": 0.5 * float(r_com @ r_com), **({"heading": 0.5 * float(r_hd @ r_hd)} if use_heading else {}),
             "slack": 0.5 * float(r_sl @ r_sl),
             "magnitude": 0.5 * float(r_mag @ r_mag), "smoothness": 0.5 * float(r_sm @ r_sm)}
    if not need_jac:
        return r, None, terms
    J_com = (s_com * traj.dcomdz[1:, [0, 2], :]).reshape(-1, nz)
    J_mag = np.diag(s_mag / rng_z)
    J_sm = s_sm * Dz
    return r, np.vstack([J_com, J_hd, J_sl, J_mag, J_sm]), terms


def objective_stop(bound: float, target: np.ndarray, z: np.ndarray, param, body_length: float,
                   weights: ObjectiveWeights, n_steps: int, n_tendons: int):
    """A rollout's ``stop(k, com, gamma)`` (:meth:`soft_envs.envs.GradientEnv.rollout`) that ends
    it once the objective of :func:`gait_residuals` must exceed ``bound``: the keyframe terms
    (magnitude, smoothness) plus the COM and slack residuals of the states reached so far are a
    lower bound of ``O = 0.5 |r|^2`` (every term is a sum of squares; the heading term, left out,
    only adds), so a rollout stopped there has ``O > bound`` whatever follows. The sums are the
    same residuals as :func:`gait_residuals` (K = ``n_steps`` states, T = ``n_tendons``), and the
    bound is met with a relative margin of 1e-9 against the summation order."""
    lo, hi = param.bounds()
    nz = len(z)
    rng_z = hi - lo
    r_mag = np.sqrt(weights.magnitude / nz) * (z - lo) / rng_z if nz else np.zeros(0)
    Kf = param.n_keyframes
    D = (np.roll(np.eye(Kf), 1, axis=1) - np.eye(Kf))
    r_sm = (np.sqrt(weights.smoothness / nz) * (np.kron(np.eye(nz // Kf), D) / rng_z[None, :]) @ z) if nz else np.zeros(0)
    s_com = np.sqrt(weights.com / n_steps) / body_length
    s_sl = np.sqrt(weights.slack / max(n_steps * n_tendons, 1)) / float(np.mean(hi - lo))
    limit = bound + 1e-9 * abs(bound)
    total = [0.5 * float(r_mag @ r_mag + r_sm @ r_sm)]

    def stop(k: int, com: np.ndarray, gamma: np.ndarray) -> bool:
        d = s_com * (com[[0, 2]] - target[k])
        sl = s_sl * np.maximum(weights.slack_eps - gamma, 0.0)
        total[0] += 0.5 * float(d @ d + sl @ sl)
        return total[0] > limit

    return stop
