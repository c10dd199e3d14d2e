r"""The co-design problem: gait keyframes z and design parameters theta, one shooting problem.

The variables are ``w = [z; theta]``: the keyframes of a walking gait
(:class:`~trajopt.optim.parameterization.GaitParameterization`) and the robot's design parameters
(:class:`~soft_envs.envs.design.DesignParameters`: regional moduli, via points, leg lengths).
The objective is the walk's (paper eq. 5-7) made independent of where the robot starts, plus a
small pull towards the shipped design:

.. math::
    O(w) = \tfrac12 |r(w)|^2, \quad r = [r_{com}; r_{mag}; r_{smooth}; r_{design}]

* ``r_com,k = sqrt(w_com / K) (c_k - c_0 - v t_k e_x) / BL``: the horizontal COM of states
  k = 1..K against a straight line at the target speed v from the rest COM ``c_0``, which moves
  with the design (its derivative ``dc_0/dtheta`` is in the Jacobian);
* the keyframes' magnitude and smoothness regularisers of :mod:`trajopt.optim.objectives`;
* ``r_design = sqrt(w_design / n_theta) (theta - theta_shipped) / range``, each parameter
  normalised by the width of its bounds.

The slack-eating term of the walk (paper eq. 13) is off: it exists to leave the flat slack
regions when a search starts from rest, and co-design starts from an optimised gait whose
cables are taut.

Jacobian: ``dr/dz`` from ``traj.dcomdz``, ``dr/dtheta`` from ``traj.dcomdtheta``, both from one
forward recurrence (:func:`soft_envs.envs.design.design_rollout`, paper eqs. 8-11 with the
design's parameter block). The derivatives of a design block hold at its own robot, so the
problem keeps a current block and moves it (:meth:`DesignParameters.moved_to`) to every point
where Gauss-Newton asks for a Jacobian (an accepted iterate); trial points of the line search are
the current block's :meth:`~DesignParameters.robot_at`.

Constraints. Linear in w: the motors' speed limit on z (:mod:`trajopt.optim.motor_limit`) and the
bounds of z and theta. Under the motors' torque-speed line (``motor_model="torque-speed"``,
:mod:`trajopt.optim.motor_torque`) its rows on w, linearised at every accepted iterate through
``dgammadz`` and ``dgammadtheta`` of the design's rollout (the tensions depend on the design:
stiffer legs, moved via points and longer legs load the motors differently); a trial whose own
rollout breaks the line beyond its 1 % tolerance (the line is not linear) is refused like a
trial that breaks the clearance. Nonlinear in theta, linearised at every accepted iterate
(:meth:`CodesignProblem.linearised_constraints`): every routed via point stays
``min_clearance`` (2 mm) inside the body (``TendonRouting.clearance``), and the total mass
stays at least ``mass_floor`` (98 %) of the shipped robot's. A trial point that breaks either
(checked exactly, :meth:`CodesignProblem.design_violation`) is refused as a failed trial.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from soft_envs.envs import MotorLaw, SimulationError, as_gradient_env
from soft_envs.envs.design import MAX_MASS_LOSS, MIN_CLEARANCE, DesignParameters, design_rollout

from ..optim.gait import GaitSpec
from ..optim.motor_limit import IDEAL, SPEED, TORQUE_SPEED, speed_limit_constraints
from ..optim.motor_torque import LINE_TOLERANCE, MotorLine
from ..optim.parameterization import GaitParameterization
from ..optim.qp import LinearConstraints
from ..tasks.targets import bl_per_min_to_mps

__all__ = ["CodesignWeights", "CodesignProblem", "InfeasibleDesign", "TrustRegion", "CLEARANCE_MARGIN", "design_env"]

#: [m] the linearised clearance keeps this much above the limit where it can (the exact check
#: then refuses fewer trials: the signed distance inside a body is concave near its edges)
CLEARANCE_MARGIN = 2e-5
#: [m] rounding allowed on the exact clearance check (the shipped via points sit at 2 mm to 1e-17 m)
CLEARANCE_ATOL = 1e-12


@dataclass(frozen=True)
class TrustRegion:
    """How far one Gauss-Newton step may move the design: via points and leg lengths by
    ``routing`` and ``legs`` [m] per coordinate, moduli by ``stiffness`` times their value. The
    linearised clearance only knows the faces nearest each point (a point sliding along a face is
    not held by it), and the objective of a via point is piecewise smooth on the mesh's
    elements: steps of a few millimetres keep the linear model honest."""

    routing: float = 5e-4
    legs: float = 5e-4
    stiffness: float = 0.05

    def radius(self, names, values: np.ndarray) -> np.ndarray:
        """(len,) the largest move of each design parameter in one step."""
        out = np.empty(len(names))
        for i, (n, v) in enumerate(zip(names, values)):
            kind = n.split(":", 1)[0]
            out[i] = self.stiffness * abs(v) if kind == "stiffness" else getattr(self, kind)
        return out


class InfeasibleDesign(SimulationError):
    """A trial design breaks a nonlinear constraint (clearance or mass): Gauss-Newton counts the
    trial as failed and shortens the step."""


@dataclass(frozen=True)
class CodesignWeights:
    """Weights of the co-design objective's terms (module docstring)."""

    com: float = 1.0
    magnitude: float = 1e-3
    smoothness: float = 1e-3
    design: float = 1e-3

    def to_dict(self) -> dict:
        return asdict(self)


def design_env(robot, contact: str, newton: Any = None, substeps: int | None = None, motor_model: str = TORQUE_SPEED):
    """A gradient environment of a design's robot under ``contact`` with ``substeps`` physics
    steps per control step (None: the law's default), with Newton options ``newton`` (None: the
    environment's) and the motors' law ``motor_model`` (what the gaits optimised on it obey)."""
    from soft_envs.envs import make_gradient_env
    env = make_gradient_env(robot, contact=contact, substeps=substeps, motor_model=motor_model)
    if newton is not None:
        env.simulator.newton.options = newton
    return env


class CodesignProblem:
    """``(r, J, info) = problem(w, need_jac)`` for Gauss-Newton over ``w = [z; theta]``.

    ``env``: the shipped robot's gradient environment (its contact law is used for every
    design); ``design``: its design parameters; ``gait``: the gait's shape (cycle, keyframes,
    interpolation); ``speed_bl_per_min``: the target speed (:meth:`set_target` changes it);
    ``max_step``: the motors' limit per step [m] (None: none); ``motor_model``: with
    ``"torque-speed"`` the motors' line too (module docstring; None: the environment's model, or
    none without ``max_step``); ``newton``: Newton options set on every design's environment
    (default: the environment's; tests take finite differences at a tight tolerance)."""

    def __init__(self, env, design: DesignParameters, gait: GaitSpec, speed_bl_per_min: float,
                 weights: CodesignWeights = CodesignWeights(), max_step: np.ndarray | None = None,
                 min_clearance: float = MIN_CLEARANCE, mass_floor: float = 1.0 - MAX_MASS_LOSS,
                 newton: Any = None, trust: "TrustRegion | None" = None, motor_model: str | None = None):
        self.env = as_gradient_env(env)
        self.newton = newton
        self.trust = TrustRegion() if trust is None else trust
        if newton is not None:
            self.env.simulator.newton.options = newton
        if design.robot is not self.env.robot:
            raise ValueError("the design parameters must be built for the environment's robot "
                             "(load_design(env.robot, ...))")
        self.contact = self.env.contact_model
        self.substeps = int(self.env.substeps)          # every design is simulated with the base's physics
        self.shipped = design
        self.block = design
        self.anchor = design.values.copy()         # the optimiser's theta of the block (move_to)
        self.gait = gait
        self.param = GaitParameterization.for_robot(self.env.robot, gait)
        self.dudz = self.param.dudz()
        self.u_offset = self.param.offset()
        self.weights = weights
        self.max_step = max_step
        self.min_clearance = float(min_clearance)
        self.min_mass = float(mass_floor) * design.total_mass()
        self.theta_shipped = design.values.copy()
        bounds = design.bounds
        self.theta_range = np.where(bounds[:, 1] > bounds[:, 0], bounds[:, 1] - bounds[:, 0], 1.0)
        self.nz, self.ntheta = self.param.nz, len(design)
        self.motor_rows = None if max_step is None else speed_limit_constraints(self.param, max_step)
        if motor_model is None:
            motor_model = IDEAL if max_step is None else getattr(self.env, "motor_model", SPEED)
        self.motor_model = motor_model
        self.line = None
        if motor_model == TORQUE_SPEED and max_step is not None:
            law = MotorLaw.of_robot(self.env.robot, np.asarray(max_step, dtype=np.float64) / self.env.timestep)
            self.line = MotorLine(self.param, law, self.env.timestep)
        self.set_target(speed_bl_per_min)
        self.sim_steps = 0
        self.rollouts = 0
        self.last_traj = None
        self._env, self._env_robot = self.env, design.robot

    # ------------------------------------------------------------------ variables
    def split(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w = np.asarray(w, dtype=np.float64)
        return w[:self.nz], w[self.nz:]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of w: the keyframes' and the design's."""
        lo, hi = self.param.bounds()
        return np.concatenate([lo, self.shipped.bounds[:, 0]]), np.concatenate([hi, self.shipped.bounds[:, 1]])

    def start(self, z: np.ndarray) -> np.ndarray:
        """w of keyframes ``z`` on the current design."""
        return np.concatenate([np.asarray(z, dtype=np.float64), self.anchor])

    def set_target(self, speed_bl_per_min: float) -> None:
        """Track a straight line along +x at ``speed_bl_per_min``."""
        self.speed = float(speed_bl_per_min)
        v = bl_per_min_to_mps(self.speed, self.env.robot.body_length)
        t = self.env.timestep * np.arange(1, self.param.n_steps() + 1)
        self.offsets = np.column_stack([v * t, np.zeros_like(t)])      # (K, 2): x, z from the rest COM

    def controls(self, z: np.ndarray, n_cycles: int | None = None) -> np.ndarray:
        return self.param.controls(z, n_cycles)

    # ------------------------------------------------------------------ designs
    def env_of(self, robot):
        """The gradient environment of a design's robot (same contact law; the last one is kept)."""
        if self._env_robot is not robot:
            self._env, self._env_robot = design_env(robot, self.contact, self.newton, self.substeps,
                                                    self.motor_model), robot
        return self._env

    def robot_at(self, theta: np.ndarray):
        """The robot of design ``theta`` from the current block."""
        theta = np.asarray(theta, dtype=np.float64)
        if np.array_equal(theta, self.anchor):
            return self.block.robot
        return self.block.robot_at(self.block.values + (theta - self.anchor))

    def move_to(self, theta: np.ndarray) -> None:
        """Linearise at design ``theta`` from now on (:meth:`DesignParameters.moved_to`)."""
        self.block, self.anchor = self.moved(self.block, self.anchor, theta)

    @staticmethod
    def moved(block, anchor: np.ndarray, theta: np.ndarray):
        """``(block, anchor)`` moved from the optimiser's design ``anchor`` to ``theta``. A block's
        values are the design as its robot has it: a leg morph carries the via points in the leg
        with it, so a moved block's routing values may differ from the optimiser's theta; the
        block maps ``theta`` to its values ``block.values + (theta - anchor)`` (the Jacobians are
        the same in both)."""
        theta = np.asarray(theta, dtype=np.float64)
        if np.array_equal(theta, anchor):
            return block, anchor
        return block.moved_to(block.values + (theta - anchor)), theta.copy()

    def _routing(self):
        for kind, sl in zip(self.block.kinds, self.block._slices):
            if kind.kind == "routing":
                return kind, sl
        return None, None

    def design_violation(self, robot) -> str | None:
        """What a design's robot breaks (None: nothing): clearance and mass, checked exactly."""
        routing, _ = self._routing()
        if routing is not None:
            d, _ = routing.clearance(robot)
            if d.size and d.min() < self.min_clearance - CLEARANCE_ATOL:
                return f"a via point {1e3 * d.min():.4f} mm inside the body (at least {1e3 * self.min_clearance:g})"
        if robot.total_mass < self.min_mass:
            return f"total mass {1e3 * robot.total_mass:.3f} g below the floor {1e3 * self.min_mass:.3f} g"
        return None

    def linearised_constraints(self, w: np.ndarray, trust: bool = True) -> LinearConstraints:
        """``G w <= h`` at the current design: the motors' limit (on z), every via point's clearance
        and the mass floor, linearised (module docstring), and the trust region (``trust``). Call
        after ``self(w, True)``."""
        _, theta = self.split(w)
        rows, rhs = [], []
        if self.motor_rows is not None:
            rows.append(np.hstack([self.motor_rows.G, np.zeros((len(self.motor_rows.h), self.ntheta))]))
            rhs.append(self.motor_rows.h)
        if self.line is not None:               # the line on w, at the current design (module docstring)
            lin = self.line_constraints(w)
            rows.append(lin.G)
            rhs.append(lin.h)
        routing, sl = self._routing()
        if routing is not None:
            d, J = routing.clearance(self.block.robot)
            allowed = np.maximum(d - self.min_clearance - CLEARANCE_MARGIN, 0.0)   # d + J dtheta >= d - allowed
            G = np.zeros((len(d), self.nz + self.ntheta))
            G[:, self.nz + sl.start:self.nz + sl.stop] = -J
            rows.append(G)
            rhs.append(allowed + G[:, self.nz:] @ theta)
        if self.ntheta and trust:             # the trust region around the current design
            radius = self.trust.radius(self.block.names, theta)
            eye = np.hstack([np.zeros((self.ntheta, self.nz)), np.eye(self.ntheta)])
            rows += [eye, -eye]
            rhs += [theta + radius, -(theta - radius)]
        dm = self.block.total_mass_jacobian()
        if np.any(dm != 0):
            g = np.concatenate([np.zeros(self.nz), -dm])
            rows.append(g[None, :])
            rhs.append(np.array([max(self.block.total_mass() - self.min_mass, 0.0) + g[self.nz:] @ theta]))
        if not rows:
            return LinearConstraints(np.zeros((0, self.nz + self.ntheta)), np.zeros(0))
        return LinearConstraints(np.vstack(rows), np.concatenate(rhs))

    def line_constraints(self, w: np.ndarray) -> LinearConstraints:
        """The motors' torque-speed line's rows on ``w`` (z and theta), linearised on the rollout
        of the last Jacobian (call after ``self(w, True)``; ``self.line`` must be set)."""
        traj = self.last_traj
        z, theta = self.split(w)
        return self.line.linearised(z, traj.cable_deformation, traj.dgammadz, theta0=theta,
                                    dgammadtheta=traj.dgammadtheta)      # None without design parameters

    # ------------------------------------------------------------------ residuals
    def __call__(self, w: np.ndarray, need_jac: bool = True):
        z, theta = self.split(w)
        if need_jac:
            self.move_to(theta)
            robot = self.block.robot
        else:
            try:
                robot = self.robot_at(theta)
            except ValueError as err:              # e.g. a via point outside the body
                raise InfeasibleDesign(str(err)) from None
            why = self.design_violation(robot)
            if why is not None:
                raise InfeasibleDesign(why)
        env = self.env_of(robot)
        u = self.u_offset + self.dudz @ z
        traj = design_rollout(env, u, self.block, self.dudz) if need_jac else env.rollout(u)
        self.sim_steps += len(u)
        self.rollouts += 1
        if not need_jac and self.line is not None:
            worst = self.line.worst(z, traj.cable_deformation)
            if worst.excess > LINE_TOLERANCE:
                raise InfeasibleDesign(worst.describe(list(robot.motor_names)))
        r, J, terms = self.residuals(traj, z, theta, robot.body_length, need_jac)
        if need_jac:
            self.last_traj = traj
        return r, J, {"terms": terms}

    def residuals(self, traj, z: np.ndarray, theta: np.ndarray, body_length: float, need_jac: bool):
        """``(r, J, terms)`` of a rollout (module docstring)."""
        wt = self.weights
        K = len(traj.x) - 1
        s_com = np.sqrt(wt.com / K) / body_length
        com = traj.com[:, [0, 2]]
        r_com = (s_com * (com[1:] - com[0] - self.offsets)).ravel()
        lo, hi = self.param.bounds()
        rng_z = hi - lo
        nz, nt = self.nz, self.ntheta
        s_mag = np.sqrt(wt.magnitude / nz)
        r_mag = s_mag * (z - lo) / rng_z
        Kf = self.param.n_keyframes
        D = np.roll(np.eye(Kf), 1, axis=1) - np.eye(Kf)          # z_{j+1} - z_j, periodic
        Dz = np.kron(np.eye(nz // Kf), D) / rng_z[None, :]
        s_sm = np.sqrt(wt.smoothness / nz)
        r_sm = s_sm * (Dz @ z)
        s_d = np.sqrt(wt.design / max(nt, 1))
        r_d = s_d * (theta - self.theta_shipped) / self.theta_range
        r = np.concatenate([r_com, r_mag, r_sm, r_d])
        terms = {"com": 0.5 * float(r_com @ r_com), "magnitude": 0.5 * float(r_mag @ r_mag),
                 "smoothness": 0.5 * float(r_sm @ r_sm), "design": 0.5 * float(r_d @ r_d)}
        if not need_jac:
            return r, None, terms
        dcom_z = traj.dcomdz[:, [0, 2], :]
        dcom_t = traj.dcomdtheta[:, [0, 2], :]
        J_com = np.concatenate([(s_com * (dcom_z[1:] - dcom_z[0])).reshape(-1, nz),
                                (s_com * (dcom_t[1:] - dcom_t[0])).reshape(-1, nt)], axis=1)
        J_mag = np.hstack([np.diag(s_mag / rng_z), np.zeros((nz, nt))])
        J_sm = np.hstack([s_sm * Dz, np.zeros((nz, nt))])
        J_d = np.hstack([np.zeros((nt, nz)), np.diag(s_d / self.theta_range)])
        return r, np.vstack([J_com, J_mag, J_sm, J_d]), terms
