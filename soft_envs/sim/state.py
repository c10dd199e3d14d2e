r"""The simulation state: everything the next implicit-Euler step depends on, in one frozen object.

Paper eq. 4 solves ``g_{k+1} = f_{k+1} - m a_{k+1} = 0`` for ``x_{k+1}`` with the acceleration
``a_{k+1} = (x_{k+1} - 2 x_k + x_{k-1}) / h^2`` and the energy ``E(x_{k+1}; u_{k+1}, x_k)``
(lagged friction, paper II-C). A step therefore needs the two latest positions, and the Coulomb
law (:mod:`.coulomb`) also its stick anchors, updated after every step. :class:`State` holds
them; :func:`advance` is the one loop body that takes a state to the next (the simulator's
:meth:`~soft_envs.sim.Simulator.step` and rollouts, the rest-state relaxation, the environments'
step) and :func:`next_state` the bookkeeping part of it that the adjoint pass re-walks
(:func:`~.sensitivity.adjoint_pass`).

A state's arrays are read-only (numpy's ``writeable`` flag): arrays given writeable are copied,
read-only ones are kept as they are. States are built by :meth:`State.at_rest` (or
``Simulator.rest_state()`` / ``Simulator.state_at_rest(x)``, which add the anchors) and by
:func:`advance`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["State", "advance", "next_state"]


def _frozen(a, name: str) -> np.ndarray:
    """``a`` as a read-only float64 array (a copy unless it is one already)."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and not a.flags.writeable:
        return a
    try:
        out = np.array(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"State.{name} must be an array of numbers, got {type(a).__name__}") from None
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class State:
    """The state of a simulation after ``k`` steps (positions in metres, world frame, y up).

    Fields
    ------
    x : (n, 3) array
        ``x_k``, the node positions now [m] (the latest solution of paper eq. 4).
    x_prev : (n, 3) array
        ``x_{k-1}`` [m]. With ``x`` it gives the velocity: the next step's inertia term of eq.
        4 is ``M (x_{k+1} - 2 x_k + x_{k-1}) / h^2``, and the lagged friction of paper II-C
        measures displacements from ``x_k`` with the normal force at ``x_k``.
    x_prev2 : (n, 3) array or None
        ``x_{k-2}`` [m], or None. Only the Newton solver's initial guess uses it (constant
        acceleration); the next state is the same to within the Newton tolerance without it.
    history : tuple
        The energy terms' lagged state, aligned with ``EnergySystem.terms``: the Coulomb law's
        stick anchors (a (c, 2) array of anchor x, z [m] per contact node), None for terms that
        keep none (the paper's law keeps none: all entries None).
    k : int
        Control steps taken since the start (``x`` is ``x_k``; a rest state has ``k = 0``). With
        physics sub-steps (:mod:`.substeps`) the states inside a control step are not counted.
    u : (n_motors,) array or None
        The controls the state was reached with (the last step's; a rest state's: the
        controls it was relaxed under), or None when not known. Sub-steps join the next
        control step's controls to these by straight lines (:mod:`.substeps`); None there
        means the robot's rest controls.

    At rest (:meth:`at_rest`): ``x_prev = x_prev2 = x``. States compare by identity; compare
    fields with ``np.array_equal``."""

    x: np.ndarray
    x_prev: np.ndarray
    x_prev2: np.ndarray | None
    history: tuple
    k: int = 0
    u: np.ndarray | None = None

    def __post_init__(self):
        x = _frozen(self.x, "x")
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"State.x must have shape (n, 3), got {x.shape}")
        arrays = {"x": x, "x_prev": _frozen(self.x_prev, "x_prev"),
                  "x_prev2": None if self.x_prev2 is None else _frozen(self.x_prev2, "x_prev2")}
        for name, a in arrays.items():
            if a is not None and a.shape != x.shape:
                raise ValueError(f"State.{name} must have the shape of State.x {x.shape}, got {a.shape}")
        if not isinstance(self.history, (tuple, list)):
            raise ValueError(f"State.history must be a tuple (one entry per energy term, None for terms "
                             f"without history), got {type(self.history).__name__}")
        history = tuple(None if h is None else _frozen(h, f"history[{i}]") for i, h in enumerate(self.history))
        if isinstance(self.k, bool) or not isinstance(self.k, (int, np.integer)) or self.k < 0:
            raise ValueError(f"State.k must be an integer >= 0, got {self.k!r}")
        u = None if self.u is None else _frozen(self.u, "u")
        if u is not None and u.ndim != 1:
            raise ValueError(f"State.u must be a 1-D array of controls, got shape {u.shape}")
        for name, value in {**arrays, "history": history, "k": int(self.k), "u": u}.items():
            object.__setattr__(self, name, value)

    def __reduce__(self):
        """Pickle (and copy) through the constructor, so an unpickled state is read-only too."""
        return State, (self.x, self.x_prev, self.x_prev2, self.history, self.k, self.u)

    @classmethod
    def at_rest(cls, x, history: tuple, k: int = 0, u=None) -> "State":
        """The body standing still at ``x``: ``x_prev = x_prev2 = x``, with the terms'
        ``history`` (``Simulator.state_at_rest(x)`` supplies the anchors where it stands) and
        the controls ``u`` it stands under (None: not known)."""
        x = _frozen(x, "x")
        return cls(x, x, x, history, k, u)

    def advanced(self, x, history: tuple, u=None) -> "State":
        """The state one step later: positions ``x`` (``x_{k+1}``), the terms' ``history``
        after the step and the step's controls ``u``."""
        return State(x, self.x, self.x_prev, history, self.k + 1, u)

    def replace(self, **changes) -> "State":
        """A copy with some fields changed (``dataclasses.replace``)."""
        from dataclasses import replace
        return replace(self, **changes)


def next_state(system, state: State, x: np.ndarray, u=None) -> State:
    """The state after the step from ``state`` to positions ``x`` under controls ``u``: the
    terms' histories are updated (``system.next_history``, the Coulomb anchors' stick or slide)
    when ``system`` keeps any, else carried over. What a step does after solving eq. 4, and what
    the adjoint pass re-walks."""
    history = system.next_history(x, state.x, state.history) if system.has_history else state.history
    return state.advanced(x, history, u)


def advance(newton, state: State, u: np.ndarray, *, cache=None, need_exact: bool = False):
    """One implicit-Euler step (paper eq. 4) from ``state`` under controls ``u``: ``(next
    State, StepInfo)``. ``newton`` is the :class:`~soft_envs.sim.integrator.NewtonSolver` (its
    ``dt`` is the step), ``cache`` the :class:`~soft_envs.sim.linsolve.FactorCache` shared by
    consecutive steps (None: start afresh), ``need_exact`` asks for the exact Hessian's
    factorisation at the new state (sensitivities). ``state.x_prev2`` only improves the
    initial guess. Inputs are not validated here (the :class:`~soft_envs.sim.Simulator` does)."""
    x, info = newton.step(state.x, state.x_prev, u, state.k, need_exact=need_exact, x_prev3=state.x_prev2,
                          cache=cache, history=state.history)
    x.flags.writeable = False              # the solver's fresh array: the new state keeps it
    return next_state(newton.system, state, x, u), info
