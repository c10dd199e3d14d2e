"""SoftRobotEnv: the Gymnasium environment shared by ``SoftTripod-v2`` and ``SoftPuppy-v2`` (and their ``-v0``, ``-v1``).

A thin layer over :class:`soft_envs.sim.Simulator`: actions in [-1, 1] become cable
contractions (followed as the motors can: ``motor_model``, :mod:`.actuation`), ``frame_skip`` implicit-Euler steps are taken, and the
observation, reward and termination are computed from the node positions. The full
specification (spaces, rewards, arguments) is in the docstrings of
:class:`~soft_envs.envs.tripod.SoftTripodEnv` and :class:`~soft_envs.envs.puppy.SoftPuppyEnv`.
The gradient hooks of :class:`~soft_envs.envs.protocol.GradientEnv` are implemented in
:mod:`.hooks` (:class:`~.hooks.GradientHooksMixin`), rendering in :mod:`.viewer`, the motors in
:mod:`.actuation`, the observation (its parts, space and construction) in :mod:`.observation`,
the reward and termination in :mod:`.task`.

Determinism: the simulator's Newton solver may reuse the Cholesky factorisation of an earlier
step (chord iterations), which makes a step's result depend, at the level of the Newton
tolerance, on what the solver did before. Every :meth:`step` and :meth:`rollout` therefore starts
with no factorisation held, so a step is a function of (state, action) only: a seeded reset
replays bit for bit, and a pickled copy steps exactly like the original.
"""
from __future__ import annotations

import dataclasses
import os
from collections import deque
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import logger, spaces

from ..sim import (DEFAULT_DT, GAIT_CYCLE_STEPS, FactorCache, Robot, SimulationError, Simulator, State,
                   incline_gravity, load_robot)
from ..sim.contact import CONTACT_LAWS
from ..sim.ground import HeightField
from ..sim.robot import DEFAULT_MAX_SPEED_RPM
from ..sim.motors import TORQUE_SPEED
from .actuation import MOTOR_SPEED_FROM_ROBOT, Actuation
from .arguments import RENDER_MODES, check_env_arguments
from .domain import draw_standing_robot, parse_domain_randomization, randomized_robot
from .ground_reference import GroundReference
from .measure import BodyFrame, wrap_angle, yaw_of
from .observation import Observation
from .task import LocomotionTask
from .threads import limit_threads_in_worker
from .hooks import GradientHooksMixin
from .viewer import EnvViewer, RenderingMixin

__all__ = ["SoftRobotEnv", "PAPER_TIMESTEP", "PAPER_GAIT_PERIOD", "MOTOR_NO_LOAD_RPM", "with_contact_law"]

PAPER_TIMESTEP = DEFAULT_DT         # [s] the paper's simulation time step h (soft_envs.sim.timing)
PAPER_GAIT_PERIOD = GAIT_CYCLE_STEPS * PAPER_TIMESTEP   # [s] the paper's gait cycle: 72 steps
MOTOR_NO_LOAD_RPM = DEFAULT_MAX_SPEED_RPM   # Pololu 298:1 micro metal gearmotor, no-load at 6 V (a motor's default)
_TRAIL_LENGTH = 3000                # COM trail points kept for rendering
_RENDER_MODES = RENDER_MODES


def with_contact_law(robot: Robot, contact: str | None) -> Robot:
    """``robot`` with its contact law switched to ``contact`` ("paper" or "coulomb"; None keeps
    the robot file's), the law's parameters as the robot file gives them."""
    if contact is None or contact == robot.contact.model:
        return robot
    return robot.replace(contact=dataclasses.replace(robot.contact, model=contact))


class SoftRobotEnv(GradientHooksMixin, RenderingMixin, gym.Env[np.ndarray, np.ndarray]):
    """A cable-driven soft robot on the ground plane (see the module docstring and the
    per-robot subclasses for the specification, keywords included)."""

    metadata = {"render_modes": list(_RENDER_MODES), "render_fps": 30}

    def __init__(
        self,
        robot: str | os.PathLike | Robot = "puppy",
        *,
        frame_skip: int = 1,
        timestep: float = PAPER_TIMESTEP,
        substeps: int | None = None,
        task: str = "walk",
        target_heading_deg: float = 0.0,
        turn_direction: str = "right",
        turn_radius: float | None = None,
        incline_deg: float = 0.0,
        forward_reward_weight: float = 10.0,
        ctrl_cost_weight: float = 0.01,
        healthy_reward: float = 0.1,
        terminate_when_unhealthy: bool = True,
        healthy_tilt_deg: float = 60.0,
        healthy_height_fraction: float = 0.5,
        reset_noise_scale: float = 1e-4,
        motor_speed_rpm: float | str | None = MOTOR_SPEED_FROM_ROBOT,
        motor_model: str = TORQUE_SPEED,
        gait_period: float = PAPER_GAIT_PERIOD,
        observe_nodes: bool = False,
        domain_randomization: Mapping[str, tuple[float, float]] | bool | None = None,
        contact: str | None = None,
        ground: HeightField | None = None,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        camera_config: Mapping[str, Any] | None = None,
    ):
        self._task = LocomotionTask(
            task=task, target_heading_deg=target_heading_deg, turn_direction=turn_direction,
            turn_radius=turn_radius, forward_reward_weight=forward_reward_weight,
            ctrl_cost_weight=ctrl_cost_weight, healthy_reward=healthy_reward,
            terminate_when_unhealthy=terminate_when_unhealthy, healthy_tilt_deg=healthy_tilt_deg,
            healthy_height_fraction=healthy_height_fraction)
        check_env_arguments(frame_skip=frame_skip, timestep=timestep, substeps=substeps, gait_period=gait_period,
                            reset_noise_scale=reset_noise_scale, motor_speed_rpm=motor_speed_rpm,
                            motor_model=motor_model, incline_deg=incline_deg, observe_nodes=observe_nodes,
                            render_mode=render_mode,
                            width=width, height=height, camera_config=camera_config)
        if not isinstance(robot, (str, os.PathLike, Robot)):
            raise ValueError(f"robot must be a shipped name, a robot.toml path or a Robot, got {type(robot).__name__}")
        limit_threads_in_worker()      # a vector-env worker: one BLAS/numba thread (threads.py)
        self._base_robot = with_contact_law(robot if isinstance(robot, Robot) else load_robot(robot), contact)
        if ground is not None:         # a HeightField (else the robot file's [ground], or the plane y = 0)
            self._base_robot = self._base_robot.replace(ground=ground)
        self._ground_ref = GroundReference(self._base_robot.ground)   # heights, tilts: above the ground
        if self._base_robot.n_motors == 0:
            raise ValueError(f"robot {self._base_robot.name!r} has no motors")
        self.frame_skip = int(frame_skip)
        self._substeps = int(CONTACT_LAWS[self._base_robot.contact.model].default_substeps
                             if substeps is None else substeps)
        self._heading = self._task.heading
        self._incline_deg = float(incline_deg)
        self._gravity = incline_gravity(incline_deg, uphill=(self._heading[0], self._heading[2]))
        self._reset_noise_scale = float(reset_noise_scale)
        self._gait_period = float(gait_period)
        self._observe_nodes = bool(observe_nodes)
        self._domain_ranges = parse_domain_randomization(domain_randomization)
        # rendering (the viewer is made at the first frame)
        self.render_mode = render_mode
        self._width, self._height = int(width), int(height)
        self._camera_config = dict(camera_config or {})
        self._viewer: EnvViewer | None = None
        self._steps_beyond_terminated = 0        # steps after terminated=True (warned at the first)
        self._init_physics(timestep)
        self._init_actuation(motor_speed_rpm, motor_model)
        self._init_spaces()

    def _init_actuation(self, motor_speed_rpm: float | str | None, motor_model: str) -> None:
        """The motors (:mod:`.actuation`)."""
        self._actuation = Actuation(self._base_robot, motor_speed_rpm, self.timestep, motor_model)
        self.motor_speed = self._actuation.speed                          # (M,) [m/s]

    def _init_spaces(self) -> None:
        """The action space, and the observation (:class:`~.observation.Observation`: its parts
        as ``observation_structure``, its space)."""
        r = self._base_robot
        self._observation = Observation(r, self._actuation.range, self._observe_nodes, self._gait_period)
        self.observation_structure = self._observation.structure
        self.action_space = spaces.Box(-1.0, 1.0, shape=(r.n_motors,), dtype=np.float32)
        self.observation_space = self._observation.space
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / self.dt))}

    def _init_physics(self, timestep: float) -> None:
        """The simulator of the nominal robot with time step ``timestep`` (from then on the
        simulator's ``dt`` is the environment's one time step), and the state at rest (until
        the first reset)."""
        self._domain: dict[str, float] = {}
        self._sim: Simulator | None = None
        self._set_domain({k: 1.0 for k in (self._domain_ranges or {})}, dt=timestep)
        u_rest = self._base_robot.u_rest
        self._reset_state = self._sim.rest_state(u_rest)
        self._restore(self._reset_state, u_rest, self._frame.com(self._reset_state.x))

    # ------------------------------------------------------------------ properties (hooks)
    @property
    def simulator(self) -> Simulator:
        """The :class:`Simulator` in use (rebuilt at reset when domain randomisation draws new
        parameters)."""
        return self._sim

    @property
    def robot(self) -> Robot:
        """The robot in use (the nominal robot with the current randomised parameters)."""
        return self._sim.robot

    @property
    def dt(self) -> float:
        """Duration of one environment step [s]: ``frame_skip * timestep``, as in Gymnasium's
        MuJoCo environments (rewards divide displacements by it)."""
        return self.frame_skip * self.timestep

    @property
    def timestep(self) -> float:
        """Control step h [s] (``simulator.dt``): the step of :meth:`rollout` (one row of its
        controls) and of the motors; ``frame_skip`` of them make an environment step."""
        return self._sim.dt

    @property
    def substeps(self) -> int:
        """Physics steps per control step (``simulator.substeps``; each ``timestep / substeps``
        seconds, the controls joined by straight lines): the ``substeps`` keyword, by default
        the contact law's (:attr:`~soft_envs.sim.contact.ContactLaw.default_substeps`)."""
        return self._substeps

    @property
    def motor_model(self) -> str:
        """The motors' law: ``"torque-speed"``, ``"speed"`` or ``"ideal"`` (the ``motor_model``
        keyword; :mod:`soft_envs.sim.motors`)."""
        return self._actuation.model

    @property
    def locomotion_task(self) -> LocomotionTask:
        """What the robot is rewarded for (task, heading, turn side, reward weights: the keywords
        of :class:`~soft_envs.envs.task.LocomotionTask`)."""
        return self._task

    @property
    def incline_deg(self) -> float:
        """Ground slope [deg], rising along the target heading."""
        return self._incline_deg

    @property
    def contact_model(self) -> str:
        """The ground contact law: ``"paper"`` or ``"coulomb"`` (see the ``contact`` keyword)."""
        return self._base_robot.contact.model

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector (3,) [m/s^2] (rotated for an incline)."""
        return self._gravity.copy()

    @property
    def domain_parameters(self) -> dict[str, float]:
        """The multiplicative factors of the current episode (empty without randomisation)."""
        return dict(self._domain)

    # ------------------------------------------------------------------ simulator management
    def _set_domain(self, factors: Mapping[str, float], dt: float | None = None) -> None:
        """Use the robot with these factors; rebuild the simulator only if they changed (with
        the current simulator's time step, or ``dt`` for the first). A robot that cannot stand
        at rest raises SimulationError and changes nothing."""
        factors = {k: float(v) for k, v in sorted(factors.items())}
        if self._sim is not None and factors == self._domain:
            return
        robot = randomized_robot(self._base_robot, factors)
        sim = Simulator(robot, dt=self._sim.dt if dt is None else dt, gravity=self._gravity, control="length",
                        substeps=self._substeps)
        x_rest = sim.rest_state(robot.u_rest).x
        self._sim, self._domain = sim, factors
        self._frame = BodyFrame(x_rest, robot.body_node_masses)     # the robot's own body (a box left out)
        com_rest = self._frame.com(x_rest)
        self._rest_com_height = float(com_rest[1]) - self._ground_ref.height_under(com_rest)

    def _draw_domain(self) -> dict[str, Any]:
        """Draw this episode's robot (:func:`~soft_envs.envs.domain.draw_standing_robot`: redraws
        from ``np_random`` until it stands at rest, else the nominal robot); returns the ``info``
        entries that report it."""
        return draw_standing_robot(self._domain_ranges, self.np_random, self._set_domain)

    # ------------------------------------------------------------------ actions
    def action_to_control(self, action: Any) -> np.ndarray:
        """Contractions u [m] (M,) commanded by ``action`` (clipped to [-1, 1]):
        ``u = u_min + (a + 1) / 2 (u_max - u_min)``; no speed limit."""
        return self._actuation.command(self._actuation.check_action(action))

    def control_to_action(self, u: Any) -> np.ndarray:
        """The action (float64, not clipped) that commands contractions ``u`` [m], (..., M)."""
        return self._actuation.to_action(u)

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode at rest (plus ``reset_noise_scale`` noise). With domain
        randomisation the robot is drawn first (:meth:`_draw_domain`); ``info`` then also holds
        ``domain_parameters`` (the factors), ``domain_draws`` and ``domain_fallback``. A reset
        never raises for a drawn robot that cannot stand. ``options``: None or a dict of the keys
        in :attr:`reset_option_keys` (none: these environments take no reset options); anything
        else is a ValueError naming the key or type, raised before the state is touched."""
        self._check_reset_options(options)
        super().reset(seed=seed)
        self._steps_beyond_terminated = 0
        domain_info = self._draw_domain() if self._domain_ranges is not None else {}
        u_rest = self.robot.u_rest
        state = self._sim.rest_state(u_rest)          # with its stick anchors (if any)
        s = self._reset_noise_scale
        if s > 0:
            x0 = state.x + self.np_random.uniform(-s, s, size=state.x.shape)
            xm1 = x0 - self.np_random.uniform(-s, s, size=state.x.shape)
            state = State(x0, xm1, None, self._sim.initial_history(x0), 0, u_rest)   # anchors where the feet are
        self._reset_state = state
        self._restore(state, u_rest, self._frame.com(state.x))
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), {**self._get_info(), **domain_info}

    #: the ``reset(options=...)`` keys this environment understands (subclasses may add some)
    reset_option_keys: frozenset[str] = frozenset()

    def _check_reset_options(self, options: Any) -> None:
        if options is None:
            return
        if not isinstance(options, Mapping):
            raise ValueError(f"reset options must be a dict or None, got {type(options).__name__}: {options!r:.80}")
        unknown = sorted(map(repr, set(options) - self.reset_option_keys))
        if unknown:
            known = ", ".join(sorted(self.reset_option_keys)) or "none"
            raise ValueError(f"unknown reset option {', '.join(unknown)} (this environment's reset options: {known})")

    def step(self, action: Any):
        self._warn_if_stepping_after_termination()
        a = self._actuation.check_action(action)
        u_cmd = self._actuation.command(a)
        state, u = self._state, self._u
        u_sub = np.empty((self.frame_skip, len(u)))
        limited = np.zeros(len(u), dtype=bool)
        cache = FactorCache()         # the sub-steps of this step share factorisations, no others
        try:
            for i in range(self.frame_skip):
                tau = self._motor_torque(state.x, u) if self.motor_model == TORQUE_SPEED else None
                u, held = self._actuation.follow(u, u_cmd, tau)    # the load of the state before the step
                limited |= held
                state = self._sim.step(state, u, factor_cache=cache)
                u_sub[i] = u
        except SimulationError as err:     # keep the state of before the step
            self._failed_state = self._state
            info = self._get_info()
            info.update(reward_forward=0.0, reward_ctrl=0.0, reward_survive=0.0,
                        sim_failure=str(err))
            return self._get_obs(), 0.0, True, False, info
        com_before, yaw_before = self._com, self._yaw
        self._restore(state, u, self._com_start)
        forward_velocity = float((self._com - com_before) @ self._heading) / self.dt / self._body_length
        yaw_rate = wrap_angle(self._yaw - yaw_before) / self.dt
        reward, reward_info = self._task.reward(forward_velocity, yaw_rate, a, self.is_healthy, self._body_length)
        terminated = self._task.terminate_when_unhealthy and not self.is_healthy
        info = self._get_info()
        info.update(forward_velocity=forward_velocity, yaw_rate=yaw_rate, u_substeps=u_sub, motor_limited=limited,
                    **reward_info)
        if self.render_mode == "human":
            self.render()
        # truncation is left to the TimeLimit wrapper added by gymnasium.make
        return self._get_obs(), reward, terminated, False, info

    def _has_terminated(self) -> bool:
        """Whether the last step returned ``terminated=True`` (a failed simulation step, or
        unhealthy with ``terminate_when_unhealthy``; a task may add its own ends)."""
        return (getattr(self, "_failed_state", None) is self._state
                or (self._n_sub > 0 and self._task.terminate_when_unhealthy and not self._healthy))

    def _warn_if_stepping_after_termination(self) -> None:
        """Warn (once per episode, as Gymnasium's own environments do) when :meth:`step` follows
        a step that returned ``terminated=True`` (unhealthy, or a failed simulation step)."""
        if not self._has_terminated():
            return
        if self._steps_beyond_terminated == 0:
            logger.warn("You are calling 'step()' even though this environment has already returned terminated = "
                        "True. You should always call 'reset()' once you receive 'terminated = True' -- any "
                        "further steps are undefined behavior.")
        self._steps_beyond_terminated += 1

    # ------------------------------------------------------------------ state and measurements
    @property
    def _body_length(self) -> float:
        return float(self._base_robot.body_length)

    def _restore(self, state: State, u: np.ndarray, com_start: np.ndarray) -> None:
        """Set the dynamic state (the simulator's :class:`~soft_envs.sim.State`: positions,
        previous positions, stick anchors, simulation steps since reset) and the applied
        contractions ``u``, and recompute the quantities derived from them."""
        x = state.x
        self._state, self._u = state, u
        self._com_start = np.array(com_start, dtype=np.float64)
        self._com = self._frame.com(x)
        self._rot = self._frame.rotation(x)
        self._yaw = yaw_of(self._rot)
        self._tilt = self._ground_ref.tilt_deg(self._rot)
        self._healthy = self._task.is_healthy(self._tilt, self._com, self._rest_com_height,
                                              self._ground_ref.height_under(self._com))
        if state.k == 0 or not hasattr(self, "_trail"):
            self._trail: deque[np.ndarray] = deque(maxlen=_TRAIL_LENGTH)
        if self.render_mode is not None:     # the COM path drawn on the ground
            self._trail.append(self._com)

    # the state's fields under the names the mixins (hooks, viewer) and tests read
    _x = property(lambda self: self._state.x, doc="positions now (n, 3) [m]")
    _x_prev = property(lambda self: self._state.x_prev, doc="positions one physics step ago (n, 3) [m]")
    _n_sub = property(lambda self: self._state.k, doc="control steps (of timestep) since reset")

    @property
    def is_healthy(self) -> bool:
        """Upright (tilt of the up vector from the ground's normal, +y on the plane, at most
        ``healthy_tilt_deg``), COM at least ``healthy_height_fraction`` of its rest height (both
        heights above the ground under the COM: :mod:`.ground_reference`), and a finite state."""
        return self._healthy

    def _get_obs(self) -> np.ndarray:
        """The observation of the current state (:meth:`.observation.Observation.build`)."""
        return self._observation.build(
            com=self._com, com_start=self._com_start, com_prev=self._frame.com(self._x_prev),
            physics_dt=self._sim.physics_dt, rotation=self._rot, gamma=self._sim.cable_deformation(self._x, self._u),
            contraction=self._actuation.to_action(self._u), n_sub=self._n_sub, timestep=self.timestep, x=self._x)

    def _motor_torque(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(M,) each motor's load torque [N m] at positions ``x`` with contractions ``u``."""
        return self._actuation.torque(self._sim.cable_tension(x, u))

    def _get_info(self) -> dict[str, Any]:
        return {"x_position": float(self._com[0]), "z_position": float(self._com[2]),
                "com": self._com.copy(), "displacement": self._com - self._com_start,
                "yaw": self._yaw, "tilt_deg": self._tilt, "time": self._n_sub * self.timestep,
                "u": self._u.copy(), "motor_torque": self._motor_torque(self._x, self._u),
                "is_healthy": self.is_healthy}

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_viewer"] = None           # matplotlib canvases are rebuilt on demand
        return state
