"""The rest state: the static equilibrium a simulation starts from (``Simulator.rest_state``).

Computed as proximal-point iterations ``x_{j+1} = argmin E(x; x_prev = x_j) + |x - x_j|^2_M / 2``
(implicit steps of 1 s from rest, each the one loop body :func:`~.state.advance`), which converge
to a state where the friction term exerts no force, so a rollout started there stays still. With
the paper's lagged (viscous-like) friction a robot on a slope creeps, so the relaxation of an
inclined simulator then uses only the normal component of gravity (on a height field that is not
flat, the Coulomb law holds the feet instead: :func:`_held_on_ground`). The Coulomb law holds it: its
relaxation is under the full gravity, with the stick anchors carried through the steps (the rest
state's anchors are loaded, and belong to it). With physical parameters the relaxation is
differentiated through the same recurrence as rollouts (:class:`~.sensitivity.ForwardSensitivities`).
"""
from __future__ import annotations

import numpy as np

from .contact import ContactParams
from .inputs import initial_placement
from .integrator import FactorCache, NewtonOptions, NewtonSolver, SimulationError
from .parameter_block import parameter_block
from .sensitivity import ForwardSensitivities
from .state import State, advance
from .system import EnergySystem

__all__ = ["relax", "placement_sensitivity", "RestStates"]


def _material(robot) -> str:
    """The material a failed rest state names, so that a unit mistake shows (E = 5 Pa, a
    density in g/cm^3): Young's modulus (and the range of the regional moduli), Poisson ratio,
    density, payload."""
    E = float(robot.youngs_modulus)
    scale = np.asarray(getattr(robot, "element_modulus_scale", np.ones(1)), dtype=np.float64)
    regions = (f" (regions {E * scale.min():g}..{E * scale.max():g} Pa)"
               if scale.size and (scale.min() != 1.0 or scale.max() != 1.0) else "")
    return (f"Young's modulus {E:g} Pa{regions}, Poisson ratio {float(robot.poisson_ratio):g}, density "
            f"{float(robot.density):g} kg/m^3, payload {float(getattr(robot, 'payload_mass', 0.0)):g} kg")


def relax(sim, u: np.ndarray, tol: float, max_iter: int, params=()):
    """The rest state of simulator ``sim`` under controls ``u`` (module docstring): its
    :class:`~.state.State`, and with ``params`` ``(state, dx/dtheta, dhistory/dtheta)``. Every
    relaxation step starts at rest at the last one's positions, with its anchors
    (:func:`~.state.advance` with a solver of ``dt = 1`` s). SimulationError, naming the robot,
    the controls, gravity and the material (so that a unit mistake shows), when a step fails or
    the body does not settle in ``max_iter``."""
    g = sim.gravity
    anchored = sim.system.contact.has_history        # the ground law holds the feet (Coulomb)
    relax_g = g if (anchored or sim.robot.fixed_nodes.size) else np.array([0.0, g[1], 0.0])
    robot = _held_on_ground(sim.robot, anchored, params)
    system = EnergySystem(robot, gravity=relax_g, control=sim.control)
    solver = NewtonSolver(system, 1.0, NewtonOptions(tol=min(tol, 1e-10), max_iter=100,
                                                     solver=sim.newton.options.solver))
    x = initial_placement(sim.robot)
    history = system.initial_history(x)
    sens = exact = None
    if params:      # its own solver for the exact Hessians: the relaxation's path stays that of rest_state
        exact = NewtonSolver(system, 1.0, solver.options)
        dx0, dh0 = placement_sensitivity(sim, system, params)
        sens = ForwardSensitivities(exact, sim.robot.body_node_masses, np.zeros((max_iter, sim.n_motors, 0)),
                                    params=params, x0=x, dx0dtheta=dx0, dhistory0dtheta=dh0, deformations=False)
    cache = FactorCache()
    for j in range(max_iter):
        start = State(x, x, None, history, j)       # at rest (no x_{k-2}: the guess is x itself)
        try:
            new, _ = advance(solver, start, u, cache=cache)
            if sens is not None:
                sens.hold()
                sens.step(j, exact.factorize_exact_at(new.x, start.x, start.x, u, history=start.history),
                          new.x, start.x, u, start.history, x_prev2=start.x)
        except SimulationError as err:
            raise SimulationError(f"rest_state of robot {sim.robot.name!r} failed (u = {u.tolist()}, "
                                  f"gravity = {relax_g.tolist()}; {_material(sim.robot)}): {err.reason}") from err
        moved = np.abs(new.x - start.x).max()
        x, history = new.x, new.history
        if moved <= tol:
            break
    else:
        hint = "; friction may not hold it on this slope (it slides)" if anchored and relax_g[[0, 2]].any() else ""
        raise SimulationError(f"rest_state of robot {sim.robot.name!r} did not settle in {max_iter} "
                              f"relaxation steps (last motion {moved:.2e} m; u = {u.tolist()}, "
                              f"gravity = {relax_g.tolist()}, tol = {tol}; {_material(sim.robot)}){hint}")
    held = robot is not sim.robot            # anchors the law does not keep
    rest = State.at_rest(x, sim.system.initial_history(x) if held else history, u=u)
    if sens is None:
        return rest
    dh = tuple(None if (p is None or held) else p[:, sens.nz:].copy()
               for p in (sens.P or (None,) * len(history)))
    return rest, sens.S1[:, sens.nz:].copy(), dh


def _held_on_ground(robot, anchored: bool, params=()):
    """The robot the relaxation simulates. A law without stick anchors (the paper's lagged,
    viscous-like friction) creeps on any ground that is not flat (a slope, rough ground), so it
    never settles there; on a height field that is not flat the relaxation holds the feet by
    the Coulomb law instead (its default friction coefficient and slip distance, the law's
    normal penalty), as the plane's relaxation drops gravity's tangential part on an incline;
    its anchors are not kept. Otherwise ``robot`` itself."""
    ground, contact = robot.ground, robot.contact
    if anchored or ground is None or ground.is_flat or robot.fixed_nodes.size:
        return robot
    fp = contact.law.friction_parameter
    if fp is not None and fp in tuple(params or ()):
        raise ValueError(f"{robot.source}: the rest state on {ground.description} is relaxed with the feet held "
                         f"by Coulomb friction: its derivative with respect to {fp} is not available")
    return robot.replace(contact=ContactParams(model="coulomb", stiffness=contact.stiffness, blend=contact.blend))


def placement_sensitivity(sim, system, params) -> tuple:
    """``(d initial_placement/dtheta (3n, nt), d initial_history/dtheta)`` for parameters that
    move the rest mesh (a :class:`~.parameter_block.ParameterBlock` with a
    ``rest_position_jacobian``, e.g. the leg morph of :mod:`soft_envs.sim.design`; ``(None,
    None)`` otherwise). The placement's shift to the ground follows the lowest node; the initial
    histories (anchors at the nodes) are linear in the positions."""
    dX = parameter_block(params).rest_position_jacobian(sim.robot)
    if dX is None:
        return None, None
    dX = np.array(dX, dtype=np.float64)
    ground = sim.robot.ground
    if ground is not None and np.any(ground.heights != 0.0):
        # the anchors on a relief are the nodes' feet on the surface, not linear in the positions:
        # initial_history of a derivative would be wrong (a planar field through the origin is exact)
        raise ValueError(f"{sim.robot.source}: the rest state's derivative with respect to parameters that move the "
                         f"rest mesh (the leg morph) is not available on {ground.description}")
    if sim.robot.fixed_nodes.size == 0:
        ground, X = sim.robot.ground, sim.robot.mesh.points
        if ground is None:
            dX[:, 1, :] -= dX[int(np.argmin(X[:, 1])), 1, :]
        else:                  # the lowest node above the field: its gap y - h(x, z) moves
            i = int(np.argmin(X[:, 1] - ground.height(X[:, 0], X[:, 2])))
            _, hx, hz = ground.derivatives(X[i, 0], X[i, 2])[:3]
            dX[:, 1, :] -= dX[i, 1, :] - hx * dX[i, 0, :] - hz * dX[i, 2, :]
    cols = [system.initial_history(dX[:, :, j]) for j in range(dX.shape[2])]
    dh = tuple(None if h is None else np.stack([c[i].ravel() for c in cols], axis=1)
               for i, h in enumerate(cols[0])) if cols else None
    return dX.reshape(-1, dX.shape[2]), dh


class RestStates:
    """The rest states of one simulator ``sim``, relaxed once per (controls, tolerance) and
    kept (:meth:`state`), and their parameter sensitivities (:meth:`sensitivity`)."""

    def __init__(self, sim):
        self.sim = sim
        self.states: dict = {}
        self._sensitivities: dict = {}

    def _controls(self, u) -> np.ndarray:
        return np.zeros(self.sim.n_motors) if u is None else self.sim.inputs.controls(u)

    def state(self, u, tol: float, max_iter: int) -> State:
        """The rest :class:`~.state.State` under controls ``u`` (None: 0), its ``u`` set."""
        u = self._controls(u)
        key = (tuple(u.tolist()), tol)
        if key not in self.states:
            self.states[key] = relax(self.sim, u, tol, max_iter)
        return self.states[key]

    def sensitivity(self, params, u, tol: float, max_iter: int) -> tuple:
        """``(x0, history0, dx0/dtheta, dhistory0/dtheta)`` of :meth:`state` for the checked
        parameters ``params``."""
        u = self._controls(u)
        key = (tuple(u.tolist()), tol, params)
        if key not in self._sensitivities:
            rest, dx, dh = relax(self.sim, u, tol, max_iter, params)
            self._sensitivities[key] = rest.x, rest.history, dx, dh
        return self._sensitivities[key]
