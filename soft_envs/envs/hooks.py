"""The gradient hooks and the state of :class:`~soft_envs.envs.base.SoftRobotEnv` (a mixin).

What :class:`~soft_envs.envs.protocol.GradientEnv` asks of an environment besides its
properties: rollouts from the reset state with exact sensitivities (and parameter
sensitivities for calibration), the state as a dict (``get_state``/``set_state``, stick anchors
included), and measurements of the current or any state (COM, cable deformation and tension).
The mixin reads the environment's ``_sim`` (the :class:`~soft_envs.sim.Simulator`), the reset
state ``_reset_state`` and the current state ``_state`` (both :class:`~soft_envs.sim.State`:
positions, previous positions, stick anchors, steps since reset), ``_u``, ``_com``,
``_com_start`` and ``_domain``, and restores states through the environment's ``_set_domain``
and ``_restore``.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..sim import State, Trajectory

__all__ = ["GradientHooksMixin"]


class GradientHooksMixin:
    """Gradient hooks and state of a soft-robot environment (module docstring)."""

    def reset_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x_0, x_{-1})`` of the last reset (copies): where :meth:`rollout` starts."""
        return self._reset_state.x.copy(), self._reset_state.x_prev.copy()

    def rollout(self, u: np.ndarray, dudz: np.ndarray | None = None, *,
                store_dxdz: bool = False, stop=None) -> Trajectory:
        """Simulate contractions ``u`` (K, M) [m] from the reset state, with sensitivities when
        ``dudz`` (K, M, nz) is given (see :meth:`Simulator.rollout`; ``stop`` too). ``u`` is
        applied as given: no action clipping and no motor limits. The environment's state is not
        touched."""
        return self._sim.rollout(u, x0=self._reset_state, dudz=dudz, store_dxdz=store_dxdz, stop=stop)

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
        st = self._state
        return {"x": st.x.copy(), "x_prev": st.x_prev.copy(), "u": self._u.copy(),
                "sim_steps": st.k, "com_start": self._com_start.copy(), "domain": dict(self._domain),
                "x_prev2": None if st.x_prev2 is None else st.x_prev2.copy(),
                "history": [None if h is None else np.array(h) for h in st.history]}

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
        history = self._sim.check_history(state.get("history"), x, "state['history']")
        new = State(x, xp, xp2, history, int(state.get("sim_steps", self._state.k)), u)
        self._trail.clear()
        self._restore(new, u, state.get("com_start", self._com_start))

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
