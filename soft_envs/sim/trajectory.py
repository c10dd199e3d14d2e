"""The result of a rollout: :class:`Trajectory` (states, centre of mass, cable deformations and,
when asked for, their sensitivities)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Trajectory"]


@dataclass
class Trajectory:
    """Result of :meth:`Simulator.rollout` (K steps, K+1 states; index 0 is the initial state).

    ``x`` (K+1, n, 3) positions; ``com`` (K+1, 3); ``cable_deformation`` (K+1, T) Gamma per
    tendon (entry 0 with the motors at ``robot.u_rest``); ``u`` (K, n_motors) the controls;
    ``newton_iterations`` (K,). With ``dudz``: ``dcomdz`` (K+1, 3, nz), ``dgammadz``
    (K+1, T, nz) (asked for without ``dudz``, they raise AttributeError saying so) and, when
    requested, ``dxdz`` (K+1, 3n, nz). With ``params`` (physical parameters or a design block):
    ``dxdtheta`` (K+1, 3n, ntheta), ``dcomdtheta`` (K+1, 3, ntheta) and ``dgammadtheta`` (K+1, T,
    ntheta), the parameters' names in ``info["parameters"]``."""

    x: np.ndarray
    com: np.ndarray
    cable_deformation: np.ndarray
    u: np.ndarray
    newton_iterations: np.ndarray
    dxdz: np.ndarray | None = None
    dxdtheta: np.ndarray | None = None
    dcomdtheta: np.ndarray | None = None
    dgammadtheta: np.ndarray | None = None
    info: dict = field(default_factory=dict)
    _dcomdz: np.ndarray | None = field(default=None, repr=False)
    _dgammadz: np.ndarray | None = field(default=None, repr=False)

    def _sensitivity(self, name: str) -> np.ndarray:
        value = getattr(self, "_" + name)
        if value is None:
            raise AttributeError(f"Trajectory.{name}: this rollout was run without dudz; pass "
                                 f"Simulator.rollout(u, dudz=...) with dudz (K, n_motors, nz) = du/dz of your "
                                 f"parameters z (e.g. dudz = np.eye(n_motors)[None].repeat(K, 0) for z = a "
                                 f"constant control per motor)")
        return value

    dcomdz = property(lambda self: self._sensitivity("dcomdz"),
                      lambda self, v: setattr(self, "_dcomdz", v), doc="(K+1, 3, nz) d COM / dz (needs dudz)")
    dgammadz = property(lambda self: self._sensitivity("dgammadz"),
                        lambda self, v: setattr(self, "_dgammadz", v), doc="(K+1, T, nz) d Gamma / dz (needs dudz)")
