"""The gradient hooks and the state of :class:`~soft_envs.envs.base.SoftRobotEnv` (a mixin).

What :class:`~soft_envs.envs.protocol.GradientEnv` asks of an environment besides its
properties: rollouts from the reset state with exact sensitivities (and parameter
sensitivities for calibration), the state as a dict (``get_state``/``set_state``, stick anchors
included), and measurements of the current or any state (COM, cable deformation and tension).
The mixin reads the environment's ``_sim`` (the :class:`~soft_envs.sim.Simulator`), the reset
state (``_x0_reset``, ``_xm1_reset``, ``_history_reset``) and the current state (``_x``,
``_x_prev``, ``_x_prev2``, ``_u``, ``_history``, ``_n_sub``, ``_com``, ``_com_start``,
``_domain``), and restores states through the environment's ``_set_domain`` and ``_restore``.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..sim import Trajectory

__all__ = ["GradientHooksMixin"]


class GradientHooksMixin:
    """Gradient hooks and state of a soft-robot environment (module docstring)."""

    def reset_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x_0, x_{-1})`` of the last reset (copies): where :meth:`rollout` starts."""
        return self._x0_reset.copy(), self._xm1_reset.copy()

    def rollout(self, u: np.ndarray, dudz: np.ndarray | None = None, *,
                store_dxdz: bool = False) -> Trajectory:
        """Simulate contractions ``u`` (K, M) [m] from the reset state, with sensitivities when
        ``dudz`` (K, M, nz) is given (see :meth:`Simulator.rollout`). ``u`` is applied as given:
        no action clipping and no motor speed limit. The environment's state is not touched."""
        return self._sim.rollout(u, x0=self._x0_reset, dudz=dudz, x_prev0=self._xm1_reset,
                                 store_dxdz=store_dxdz, history0=self._history_reset)

    def rollout_parameters(self, u: np.ndarray, parameters) -> Trajectory:
        """:meth:`rollout` from the rest state with sensitivities to physical ``parameters``
        (``traj.dxdtheta``; see :func:`soft_envs.envs.identification.parameter_rollout`)."""
        from .identification import parameter_rollout
        return parameter_rollout(self, u, parameters)

    def get_state(self) -> dict[str, Any]:
        """A copy of everything a step depends on: positions ``x`` and ``x_prev`` (n, 3),
        applied contractions ``u`` (M,), simulation steps since reset ``sim_steps``, the start
        COM ``com_start`` (3,) and the ``domain`` parameters; also ``x_prev2`` (n, 3) or None,
        the state before ``x_prev``, which only improves the solver's first guess (the next
        state is the same to within the Newton tolerance without it); and ``history``, the
        contact law's lagged state (the Coulomb law's stick anchors: a list with one (c, 2)
        array; None entries for terms without history)."""
        return {"x": self._x.copy(), "x_prev": self._x_prev.copy(), "u": self._u.copy(),
                "sim_steps": self._n_sub, "com_start": self._com_start.copy(), "domain": dict(self._domain),
                "x_prev2": None if self._x_prev2 is None else self._x_prev2.copy(),
                "history": [None if h is None else np.array(h) for h in self._history]}

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restore a state from :meth:`get_state` (``x`` required; ``x_prev`` defaults to ``x``,
        i.e. at rest, ``x_prev2`` to ``x`` at rest and to None otherwise, ``history`` to the
        stick anchors of a robot at rest at ``x``, other keys to their current values)."""
        if "domain" in state:
            self._set_domain(state["domain"])
        n = self._sim.n_nodes
        x = np.array(state["x"], dtype=np.float64)
        xp = np.array(state.get("x_prev", x), dtype=np.float64)
        xp2 = state.get("x_prev2", x if "x_prev" not in state else None)
        xp2 = None if xp2 is None else np.array(xp2, dtype=np.float64)
        u = np.array(state.get("u", self._u), dtype=np.float64)
        checks = [("x", x, (n, 3)), ("x_prev", xp, (n, 3)), ("u", u, self._u.shape)]
        if xp2 is not None:
            checks.append(("x_prev2", xp2, (n, 3)))
        for name, v, shape in checks:
            if v.shape != shape or not np.isfinite(v).all():
                raise ValueError(f"state[{name!r}] must be a finite array of shape {shape}, got {v.shape}")
        history = self._check_history(state.get("history"), x)
        self._trail.clear()
        self._restore(x, xp, u, int(state.get("sim_steps", self._n_sub)),
                      state.get("com_start", self._com_start), xp2, history)

    def _check_history(self, history, x: np.ndarray) -> tuple:
        """A state's ``history`` as the simulator's tuple (default: at rest at x)."""
        expected = self._sim.initial_history(x)
        if history is None:
            return expected
        if len(history) != len(expected):
            raise ValueError(f"state['history'] must have {len(expected)} entries, got {len(history)}")
        out = []
        for i, (h, e) in enumerate(zip(history, expected)):
            if e is None or h is None:
                if (e is None) != (h is None):
                    raise ValueError(f"state['history'][{i}] must be {'None' if e is None else 'an array'}")
                out.append(None)
                continue
            h = np.array(h, dtype=np.float64)
            if h.shape != e.shape or not np.isfinite(h).all():
                raise ValueError(f"state['history'][{i}] must be a finite array of shape {e.shape}, got {h.shape}")
            out.append(h)
        return tuple(out)

    def com(self) -> np.ndarray:
        """Current centre of mass (3,) [m]."""
        return self._com.copy()

    def cable_deformation(self, x: np.ndarray | None = None, u: np.ndarray | None = None) -> np.ndarray:
        """Cable deformation Gamma (T,) [m] per tendon (> 0: stretched, < 0: slack; paper eq. 3)
        at positions ``x`` (n, 3) with controls ``u`` (M,), by default the current ones."""
        return self._sim.cable_deformation(self._x if x is None else x, self._u if u is None else u)

    def cable_tension(self, x: np.ndarray | None = None, u: np.ndarray | None = None) -> np.ndarray:
        """Cable tension (T,) [N] per tendon (0 when slack) at positions ``x`` (n, 3) with
        controls ``u`` (M,), by default the current ones."""
        return self._sim.cable_tension(self._x if x is None else x, self._u if u is None else u)
