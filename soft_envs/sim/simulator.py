"""Simulator: implicit-Euler rollouts of a :class:`Robot`, with exact sensitivities.

>>> robot = load_robot("puppy")
>>> sim = Simulator(robot)                      # dt = DEFAULT_DT, the paper's h = 0.033 s
>>> rest = sim.rest_state()                     # a State: positions, velocity 0, stick anchors
>>> traj = sim.rollout(np.zeros((168, robot.n_motors)), x0=rest)   # the same as x0=None
>>> state = sim.step(rest, np.zeros(robot.n_motors))               # one step: the next State
>>> fine = Simulator(robot, substeps=4)         # 4 physics steps of 8.25 ms per control step

Physics lives in :mod:`.system` (energies), :mod:`.integrator` (Newton per step) and
:mod:`.sensitivity` (derivatives of whole rollouts); what a step carries to the next is a
:class:`~.state.State`, advanced by :func:`~.state.advance` (the one loop body of steps,
rollouts, the rest-state relaxation, the environments and the adjoint); control steps and
rollouts with their sub-steps are :mod:`.rollout`, the inputs' checks :mod:`.inputs`, the rest
states :mod:`.rest`. This module only strings them together.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from .inputs import InputChecks, initial_placement
from .integrator import FactorCache, NewtonOptions, NewtonSolver
from .parameter_block import ParameterBlock
from .rest import RestStates
from .rollout import control_step, forward_sensitivities, run_rollout
from .robot import Robot
from .sensitivity import adjoint_pass
from .state import State, advance
from .substeps import check_substeps, control_step_gradient, newton_tolerance
from .system import EnergySystem
from .timing import DEFAULT_DT
from .trajectory import Trajectory

__all__ = ["Simulator", "Trajectory"]


class Simulator:
    """Implicit-Euler simulation of one robot.

    Parameters
    ----------
    robot : Robot
    dt : the control step h [s] (default :data:`~soft_envs.sim.timing.DEFAULT_DT`, the paper's
        0.033 s): one row of a control trajectory, one :meth:`step`. Fixed for the simulator's
        life.
    substeps : physics steps per control step (default 1, the paper's integration): the Newton
        solver steps ``dt / substeps`` (:attr:`physics_dt`, its one home at run time) and the
        controls are joined by straight lines inside a control step (:mod:`.substeps`).
    gravity : gravity vector [m/s^2]; rotate it for an incline (:func:`incline_gravity`).
    control : ``"length"`` (u = contracted cable length [m]) or ``"tension"`` (u = tension [N]).
    newton : :class:`NewtonOptions` (tolerance, iterations, linear solver); default
        ``NewtonOptions()``, with a sub-stepped simulator's tolerance
        (:func:`~.substeps.newton_tolerance`: 1e-6 m per physics step).
    """

    def __init__(self, robot: Robot, dt: float = DEFAULT_DT, gravity=(0.0, -9.81, 0.0),
                 control: str = "length", newton: NewtonOptions | None = None, substeps: int = 1):
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be positive, got {dt!r}")
        self.robot = robot
        self._dt = float(dt)
        self.substeps = check_substeps(substeps)
        self.system = EnergySystem(robot, gravity=gravity, control=control)
        self.newton = NewtonSolver(self.system, self._dt if self.substeps == 1 else self._dt / self.substeps,
                                   newton or NewtonOptions(tol=newton_tolerance(self.substeps)))
        self.gravity = self.system.gravity
        self.control = control
        self.inputs = InputChecks(robot, self.system, control)
        self._rest = RestStates(self)

    @property
    def dt(self) -> float:
        """The control step h [s]: one row of a control trajectory, one :meth:`step`."""
        return self._dt

    @property
    def physics_dt(self) -> float:
        """The physics step [s], ``dt / substeps`` (the Newton solver's, which builds ``M / h^2``
        from it)."""
        return self.newton.dt

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict:
        """Pickle only what defines the simulator (the CHOLMOD objects do not pickle): robot,
        time step, sub-steps, gravity, control mode, Newton options and the rest-state cache.
        The energy system and the solver are rebuilt on unpickling (with no factorisation held,
        exactly like a freshly constructed simulator)."""
        return {"robot": self.robot, "dt": self.dt, "substeps": self.substeps, "gravity": np.array(self.gravity),
                "control": self.control, "newton": self.newton.options, "rest_cache": dict(self._rest.states)}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["robot"], dt=state["dt"], gravity=state["gravity"], control=state["control"],
                      newton=state["newton"], substeps=state.get("substeps", 1))
        self._rest.states.update({k: v if isinstance(v, State) else State.at_rest(*v)     # (x, history): older pickles
                                  for k, v in state["rest_cache"].items()})

    @property
    def n_motors(self) -> int:
        return self.robot.n_motors

    @property
    def n_nodes(self) -> int:
        return self.robot.mesh.n_nodes

    # ------------------------------------------------------------------ validation (:mod:`.inputs`)
    def _check_u(self, u, K: int | None = None, check_bounds: bool = False) -> np.ndarray:
        return self.inputs.controls(u, K, check_bounds)

    def _check_x(self, x, name: str) -> np.ndarray:
        return self.inputs.positions(x, name)

    def check_history(self, history, x: np.ndarray, name: str = "history") -> tuple:
        """``history`` as the energy terms' tuple (None: at rest at ``x``, :meth:`initial_history`),
        checked against the terms (ValueError naming ``name`` and the entry otherwise)."""
        return self.inputs.history(history, x, name)

    def _check_state(self, state: State, name: str = "state") -> State:
        return self.inputs.state(state, name)

    # ------------------------------------------------------------------ states
    def initial_placement(self) -> np.ndarray:
        """Rest mesh, lowered/raised to touch the ground (unless it has fixed nodes)."""
        return initial_placement(self.robot)

    def state_at_rest(self, x, history: tuple | None = None) -> State:
        """The :class:`State` of the body standing still at positions ``x`` (n, 3): ``x_prev =
        x_prev2 = x``, ``k = 0``, and the terms' ``history`` (default :meth:`initial_history`:
        the stick anchors where the nodes stand, unloaded)."""
        x = self._check_x(x, "x")
        return State.at_rest(x, self.check_history(history, x, "history"))

    def rest_state(self, u=None, tol: float = 1e-9, max_iter: int = 200) -> State:
        """Static equilibrium under gravity with controls ``u`` (default 0), as a :class:`State`
        (positions ``.x``, ``x_prev = x_prev2 = x``, its stick anchors ``.history``, ``k = 0``,
        the controls ``.u``): the robot standing on the ground, or the static solution of a
        clamped body. It is where :meth:`rollout` starts by default, so ``rollout(u,
        x0=sim.rest_state())`` is ``rollout(u)``. :meth:`rest_positions` gives a writeable copy
        of the positions.

        Computed by relaxation, implicit steps of 1 s from rest (:mod:`.rest`), to a state
        where friction exerts no force, so a rollout started there stays still. With the
        paper's lagged (viscous-like) friction a robot on a slope creeps, so the rest state of
        an inclined simulator then uses only the normal component of gravity; the Coulomb law
        holds it under the full gravity, with loaded stick anchors that belong to the state.
        """
        return self._rest.state(u, tol, max_iter)

    def rest_positions(self, u=None, tol: float = 1e-9, max_iter: int = 200) -> np.ndarray:
        """The node positions (n, 3) of :meth:`rest_state` (a writeable copy). Starting a
        rollout from them (a bare array) re-anchors the nodes where they stand: pass the
        :meth:`rest_state` itself to start from the rest state."""
        return self._rest.state(u, tol, max_iter).x.copy()

    def rest_history(self, u=None, tol: float = 1e-9, max_iter: int = 200) -> tuple:
        """The energy terms' history (stick anchors) of :meth:`rest_state`, i.e.
        ``rest_state(...).history`` (all None when the contact law keeps none)."""
        return self._rest.state(u, tol, max_iter).history

    def rest_sensitivity(self, params, u=None, tol: float = 1e-9, max_iter: int = 200) -> tuple:
        """``(x0, history0, dx0/dtheta (3n, ntheta), dhistory0/dtheta)`` of :meth:`rest_state`
        for the physical parameters ``params`` (names of
        :data:`~soft_envs.sim.parameters.PARAMETERS`): the rest state is the end of the
        relaxation's implicit steps, differentiated through the same recurrence as rollouts
        (:class:`~.sensitivity.ForwardSensitivities`, each step starting at rest)."""
        return self._rest.sensitivity(self._parameters(params), u, tol, max_iter)

    def _parameters(self, params):
        """Names of physical parameters checked against this robot, or a
        :class:`~.parameter_block.ParameterBlock` (design parameters) checked by the block."""
        if isinstance(params, ParameterBlock):
            return params.check(self.system)
        return self.system.check_parameters(params)

    def step(self, state, *args, factor_cache: FactorCache | None = None, **kwargs):
        """One control step (paper eq. 4; with :attr:`substeps` > 1, that many implicit-Euler
        steps along the straight line from ``state.u`` to ``u``): ``step(state, u) -> State``,
        the state after the step from :class:`State` ``state`` under controls ``u`` (n_motors,)
        (positions ``x_{k+1}``, ``x_prev`` the positions one physics step before, the anchors
        updated, ``k + 1``, ``u``). The same loop body as :meth:`rollout`: K chained steps from a state give the rollout from it bit for bit
        when they share one ``factor_cache`` (a :class:`FactorCache`, which lets a step reuse
        the factorisation of the step before, as a rollout does); without it a step starts
        afresh and its result depends on its inputs only. Raises :class:`SimulationError` on
        failure; the inputs are never modified.

        Deprecated form (kept working, with a DeprecationWarning): ``step(x_prev, x_prev2, u,
        k=None, x_prev3=None, factor_cache=None, history=None) -> x`` (positions (n, 3)), the
        state given loose (``history`` default: at rest at ``x_prev``)."""
        if not isinstance(state, State):
            warnings.warn("Simulator.step(x_prev, x_prev2, u, ...) is deprecated: pass a State, "
                          "step(state, u) -> State (sim.rest_state(), sim.state_at_rest(x) or "
                          "State(x, x_prev, x_prev2, history, k)); see CHANGELOG.md",
                          DeprecationWarning, stacklevel=2)
            return self._step_positions(state, *args, factor_cache=factor_cache, **kwargs)
        if len(args) + len(kwargs) != 1 or set(kwargs) - {"u"}:
            raise TypeError("Simulator.step(state, u, *, factor_cache=None) takes the State and the controls u")
        u = args[0] if args else kwargs["u"]
        return control_step(self.newton, self._check_state(state), self._check_u(u), self.substeps, self.robot.u_rest,
                            cache=factor_cache)

    def _step_positions(self, x_prev, x_prev2, u, k: int | None = None, x_prev3=None,
                        factor_cache: FactorCache | None = None, history: tuple | None = None) -> np.ndarray:
        """The deprecated form of :meth:`step`: the state given loose, the new positions returned."""
        u = self._check_u(u)
        x_prev = self._check_x(x_prev, "x_prev")
        x3 = None if x_prev3 is None else self._check_x(x_prev3, "x_prev3")
        state = State(x_prev, self._check_x(x_prev2, "x_prev2"), x3, self.system.resolve_history(history, x_prev),
                      0 if k is None else k)
        return np.array(advance(self.newton, state, u, cache=factor_cache)[0].x)

    @property
    def has_history(self) -> bool:
        """Whether the energy keeps lagged state beyond x_prev (``contact.model = "coulomb"``:
        stick anchors); a :class:`State` then carries it in ``history``."""
        return self.system.has_history

    def initial_history(self, x0) -> tuple:
        """The energy terms' history of the robot at rest at ``x0`` (anchors where it stands)."""
        return self.system.initial_history(self._check_x(x0, "x0"))

    def next_history(self, x, x_prev, history: tuple) -> tuple:
        """The history after the step from ``x_prev`` to ``x`` that started with ``history``
        (what :meth:`step` does to ``State.history``)."""
        return self.system.next_history(self._check_x(x, "x"), self._check_x(x_prev, "x_prev"), history)

    # ------------------------------------------------------------------ rollouts
    def _start_state(self, x0, x_prev0, history0) -> State:
        """The :class:`State` a rollout starts from (:meth:`rollout`'s ``x0``, ``x_prev0``,
        ``history0``)."""
        if isinstance(x0, State):
            if x_prev0 is not None or history0 is not None:
                raise ValueError("x0 is a State, which carries its own x_prev and history: pass x_prev0 and "
                                 "history0 only with x0 as an array (or x0=state.replace(x_prev=..., history=...))")
            return self._check_state(x0, "x0")
        if x0 is None:
            rest = self.rest_state()
            if x_prev0 is None and history0 is None:
                return rest
            x0, history0 = rest.x, rest.history if history0 is None else history0
        x0 = self._check_x(x0, "x0")
        at_rest = x_prev0 is None
        xm1 = x0 if at_rest else self._check_x(x_prev0, "x_prev0")
        return State(x0, xm1, x0 if at_rest else None, self.check_history(history0, x0, "history0"))

    def rollout(self, u, x0=None, dudz=None, *, x_prev0=None, store_dxdz: bool = False,
                check_bounds: bool = True, history0: tuple | None = None, params=None,
                dx0dtheta: np.ndarray | None = None, dhistory0dtheta: tuple | None = None,
                keep_substeps: bool = False, stop=None) -> Trajectory:
        """Simulate controls ``u`` (K, n_motors) from the state ``x0``: K chained
        :meth:`step`\\ s sharing one factorisation cache (:func:`~.rollout.run_rollout`). The
        trajectory holds the ends of the control steps; ``keep_substeps`` also keeps the
        sub-steps' positions and controls in ``traj.info["substep_x"]``, ``["substep_u"]``.
        ``stop(k, com, gamma)`` (optional) sees every state's centre of mass and cable
        deformations as it is reached and may end the rollout there
        (:class:`~.rollout.RolloutStopped`: an objective that already knows its answer).

        ``x0`` is one of

        * None (default): :meth:`rest_state`, anchors included;
        * a :class:`State` (``sim.rest_state()``, a state of an earlier rollout,
          ``traj.info["state"]``, ...): started as it is (its ``x_prev``, ``x_prev2`` and
          ``history``); ``rollout(u, x0=sim.rest_state())`` is ``rollout(u)`` bit for bit;
        * an array (n, 3) of positions: the body at rest there (``x_{-1} = x_prev0``, default
          ``x0``), its anchors ``history0``, default where the nodes stand
          (:meth:`state_at_rest`). Unloaded anchors are not the rest state's, so for a Coulomb
          robot an array equal to the rest positions is not the rest state: pass the State.

        ``x_prev0`` and ``history0`` go with an array (or None) ``x0`` only.

        With ``dudz`` (K, n_motors, nz) the forward sensitivities of paper eqs. 10-11 are
        computed alongside (:class:`~.sensitivity.ForwardSensitivities`): ``dcomdz`` and
        ``dgammadz`` always, ``dxdz`` if ``store_dxdz``. In length control, contractions
        outside a motor's range raise a ValueError unless ``check_bounds=False`` (finite
        differences at a bound). The rollout owns the factorisation its steps reuse, so its
        result depends on its inputs only. ``traj.info["state"]`` is the :class:`State` at the
        end (continue with ``rollout(u2, x0=traj.info["state"])``), ``traj.info["history"]``
        its history, ``traj.info["start"]`` the State it started from.

        With ``params`` (names of physical parameters, :mod:`.parameters`, or a
        :class:`~.parameter_block.ParameterBlock` such as the design parameters of
        :mod:`soft_envs.sim.design`) the parameter block of the recurrence runs too: ``traj.dxdtheta`` (K+1, 3n, ntheta) and ``traj.dcomdtheta``
        (K+1, 3, ntheta). From the rest state (``x0=None``) the derivative of the rest state
        itself is included (:meth:`rest_sensitivity`); from a given ``x0`` pass its derivative
        ``dx0dtheta`` (default 0) and that of the history, ``dhistory0dtheta``.
        """
        u = self._check_u(u, K=len(np.asarray(u)), check_bounds=check_bounds)
        K = len(u)
        params = self._parameters(params) if params else ()
        if params and x0 is None:
            x_rest, rest_h, dx0dtheta, dhistory0dtheta = self.rest_sensitivity(params)
            start = self._start_state(x_rest, x_prev0, rest_h if history0 is None else history0)
        else:
            start = self._start_state(x0, x_prev0, history0)
        sens = forward_sensitivities(self.newton, self.robot.body_node_masses, dudz, K, self.n_motors, self.substeps,
                                     store_dxdz=store_dxdz, params=params, dx0dtheta=dx0dtheta,
                                     dhistory0dtheta=dhistory0dtheta, x0=start.x)
        traj = run_rollout(self.newton, self.robot, start, u, self.substeps, sens, want_z=dudz is not None,
                           keep_substeps=keep_substeps, stop=stop)
        if params:
            traj.info["parameters"] = params.names if isinstance(params, ParameterBlock) else params
        return traj

    def rollout_gradient(self, u, dobj_dx, x0=None, dudz=None, traj: Trajectory | None = None,
                         history0: tuple | None = None):
        """Adjoint gradient of a scalar objective ``O = sum_k o_k(x_k)`` of a rollout.

        ``dobj_dx`` (K+1, n, 3) holds ``do/dx_k`` (entry 0 ignored). Returns ``dO/du`` (K,
        n_motors), or ``dO/dz`` (nz,) when ``dudz`` is given. ``x0`` and ``history0`` as in
        :meth:`rollout`. Pass the ``traj`` of the same rollout to skip re-simulating it (with
        ``x0`` and ``history0`` None, the gradient is of the rollout ``traj`` came from; with
        sub-steps it must hold them, ``rollout(..., keep_substeps=True)``, else the rollout is
        simulated again). With sub-steps the adjoint runs over every physics step and its
        gradient is carried back to the control steps (:func:`~.substeps.control_step_gradient`)."""
        u = self._check_u(u, K=len(np.asarray(u)))
        n = self.substeps
        if traj is None or (n > 1 and "substep_x" not in traj.info):
            if traj is not None and x0 is None and history0 is None:
                x0 = traj.info.get("start")
            traj = self.rollout(u, x0=x0, check_bounds=False, history0=history0, keep_substeps=n > 1)
            x0 = history0 = None
        dobj_dx = np.asarray(dobj_dx, dtype=np.float64)
        if dobj_dx.shape != traj.x.shape:
            raise ValueError(f"dobj_dx must have shape {traj.x.shape}, got {dobj_dx.shape}")
        start = traj.info.get("start") if x0 is None and history0 is None else None
        start = self._start_state(x0, None, history0) if start is None else start
        if n == 1:
            dOdu = adjoint_pass(self.newton, traj.x, u, dobj_dx, start=start)
        else:                            # the objective sees the ends of the control steps only
            fine = np.zeros(traj.info["substep_x"].shape)
            fine[::n] = dobj_dx
            dOdu = control_step_gradient(adjoint_pass(self.newton, traj.info["substep_x"], traj.info["substep_u"],
                                                      fine, start=start), n)
        if dudz is None:
            return dOdu
        return np.einsum("km,kmz->z", dOdu, np.asarray(dudz, dtype=np.float64))

    # ------------------------------------------------------------------ energies (tests, FD)
    def energy(self, x, x_prev, u, history=None) -> float:
        """Potential energy E(x; u, x_prev): FEM + cables + contact/friction + gravity
        (``history``: see :meth:`step`)."""
        return self.system.energy(self._check_x(x, "x"), self._check_x(x_prev, "x_prev"), self._check_u(u),
                                  history)

    def gradient(self, x, x_prev, u, history=None) -> np.ndarray:
        """dE/dx as (n, 3) (rows of fixed nodes included)."""
        _, g, _ = self.system.assemble(self._check_x(x, "x"), self._check_x(x_prev, "x_prev"), self._check_u(u),
                                       history=history)
        return g.reshape(-1, 3)

    def hessian(self, x, x_prev, u, history=None) -> sp.csc_matrix:
        """d^2E/dx^2 as a symmetric (3n, 3n) sparse matrix; rows/columns of fixed dofs are zero."""
        _, _, h = self.system.assemble(self._check_x(x, "x"), self._check_x(x_prev, "x_prev"), self._check_u(u),
                                       history=history)
        Hf = self.system.pattern.full(h)
        P = sp.csr_matrix((np.ones(len(self.system.free)), (self.system.free, np.arange(len(self.system.free)))),
                          shape=(self.system.n_dof, len(self.system.free)))
        return (P @ Hf @ P.T).tocsc()

    def com(self, x) -> np.ndarray:
        return self.robot.com(np.asarray(x))

    def cable_deformation(self, x, u) -> np.ndarray:
        return self.system.cable_deformation(self._check_x(x, "x"), self._check_u(u))

    def cable_tension(self, x, u) -> np.ndarray:
        """Tension per tendon [N]: Q'(Gamma) in length control, u of its motor in tension control."""
        return self.system.cables.tension(self._check_x(x, "x"), self._check_u(u))
