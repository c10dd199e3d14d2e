"""What the :class:`~soft_envs.sim.Simulator` checks of its inputs: controls, positions, states
and the energy terms' histories. Every check raises a ValueError that names the input, the
entry and the value, before anything is simulated, and never modifies what it is given."""
from __future__ import annotations

import numpy as np

from .state import State

__all__ = ["InputChecks", "initial_placement"]


def initial_placement(robot) -> np.ndarray:
    """The rest mesh (n, 3), lowered or raised to touch the ground (unless it has fixed nodes):
    where the rest relaxation starts."""
    x = np.array(robot.mesh.points)
    if robot.fixed_nodes.size == 0:
        if robot.ground is None:
            x[:, 1] -= x[:, 1].min()
        else:                                   # the lowest node above the field touches it
            x[:, 1] -= (x[:, 1] - robot.ground.height(x[:, 0], x[:, 2])).min()
    return x


class InputChecks:
    """The checks of one simulator's inputs (its ``robot``, energy ``system`` and ``control``
    mode: ``"length"`` or ``"tension"``)."""

    def __init__(self, robot, system, control: str):
        self.robot, self.system, self.control = robot, system, control
        self._history_layout: tuple | None = None

    @property
    def n_motors(self) -> int:
        return self.robot.n_motors

    @property
    def n_nodes(self) -> int:
        return self.robot.mesh.n_nodes

    def controls(self, u, K: int | None = None, check_bounds: bool = False) -> np.ndarray:
        """``u`` as a float64 copy: (n_motors,) when ``K`` is None, else (K, n_motors); finite,
        non-negative in tension control, and with ``check_bounds`` within the motors' ranges."""
        arr = np.array(u, dtype=np.float64)          # a copy: trajectories keep their own
        shape = (self.n_motors,) if K is None else None
        if K is None and arr.shape != shape:
            raise ValueError(f"controls u must have shape ({self.n_motors},), got {arr.shape}")
        if K is not None and (arr.ndim != 2 or arr.shape[1] != self.n_motors):
            raise ValueError(f"controls u must have shape (K, {self.n_motors}), got {arr.shape}")
        bad = ~np.isfinite(arr)
        if bad.any():
            raise ValueError(f"controls u contain NaN or inf at {np.argwhere(bad)[:5].tolist()}")
        if self.control == "tension" and (arr < 0).any():
            raise ValueError("tension controls must be >= 0 (cables can only pull)")
        if check_bounds and self.control == "length" and self.n_motors:
            self.bounds(arr.reshape(-1, self.n_motors))
        return arr

    def bounds(self, u: np.ndarray) -> None:
        """Contractions outside a motor's [u_min, u_max] are a ValueError naming the first one
        (a unit slip, mm for m, is the usual cause)."""
        lo, hi = self.robot.u_bounds[:, 0], self.robot.u_bounds[:, 1]
        slack = 1e-12 * np.maximum(hi - lo, 1.0)
        bad = (u < lo - slack) | (u > hi + slack)
        if bad.any():
            k, m = np.argwhere(bad)[0]
            raise ValueError(f"controls u[{k}, {m}] = {float(u[k, m])!r} m lie outside motor "
                             f"{self.robot.motors[m].name!r}'s range [{float(lo[m])!r}, {float(hi[m])!r}] m "
                             f"({int(bad.sum())} entries out of range; pass check_bounds=False "
                             "to simulate them anyway)")

    def positions(self, x, name: str) -> np.ndarray:
        """Node positions (n, 3), finite (a :class:`State` is refused: pass its ``.x``)."""
        if isinstance(x, State):
            raise ValueError(f"{name} must be an array of node positions, got a State (its positions are "
                             f"{name}.x; functions that start from a state, step and rollout, take the State)")
        arr = np.asarray(x, dtype=np.float64)
        if arr.shape != (self.n_nodes, 3):
            raise ValueError(f"{name} must have shape ({self.n_nodes}, 3), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"{name} contains NaN or inf")
        return arr

    def history(self, history, x: np.ndarray, name: str = "history") -> tuple:
        """``history`` as the energy terms' tuple (None: at rest at ``x``, the system's
        ``initial_history``), checked against the terms."""
        if history is None:
            return self.system.initial_history(x)
        expected = self._history_shapes()
        if not isinstance(history, (tuple, list)) or len(history) != len(expected):
            raise ValueError(f"{name} must be a tuple of {len(expected)} entries (one per energy term), "
                             f"got {type(history).__name__} of length {len(history) if hasattr(history, '__len__') else '?'}")
        for i, (h, e) in enumerate(zip(history, expected)):
            if (h is None) != (e is None):
                raise ValueError(f"{name}[{i}] must be {'None' if e is None else 'an array'} for this contact law")
            if h is not None and (np.shape(h) != e or not np.isfinite(h).all()):
                raise ValueError(f"{name}[{i}] must be a finite array of shape {e}, got shape {np.shape(h)}")
        return tuple(history)

    def _history_shapes(self) -> tuple:
        """The shape of each energy term's history (None for terms without one): fixed by the
        robot and its terms, so worked out once (a step's check of its State reads it)."""
        if self._history_layout is None:
            self._history_layout = tuple(None if h is None else h.shape
                                         for h in self.system.initial_history(initial_placement(self.robot)))
        return self._history_layout

    def state(self, state: State, name: str = "state") -> State:
        """A :class:`State` of this simulator (node count, finite positions, the terms' history,
        the controls' count)."""
        if not isinstance(state, State):
            raise ValueError(f"{name} must be a soft_envs.sim.State (e.g. sim.rest_state() or "
                             f"sim.state_at_rest(x)), got {type(state).__name__}")
        for field_name in ("x", "x_prev", "x_prev2"):
            a = getattr(state, field_name)
            if a is not None:
                self.positions(a, f"{name}.{field_name}")
        if state.u is not None and state.u.shape != (self.n_motors,):
            raise ValueError(f"{name}.u must have shape ({self.n_motors},), got {state.u.shape}")
        self.history(state.history, state.x, f"{name}.history")
        return state
