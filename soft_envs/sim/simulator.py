"""Simulator: implicit-Euler rollouts of a :class:`Robot`, with exact sensitivities.

>>> robot = load_robot("puppy")
>>> sim = Simulator(robot, dt=0.033)
>>> x0 = sim.rest_state()
>>> traj = sim.rollout(np.zeros((168, robot.n_motors)), x0=x0)

Physics lives in :mod:`.system` (energies), :mod:`.integrator` (Newton per step) and
:mod:`.sensitivity` (derivatives of whole rollouts); this module only strings them together.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .parameter_block import ParameterBlock, parameter_block
from .integrator import FactorCache, NewtonOptions, NewtonSolver, SimulationError
from .robot import Robot
from .sensitivity import ForwardSensitivities, adjoint_pass
from .system import EnergySystem

__all__ = ["Simulator", "Trajectory"]


@dataclass
class Trajectory:
    """Result of :meth:`Simulator.rollout` (K steps, K+1 states; index 0 is the initial state).

    ``x`` (K+1, n, 3) positions; ``com`` (K+1, 3); ``cable_deformation`` (K+1, T) Gamma per
    tendon (entry 0 with the motors at ``robot.u_rest``); ``u`` (K, n_motors) the controls;
    ``newton_iterations`` (K,). With ``dudz``: ``dcomdz`` (K+1, 3, nz), ``dgammadz``
    (K+1, T, nz) (asked for without ``dudz``, they raise AttributeError saying so) and, when
    requested, ``dxdz`` (K+1, 3n, nz). With physical ``params``:
    ``dxdtheta`` (K+1, 3n, ntheta) and ``dcomdtheta`` (K+1, 3, ntheta), the parameters' names in
    ``info["parameters"]``."""

    x: np.ndarray
    com: np.ndarray
    cable_deformation: np.ndarray
    u: np.ndarray
    newton_iterations: np.ndarray
    dxdz: np.ndarray | None = None
    dxdtheta: np.ndarray | None = None
    dcomdtheta: np.ndarray | None = None
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


class Simulator:
    """Implicit-Euler simulation of one robot.

    Parameters
    ----------
    robot : Robot
    dt : time step h [s] (paper: 0.033).
    gravity : gravity vector [m/s^2]; rotate it for an incline (:func:`incline_gravity`).
    control : ``"length"`` (u = contracted cable length [m]) or ``"tension"`` (u = tension [N]).
    newton : :class:`NewtonOptions` (tolerance, iterations, linear solver).
    """

    def __init__(self, robot: Robot, dt: float = 0.033, gravity=(0.0, -9.81, 0.0),
                 control: str = "length", newton: NewtonOptions | None = None):
        self.robot = robot
        self.system = EnergySystem(robot, gravity=gravity, control=control)
        self.newton = NewtonSolver(self.system, dt, newton or NewtonOptions())
        self.dt = float(dt)
        self.gravity = self.system.gravity
        self.control = control
        self._rest_cache: dict = {}
        self._rest_sens_cache: dict = {}

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict:
        """Pickle only what defines the simulator (the CHOLMOD objects do not pickle): robot,
        time step, gravity, control mode, Newton options and the rest-state cache. The energy
        system and the solver are rebuilt on unpickling (with no factorisation held, exactly
        like a freshly constructed simulator)."""
        return {"robot": self.robot, "dt": self.dt, "gravity": np.array(self.gravity),
                "control": self.control, "newton": self.newton.options,
                "rest_cache": dict(self._rest_cache)}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["robot"], dt=state["dt"], gravity=state["gravity"],
                      control=state["control"], newton=state["newton"])
        self._rest_cache.update(state["rest_cache"])

    @property
    def n_motors(self) -> int:
        return self.robot.n_motors

    @property
    def n_nodes(self) -> int:
        return self.robot.mesh.n_nodes

    # ------------------------------------------------------------------ validation
    def _check_u(self, u, K: int | None = None, check_bounds: bool = False) -> np.ndarray:
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
            self._check_bounds(arr.reshape(-1, self.n_motors))
        return arr

    def _check_bounds(self, u: np.ndarray) -> None:
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

    def _check_x(self, x, name: str) -> np.ndarray:
        arr = np.asarray(x, dtype=np.float64)
        if arr.shape != (self.n_nodes, 3):
            raise ValueError(f"{name} must have shape ({self.n_nodes}, 3), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"{name} contains NaN or inf")
        return arr

    # ------------------------------------------------------------------ states
    def initial_placement(self) -> np.ndarray:
        """Rest mesh, lowered/raised to touch the ground (unless it has fixed nodes)."""
        x = np.array(self.robot.mesh.points)
        if self.robot.fixed_nodes.size == 0:
            x[:, 1] -= x[:, 1].min()
        return x

    def rest_state(self, u=None, tol: float = 1e-9, max_iter: int = 200) -> np.ndarray:
        """Static equilibrium under gravity with controls ``u`` (default 0): the robot standing
        on the ground, or the static solution of a clamped body.

        Computed as proximal-point iterations ``x_{j+1} = argmin E(x; x_prev = x_j) +
        |x - x_j|^2_M / 2`` (implicit steps of 1 s from rest), which converge to a state where
        the friction term exerts no force, so a rollout started there stays still. With the
        paper's lagged (viscous-like) friction a robot on a slope creeps, so the rest state of
        an inclined simulator then uses only the normal component of gravity. The Coulomb law
        holds it: its rest state is under the full gravity, with the stick anchors carried
        through the iterations (:meth:`rest_history` gives them, and rollouts from the rest
        state start with them).
        """
        return self._rest(u, tol, max_iter)[0].copy()

    def rest_history(self, u=None, tol: float = 1e-9, max_iter: int = 200) -> tuple:
        """The energy terms' history (stick anchors) of :meth:`rest_state` (all None when the
        contact law keeps none)."""
        return self._rest(u, tol, max_iter)[1]

    def rest_sensitivity(self, params, u=None, tol: float = 1e-9, max_iter: int = 200) -> tuple:
        """``(x0, history0, dx0/dtheta (3n, ntheta), dhistory0/dtheta)`` of :meth:`rest_state`
        for the physical parameters ``params`` (names of
        :data:`~soft_envs.sim.parameters.PARAMETERS`): the rest state is the end of the
        relaxation's implicit steps, differentiated through the same recurrence as rollouts
        (:class:`~.sensitivity.ForwardSensitivities`, each step starting at rest)."""
        params = self._parameters(params)
        u = np.zeros(self.n_motors) if u is None else self._check_u(u)
        key = (tuple(u.tolist()), tol, params)
        if key not in self._rest_sens_cache:
            self._rest_sens_cache[key] = self._relax(u, tol, max_iter, params)
        return self._rest_sens_cache[key]

    def _parameters(self, params):
        """Names of physical parameters checked against this robot, or a
        :class:`~.parameter_block.ParameterBlock` (design parameters) checked by the block."""
        if isinstance(params, ParameterBlock):
            return params.check(self.system)
        return self.system.check_parameters(params)

    def _rest(self, u, tol: float, max_iter: int) -> tuple[np.ndarray, tuple]:
        u = np.zeros(self.n_motors) if u is None else self._check_u(u)
        key = (tuple(u.tolist()), tol)
        if key not in self._rest_cache:
            self._rest_cache[key] = self._relax(u, tol, max_iter)[:2]
        return self._rest_cache[key]

    def _relax(self, u, tol: float, max_iter: int, params=()) -> tuple:
        """The relaxation of :meth:`rest_state`: ``(x, history)``, and with ``params`` their
        derivatives."""
        g = self.gravity
        anchored = self.system.has_history
        relax_g = g if (anchored or self.robot.fixed_nodes.size) else np.array([0.0, g[1], 0.0])
        system = EnergySystem(self.robot, gravity=relax_g, control=self.control)
        relax = NewtonSolver(system, 1.0, NewtonOptions(tol=min(tol, 1e-10), max_iter=100,
                                                        solver=self.newton.options.solver))
        x = self.initial_placement()
        history = system.initial_history(x)
        sens = exact = None
        if params:      # its own solver for the exact Hessians: the relaxation's path stays that of rest_state
            exact = NewtonSolver(system, 1.0, relax.options)
            dx0, dh0 = self._placement_sensitivity(system, params)
            sens = ForwardSensitivities(exact, self.robot.node_masses, np.zeros((max_iter, self.n_motors, 0)),
                                        params=params, x0=x, dx0dtheta=dx0, dhistory0dtheta=dh0)
        cache = FactorCache()
        for j in range(max_iter):
            try:
                xn, _ = relax.step(x, x, u, cache=cache, history=history)
                if sens is not None:
                    sens.hold()
                    sens.step(j, exact.factorize_exact_at(xn, x, x, u, history=history), xn, x, u, history,
                              x_prev2=x)
            except SimulationError as err:
                raise SimulationError(f"rest_state of robot {self.robot.name!r} failed (u = {u.tolist()}, "
                                      f"gravity = {relax_g.tolist()}): {err.reason}") from err
            if anchored:
                history = system.next_history(xn, x, history)
            moved = np.abs(xn - x).max()
            x = xn
            if moved <= tol:
                break
        else:
            hint = "; friction may not hold it on this slope (it slides)" if anchored and relax_g[[0, 2]].any() else ""
            raise SimulationError(f"rest_state of robot {self.robot.name!r} did not settle in {max_iter} "
                                  f"relaxation steps (last motion {moved:.2e} m; u = {u.tolist()}, "
                                  f"gravity = {relax_g.tolist()}, tol = {tol}){hint}")
        for a in (x, *[h for h in history if h is not None]):
            a.setflags(write=False)
        if sens is None:
            return x, history
        dh = tuple(None if p is None else p[:, sens.nz:].copy() for p in (sens.P or (None,) * len(history)))
        return x, history, sens.S1[:, sens.nz:].copy(), dh

    def _placement_sensitivity(self, system, params) -> tuple:
        """``(d initial_placement/dtheta (3n, nt), d initial_history/dtheta)`` for parameters
        that move the rest mesh (a :class:`~.parameter_block.ParameterBlock` with a
        ``rest_position_jacobian``; ``(None, None)`` otherwise). The placement's shift to the
        ground follows the lowest node; the initial histories (anchors at the nodes) are linear
        in the positions."""
        dX = parameter_block(params).rest_position_jacobian(self.robot)
        if dX is None:
            return None, None
        dX = np.array(dX, dtype=np.float64)
        if self.robot.fixed_nodes.size == 0:
            dX[:, 1, :] -= dX[int(np.argmin(self.robot.mesh.points[:, 1])), 1, :]
        cols = [system.initial_history(dX[:, :, j]) for j in range(dX.shape[2])]
        dh = tuple(None if h is None else np.stack([c[i].ravel() for c in cols], axis=1)
                   for i, h in enumerate(cols[0])) if cols else None
        return dX.reshape(-1, dX.shape[2]), dh

    def step(self, x_prev, x_prev2, u, k: int | None = None, x_prev3=None,
             factor_cache: FactorCache | None = None, history: tuple | None = None) -> np.ndarray:
        """One implicit-Euler step: ``x_k`` from ``x_{k-1}``, ``x_{k-2}`` and ``u_k``. ``x_{k-3}``
        (optional) gives the Newton solver a better initial guess; the result is the same to
        within the Newton tolerance. ``factor_cache`` (a :class:`FactorCache` shared by
        consecutive steps) lets a step reuse the factorisation of the step before; without
        it the step starts afresh and its result depends on its inputs only. ``history`` is
        the energy terms' lagged state (the Coulomb law's stick anchors): pass what
        :meth:`next_history` returned after the previous step (default: at rest at
        ``x_prev``, i.e. :meth:`initial_history`). Raises :class:`SimulationError` on failure;
        the inputs are never modified."""
        u = self._check_u(u)
        x3 = None if x_prev3 is None else self._check_x(x_prev3, "x_prev3")
        x, _ = self.newton.step(self._check_x(x_prev, "x_prev"), self._check_x(x_prev2, "x_prev2"), u, k,
                                x_prev3=x3, cache=factor_cache, history=history)
        return x

    @property
    def has_history(self) -> bool:
        """Whether the energy keeps lagged state beyond x_prev (``contact.model = "coulomb"``:
        stick anchors); steps then take a ``history``."""
        return self.system.has_history

    def initial_history(self, x0) -> tuple:
        """The energy terms' history of the robot at rest at ``x0`` (anchors where it stands)."""
        return self.system.initial_history(self._check_x(x0, "x0"))

    def next_history(self, x, x_prev, history: tuple) -> tuple:
        """The history after the step from ``x_prev`` to ``x`` that started with ``history``."""
        return self.system.next_history(self._check_x(x, "x"), self._check_x(x_prev, "x_prev"), history)

    # ------------------------------------------------------------------ rollouts
    def rollout(self, u, x0=None, dudz=None, *, x_prev0=None, store_dxdz: bool = False,
                check_bounds: bool = True, history0: tuple | None = None, params=None,
                dx0dtheta: np.ndarray | None = None, dhistory0dtheta: tuple | None = None) -> Trajectory:
        """Simulate controls ``u`` (K, n_motors) from ``x0`` (default :meth:`rest_state`) with
        zero initial velocity (or ``x_{-1} = x_prev0``).

        With ``dudz`` (K, n_motors, nz) the forward sensitivities of paper eqs. 10-11 are
        computed alongside (:class:`~.sensitivity.ForwardSensitivities`): ``dcomdz`` and
        ``dgammadz`` always, ``dxdz`` if ``store_dxdz``. In length control, contractions
        outside a motor's range raise a ValueError unless ``check_bounds=False`` (finite
        differences at a bound). The rollout owns the factorisation its steps reuse, so its
        result depends on its inputs only. ``history0``: the energy terms' history at the start
        (default: at rest at ``x0``); ``traj.info["history"]`` is the history at the end.

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
            x0, rest_h, dx0dtheta, dhistory0dtheta = self.rest_sensitivity(params)
            history0 = rest_h if history0 is None else history0
        elif x0 is None:
            x0 = self.rest_state()
            history0 = self.rest_history() if history0 is None else history0
        x0 = self._check_x(x0, "x0")
        xm1 = x0 if x_prev0 is None else self._check_x(x_prev0, "x_prev0")
        sens = None
        if dudz is not None:
            dudz = np.asarray(dudz, dtype=np.float64)
            if dudz.ndim != 3 or dudz.shape[:2] != (K, self.n_motors):
                raise ValueError(f"dudz must have shape ({K}, {self.n_motors}, nz), got {dudz.shape}")
            if not np.isfinite(dudz).all():
                raise ValueError(f"dudz contains NaN or inf at {np.argwhere(~np.isfinite(dudz))[:5].tolist()}")
        want_z = dudz is not None
        if want_z or params:
            dudz = np.zeros((K, self.n_motors, 0)) if dudz is None else dudz
            sens = ForwardSensitivities(self.newton, self.robot.node_masses, dudz, store_dxdz, params=params,
                                        dx0dtheta=dx0dtheta, dhistory0dtheta=dhistory0dtheta, x0=x0)
        cables = self.system.cables
        xs = np.empty((K + 1, self.n_nodes, 3))
        xs[0] = x0
        gam = np.empty((K + 1, cables.n_tendons))
        gam[0] = cables.deformation(x0, self.robot.u_rest)      # before the first control
        iters = np.zeros(K, dtype=np.int64)
        cache = FactorCache()
        history = self.system.resolve_history(history0, x0)
        prev, prev2 = x0, xm1
        prev3 = x0 if x_prev0 is None else None      # at rest: x_{-2} = x_{-1} = x_0
        for k in range(K):
            x, info = self.newton.step(prev, prev2, u[k], k, need_exact=sens is not None, x_prev3=prev3,
                                       cache=cache, history=history)
            xs[k + 1] = x
            iters[k] = info.iterations
            gam[k + 1] = cables.deformation(x, u[k])
            if sens is not None:
                sens.step(k, info.solver, x, prev, u[k], history, x_prev2=prev2)
            if self.system.has_history:
                history = self.system.next_history(x, prev, history)
            prev3, prev2, prev = prev2, prev, x
        masses = self.robot.node_masses
        com = np.einsum("kni,n->ki", xs, masses) / masses.sum()
        traj = Trajectory(x=xs, com=com, cable_deformation=gam, u=u, newton_iterations=iters,
                          info={"history": history})
        if want_z:
            traj.dcomdz, traj.dgammadz, traj.dxdz = sens.dcomdz, sens.dgammadz, sens.dxdz
        if params:
            traj.dxdtheta, traj.dcomdtheta = sens.dxdtheta, sens.dcomdtheta
            traj.info["parameters"] = params.names if isinstance(params, ParameterBlock) else params
        return traj

    def rollout_gradient(self, u, dobj_dx, x0=None, dudz=None, traj: Trajectory | None = None,
                         history0: tuple | None = None):
        """Adjoint gradient of a scalar objective ``O = sum_k o_k(x_k)`` of a rollout.

        ``dobj_dx`` (K+1, n, 3) holds ``do/dx_k`` (entry 0 ignored). Returns ``dO/du`` (K,
        n_motors), or ``dO/dz`` (nz,) when ``dudz`` is given. Pass the ``traj`` of the same
        rollout to skip re-simulating it."""
        u = self._check_u(u, K=len(np.asarray(u)))
        if traj is None:
            traj = self.rollout(u, x0=x0, check_bounds=False, history0=history0)
        dobj_dx = np.asarray(dobj_dx, dtype=np.float64)
        if dobj_dx.shape != traj.x.shape:
            raise ValueError(f"dobj_dx must have shape {traj.x.shape}, got {dobj_dx.shape}")
        dOdu = adjoint_pass(self.newton, traj.x, u, dobj_dx, history0)
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
