r"""The specification of the shipped environments (spaces, rewards, arguments, versions), written once.

``SoftTripodEnv`` and ``SoftPuppyEnv`` differ in their robot only: its description, its motors
and tendons, its body length and an example. :func:`env_docstring` builds a class's docstring
(Gymnasium's MuJoCo layout: Description, Action Space, Observation Space, Rewards, Starting
State, Episode End, Arguments, Version History) from a :class:`RobotDoc` holding those parts;
everything else, including the keyword table of :class:`~soft_envs.envs.base.SoftRobotEnv`, is
written here, and the list of gradient hooks comes from
:data:`~soft_envs.envs.protocol.GRADIENT_ENV_MEMBERS`. ``help(SoftTripodEnv)`` shows the result.
"""
from __future__ import annotations

import inspect
import textwrap
from dataclasses import dataclass

from .hooks import GradientHooksMixin
from .protocol import GRADIENT_ENV_MEMBERS, PARAMETER_MEMBERS, GradientEnv

__all__ = ["RobotDoc", "env_docstring", "markdown_table"]


@dataclass(frozen=True)
class RobotDoc:
    """What the specification of one shipped robot's environment says about the robot.

    ``name``: the shipped robot (``"tripod"``); ``env_name``: the id's stem (``"SoftTripod"``);
    ``description``: the Description section's paragraph; ``actions``: per motor, in robot.toml
    order, ``(what the action does, motor name)``; ``tendons``: the cable-deformation row's list
    of tendons and ``contractions`` the contraction row's list of motors; ``n_tendons``;
    ``body_length_m``; ``example``: a ``gym.make`` line of the Arguments section."""

    name: str
    env_name: str
    description: str
    actions: tuple[tuple[str, str], ...]
    n_tendons: int
    tendons: str
    contractions: str
    body_length_m: float
    example: str
    #: the ids registered for the robot: the paper's robots every version, a robot shipped after
    #: the v2 physics (the Hexapod, the Inchworm) only ``("v2",)``
    versions: tuple[str, ...] = ("v0", "v1", "v2")

    @property
    def n_motors(self) -> int:
        return len(self.actions)

    def motor_figures(self) -> dict[str, float]:
        """The shipped robot file's figures the Action Space states, read from it (not written
        here): ``u_min_mm``, ``u_max_mm`` (the first motor's range), ``rpm`` (its
        ``max_speed_rpm``), ``spool_radius_mm`` and ``v_max_mm_s``, its no-load contraction speed
        (:attr:`~soft_envs.sim.drive.Motor.max_contraction_speed`); unset keys take
        :class:`~soft_envs.sim.drive.Motor`'s defaults."""
        from ..sim.drive import Motor
        from ..sim.robot_file import asset_path, read_robot_toml
        entry = read_robot_toml(asset_path(self.name))["motors"][0]
        motor = Motor(name=str(entry["name"]), tendons=(), **{k: float(entry[k]) for k in
                      ("u_min", "u_max", "spool_radius", "max_speed_rpm") if k in entry})
        return {"u_min_mm": 1e3 * motor.u_min, "u_max_mm": 1e3 * motor.u_max, "rpm": motor.max_speed_rpm,
                "spool_radius_mm": 1e3 * motor.spool_radius, "v_max_mm_s": 1e3 * motor.max_contraction_speed}

    def motor_ranges_mm(self) -> list[tuple[float, float]]:
        """Each motor's ``(u_min, u_max)`` [mm], in robot.toml order, read from the shipped file."""
        from ..sim.robot_file import asset_path, read_robot_toml
        return [(1e3 * float(m.get("u_min", 0.0)), 1e3 * float(m["u_max"]))
                for m in read_robot_toml(asset_path(self.name))["motors"]]

    @property
    def n_observations(self) -> int:
        """Entries of the observation without nodes: COM 3 + velocity 3 + forward 3 + up 3 +
        cable deformation per tendon + contraction per motor + gait phase 2."""
        return 12 + self.n_tendons + self.n_motors + 2


def markdown_table(header: tuple[str, ...], rows: list[tuple[str, ...]], pad_up_to: int = 70) -> str:
    """A markdown table readable as plain text: each column is padded to its widest cell of at
    most ``pad_up_to`` characters (longer cells run on)."""
    widths = [max(len(r[i]) for r in (header, *rows) if len(r[i]) <= pad_up_to) for i in range(len(header))]

    def line(cells):
        return "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths)) + " |"
    return "\n".join([line(header), "|" + "|".join("-" * (w + 2) for w in widths) + "|", *map(line, rows)])


def _span(start: int, size: int) -> str:
    return str(start) if size == 1 else f"{start}-{start + size - 1}"


#: what each ``motor_model`` lets a motor do in one simulation step (the Action Space's table)
_MOTOR_MODEL_ROWS = [
    ('`"torque-speed"` (default)', "at most `v_max (1 - tau / stall_torque) timestep`; none once `tau >= max_torque`",
     "at most `v_max timestep`"),
    ('`"speed"` (`-v0`, `-v1`)', "at most `v_max timestep`", "at most `v_max timestep`"),
    ('`"ideal"`', "to `u_cmd` at once", "to `u_cmd` at once"),
]


def _action_section(r: RobotDoc) -> str:
    rows = [(str(i), what, f"-1 (u_min = {lo:g} mm)", f"1 (u_max = {hi:g} mm)", name, "cable length (m)")
            for i, ((what, name), (lo, hi)) in enumerate(zip(r.actions, r.motor_ranges_mm()))]
    table = markdown_table(("Num", "Action", "Control Min", "Control Max", "Name (robot.toml)", "Type (Unit)"), rows)
    model_rows = _MOTOR_MODEL_ROWS if "v0" in r.versions else [(m.replace(" (`-v0`, `-v1`)", ""), *rest)
                                                                for m, *rest in _MOTOR_MODEL_ROWS]
    motor_table = markdown_table(("motor_model", "winding (u rises)", "unwinding (u falls)"), model_rows)
    m = r.motor_figures()
    v_max = m["v_max_mm_s"]
    return f"""## Action Space
The action space is a `Box(-1, 1, ({r.n_motors},), float32)`. Action *a* commands the cable
contraction (metres of cable pulled in by the motor) `u_cmd = u_min + (a + 1) / 2 (u_max - u_min)`;
values outside [-1, 1] are clipped, NaN/inf or a wrong shape raise `ValueError`.
The applied contraction follows the command as the motors can (`motor_model`,
`soft_envs.sim.motors`). With `v_max = motor_speed_rpm * 2 pi / 60 * spool_radius`, the
no-load contraction speed (by default the robot's `[[motors]] max_speed_rpm`: {m["rpm"]:g} rpm for this
robot's file, a Pololu 298:1 HP micro metal gearmotor's no-load speed at 6 V; spool radius
{m["spool_radius_mm"]:g} mm: {v_max:.0f} mm/s, {v_max * 0.033:.2f} mm per 0.033 s step), in every control step it moves towards
`u_cmd`:

{motor_table}

The load torque is *tau* = `spool_radius` x the sum of the tensions of the motor's tendons, of
the state before the step; `stall_torque` and `max_torque` are the robot's `[[motors]]` keys
(0.39 and 0.196 N m for the shipped robots). Back-driving (a tension beyond the stall torque
turning the motor backwards) is not modelled. `info["u"]` is the contraction applied at the end
of the step, `info["u_substeps"]` (frame_skip, {r.n_motors}) the contraction at the end of each
control step, `info["motor_torque"]` ({r.n_motors},) each motor's load torque [N m] at the current
state (the one the next step's law uses) and `info["motor_limited"]` ({r.n_motors},) whether the
law held the motor back from its command in the step.

{{table}}
""".replace("{table}", table)


def _observation_section(r: RobotDoc) -> str:
    cables, motors = 12, 12 + r.n_tendons
    phase = motors + r.n_motors
    rows = [
        ("0", "COM x relative to the COM at reset", "-Inf", "Inf", "position (m)"),
        ("1", "COM height above the ground (y)", "-Inf", "Inf", "position (m)"),
        ("2", "COM z relative to the COM at reset", "-Inf", "Inf", "position (m)"),
        ("3-5", "COM velocity (x, y, z) over the last physics step", "-Inf", "Inf", "velocity (m/s)"),
        ("6-8", "forward vector R e_x (world frame)", "-1", "1", "unit vector"),
        ("9-11", "up vector R e_y (world frame)", "-1", "1", "unit vector"),
        (_span(cables, r.n_tendons), f"cable deformation Gamma of {r.tendons}, divided by the motor's range "
         "u_max - u_min (> 0 stretched, < 0 slack)", "-Inf", "Inf", "dimensionless"),
        (_span(motors, r.n_motors), f"applied contraction of {r.contractions}, scaled like the actions",
         "-1", "1", "dimensionless"),
        (_span(phase, 2), "gait phase sin, cos of 2 pi t / gait_period (t since reset)", "-1", "1", "dimensionless"),
        (f"{phase + 2}-...", "only with `observe_nodes=True`: node positions minus the COM, (n_nodes, 3) "
         "flattened: 3 n_nodes values (`env.unwrapped.robot.mesh.n_nodes`)", "-Inf", "Inf", "position (m)"),
    ]
    table = markdown_table(("Num", "Observation", "Min", "Max", "Type (Unit)"), rows)
    return f"""## Observation Space
A `Box(low, high, ({r.n_observations},), float64)` with the bounds of the Min and Max columns;
`env.unwrapped.observation_structure` gives the size of each part, in this order. The orientation
is the mass-weighted best-fit rotation *R* of the rest shape onto the current shape (Kabsch); its
first two columns are the body's forward and up vectors (a continuous 6-D representation of the
rotation; at rest (1, 0, 0) and (0, 1, 0)).

{table}

The unit vectors, the applied contraction and the gait phase lie in [-1, 1] by construction
(clipped there against rounding; `soft_envs.envs.observation.BOUNDED_PARTS`). The other parts
have no bound the environment can promise, so their bounds are -Inf and Inf:

- COM x and z: the environment never truncates (`gym.make`'s `TimeLimit` does), so a robot may
  walk on without limit.
- COM height: the ground keeps it above 0 in practice, but contact is a penalty (the feet sink in
  a little), not a hard floor, and nothing bounds it from above.
- COM velocity: the reset noise alone gives up to `reset_noise_scale` / the physics step (any
  value, with the keyword), and no part of the model caps the speed of a fall.
- cable deformation: it grows with the body's stretch, which the neo-Hookean material does not
  cap; below, the only bound (a cable's length is not negative) is never approached.
- node positions: the body's deformation is not capped either.

`info` holds `com`, `x_position`, `z_position`, `displacement` (COM minus the COM at
reset), `yaw` (rad, from +x towards +z: clockwise seen from above), `tilt_deg`, `time`, `u`,
`motor_torque`, `is_healthy` and, after a step, `forward_velocity` (body lengths per second along the
target heading), `yaw_rate` (rad/s, > 0 turning right), `u_substeps`, `motor_limited` and the reward terms.
"""


def _rewards_to_episode_end(r: RobotDoc) -> str:
    return r"""## Rewards
The total reward is: ***reward*** *=* *healthy_reward + forward_reward - ctrl_cost*.

- *forward_reward* (`info["reward_forward"]`): task progress times `forward_reward_weight`.
  With `task="walk"`, the speed of the COM along the target heading
  (`target_heading_deg`, 0 = +x) in body lengths per second over the step,
  $w_{forward} \times \frac{\Delta c \cdot d}{dt \cdot L}$ (*dt* = `env.unwrapped.dt`, the duration of the step) with *L* = """ \
        + f"{r.body_length_m:g} m." + r"""
  With `task="turn"`, the yaw rate (rad/s) in the requested direction (`turn_direction`,
  right = clockwise seen from above) times `turn_radius` / *L*, i.e. the speed in body
  lengths per second of a point at `turn_radius` from the turning centre (default radius *L*).
- *ctrl_cost* (`info["reward_ctrl"]` = -ctrl_cost): $w_{control} \times \sum ((a + 1) / 2)^2$,
  the squared commanded contraction as a fraction of its range (no cost at a = -1, slack).
- *healthy_reward* (`info["reward_survive"]`): `healthy_reward` in every step in which the
  robot is healthy (see Episode End).

With the defaults, walking at the paper's simulated speeds (6-9 body lengths per minute,
0.1-0.15 BL/s) earns a forward reward of 1-1.5 per step, against 0.1 for staying upright
and at most 0.01 per fully pulled motor.

## Starting State
The rest state: the robot standing still on the ground with no contraction (static
equilibrium, computed once per physical parameter set; on an incline, under the normal
component of gravity, see `Simulator.rest_state`). Node positions get uniform noise
$\mathcal{U}[-s, s]$ with *s* = `reset_noise_scale` metres, and the previous positions
another $\mathcal{U}[-s, s]$ (so velocities are perturbed by up to *s* / timestep).
All randomness comes from `self.np_random` (seeded by `reset(seed=...)`).

## Episode End
### Termination
- If `terminate_when_unhealthy` (default), when the robot is unhealthy: its up vector tilts
  more than `healthy_tilt_deg` (60) degrees from +y, or its COM is lower than
  `healthy_height_fraction` (0.5) of its rest height (the robot fell over). On a `ground=` height
  field the tilt is from the normal of the field's plane part and both heights are above the
  ground under the COM (`soft_envs.envs.ground_reference`).
- Always, when the simulation fails (the Newton solver raises `SimulationError`): the step
  returns `terminated=True`, reward 0, `info["sim_failure"]` with the reason, and the
  environment's state is left as it was before the step.

### Truncation
`gymnasium.make` wraps the environment in a `TimeLimit` of `max_episode_steps` = 300
environment steps (`soft_envs.MAX_EPISODE_STEPS`; 10 s at `frame_skip=1`, about four of the
paper's gait cycles); `gym.make(..., max_episode_steps=N)` changes it. The environment
itself never truncates. The RL baseline (`trajopt rl train`) passes 168, trajopt's
optimisation horizon (24 prep steps + 2 cycles of 72), so both methods see the same episodes.
"""


def _arguments(r: RobotDoc) -> list[tuple[str, str, str, str]]:
    """The rows of the Arguments table: the keywords of ``SoftRobotEnv.__init__``."""
    return [
        ("`robot`", "**str \\| Path \\| Robot**", f'`"{r.name}"`',
         "shipped robot name, a `robot.toml` path "
         + (f"(e.g. the fine mesh `assets/{r.name}/robot_fine.toml`) " if "v0" in r.versions else "")
         + "or a "
         "`Robot`; sizes in the tables above change accordingly"),
        ("`frame_skip`", "**int**", "`1`", "control steps per environment step; `env.unwrapped.dt = frame_skip * timestep`"),
        ("`timestep`", "**float**", "`0.033`",
         "control step [s] (`env.unwrapped.timestep`, `env.unwrapped.simulator.dt`; the paper's h): the motors' "
         "and the gradient hooks' step"),
        ("`substeps`", "**int \\| None**", "`None`",
         "physics steps per control step (implicit Euler of `timestep / substeps`, the contraction moving at a "
         "constant speed within the step); `None`: the contact law's default, 4 for `\"coulomb\"` (8.25 ms, where "
         "the gaits' speeds converge: docs/fidelity.md), 1 for `\"paper\"` (its friction is defined at 33 ms); "
         "`env.unwrapped.substeps`"),
        ("`task`", "**str**", '`"walk"`', '`"walk"` (speed along the target heading) or `"turn"` (yaw rate)'),
        ("`target_heading_deg`", "**float**", "`0`",
         "walking direction, degrees from +x towards +z (90 = +z, the robot's right; the convention of `trajopt`); "
         "also the uphill direction"),
        ("`turn_direction`", "**str**", '`"right"`',
         '`"right"` (clockwise seen from above) or `"left"`; only with `task="turn"`'),
        ("`turn_radius`", "**float \\| None**", "`None`",
         "radius [m] converting yaw rate to speed in the turn reward; `None` = body length"),
        ("`incline_deg`", "**float**", "`0`",
         "ground slope, rising along the target heading (gravity is rotated, `incline_gravity`)"),
        ("`forward_reward_weight`", "**float**", "`10`", "weight of *forward_reward*"),
        ("`ctrl_cost_weight`", "**float**", "`0.01`", "weight of *ctrl_cost*"),
        ("`healthy_reward`", "**float**", "`0.1`", "reward per healthy step"),
        ("`terminate_when_unhealthy`", "**bool**", "`True`", "terminate when the robot falls over"),
        ("`healthy_tilt_deg`", "**float**", "`60`", "largest tilt of the up vector from +y that is healthy [deg]"),
        ("`healthy_height_fraction`", "**float**", "`0.5`", "lowest healthy COM height as a fraction of the rest height"),
        ("`reset_noise_scale`", "**float**", "`1e-4`",
         "half-width [m] of the uniform noise on initial positions and previous positions"),
        ("`motor_speed_rpm`", "**str \\| float \\| None**", '`"robot"`',
         "motor output speed limit [rpm] (times the spool radius: the contraction speed limit); "
         "`\"robot\"`: the robot's `[[motors]] max_speed_rpm` (100 rpm for the shipped robots); a number "
         "overrides it; `None`: no speed limit (the torque limit of `\"torque-speed\"` still holds); the "
         "no-load speed of `motor_model`'s line"),
        ("`motor_model`", "**str**", '`"torque-speed"`',
         "the motors' law (Action Space): `\"torque-speed\"` (a DC gearmotor's torque-speed line at the load "
         "torque and its gearbox's `max_torque`), `\"speed\"` (the speed limit alone), `\"ideal\"` (no limit). "
         + (f"`{r.env_name}-v0` and `{r.env_name}-v1` pass `\"speed\"` (their dynamics are kept); "
            if "v0" in r.versions else "") + "`soft_envs.sim.motors`"),
        ("`gait_period`", "**float**", "`2.376`", "period [s] of the gait-phase observation (the paper's cycle: 72 steps)"),
        ("`observe_nodes`", "**bool**", "`False`", "append all node positions relative to the COM to the observation"),
        ("`domain_randomization`", "**dict \\| bool \\| None**", "`None`",
         "multiplicative factors drawn uniformly at each reset (from `np_random`, keys in sorted order) for "
         "`friction`, `contact_stiffness`, `youngs_modulus`, `density`, `payload_mass`, as `{key: (low, high)}`, "
         "e.g. `{\"friction\": (0.7, 1.3)}`; `True`: `soft_envs.envs.DEFAULT_DOMAIN_RANDOMIZATION` = "
         "friction (0.7, 1.3), youngs_modulus (0.8, 1.2), density (0.9, 1.1), payload_mass (0.9, 1.1); "
         "`None` or `False`: the nominal robot. `env.unwrapped.domain_parameters` holds the episode's factors"),
        ("`contact`", "**str \\| None**", "`None`",
         "ground contact law: `\"coulomb\"` (Coulomb friction bounded by `friction_coefficient` x the "
         "normal force, feet held by stick anchors: `soft_envs.sim.contact.coulomb`; the shipped robot "
         "files' default), `\"paper\"` (paper II-C: viscous-like lagged friction, what Table I was made with), "
         f"or `None` for the robot file's `[contact] model`. `{r.env_name}-v2`, the latest id, passes "
         f"`\"coulomb\"` (`gym.make(\"{r.env_name}-v2\", contact=\"paper\")` for the paper's law)"
         + (f"; `{r.env_name}-v0` passes `\"paper\"` (Table I), `{r.env_name}-v1` `\"coulomb\"` at one physics step"
            if "v0" in r.versions else "")),
        ("`ground`", "**HeightField \\| None**", "`None`",
         "the ground's surface, a `soft_envs.sim.ground.HeightField` (rough terrain, a step, a trench; "
         "`soft_envs.sim.ground`); `None`: the robot file's `[ground]`, or the plane y = 0 without one"),
        ("`render_mode`", "**str \\| None**", "`None`",
         '`"rgb_array"` (uint8 frames, offscreen matplotlib, no OpenGL) or `"human"` (matplotlib window)'),
        ("`width`, `height`", "**int**", "`480`, `360`", "frame size in pixels"),
        ("`camera_config`", "**dict \\| None**", "`None`",
         "extra keyword arguments of `soft_envs.render.Renderer` (`elevation`, `azimuth`, `distance`, ...)"),
    ]


#: joins a method's arguments so that the hooks paragraph is not wrapped inside one (a space after)
_KEEP_TOGETHER = ",\N{NO-BREAK SPACE}"


def _member(name: str) -> str:
    """``name`` of a property, ``name(arguments)`` of a method of :class:`GradientEnv` (or,
    for an optional member, of the environments' :class:`~.hooks.GradientHooksMixin`)."""
    attr = inspect.getattr_static(GradientEnv, name, None) or inspect.getattr_static(GradientHooksMixin, name)
    if attr is None or isinstance(attr, property):
        return f"`{name}`"
    args, star = [], False
    for p in list(inspect.signature(attr).parameters.values())[1:]:          # without self
        if p.kind is p.KEYWORD_ONLY and not star:
            args.append("*")
            star = True
        args.append(p.name if p.default is p.empty else f"{p.name}={p.default!r}")
    return f"`{name}({_KEEP_TOGETHER.join(args)})`"


def _arguments_section(r: RobotDoc) -> str:
    table = markdown_table(("Parameter", "Type", "Default", "Description"), _arguments(r))
    hooks = ", ".join(_member(m) for m in GRADIENT_ENV_MEMBERS)
    optional = ", ".join(_member(m) for m in PARAMETER_MEMBERS)
    hooks_paragraph = textwrap.fill(
        f"Gradient hooks for trajectory optimisation (`soft_envs.envs.GradientEnv`) are on `env.unwrapped`: "
        f"{hooks} (`rollout` takes one row of `u` per simulation step, in metres of cable contraction); for "
        f"calibration {optional}; also `simulator`, `action_to_control()`, `control_to_action()` and "
        "`domain_parameters`.", width=95, break_on_hyphens=False, break_long_words=False).replace(_KEEP_TOGETHER, ", ")
    return f"""## Arguments
```python
import gymnasium as gym
import soft_envs
{r.example}
```

{table}

`gymnasium.make` also takes `max_episode_steps` (default 300, see Truncation).

{hooks_paragraph}
"""


def _version_section(r: RobotDoc) -> str:
    if "v0" not in r.versions:
        return f"""## Version History
* v2: Initial version of `{r.env_name}`, registered at the version of the physics it was
  shipped with, that of `SoftTripod-v2` and `SoftPuppy-v2` (there is no `{r.env_name}-v0` or
  `-v1`): every contact law at its own number of physics steps per 0.033 s control step
  (`substeps=None`: 4 for the Coulomb law, 1 for the paper's law), the Coulomb law by default
  and the motors on their torque-speed line (`motor_model="torque-speed"`).
"""
    return """## Version History
* v0: Initial version. Since then, without a new id (the dynamics and rewards are
  unchanged): `env.unwrapped.dt` is the duration of an environment step, as in Gymnasium's
  MuJoCo environments (it was the simulation step, now `env.unwrapped.timestep`; the two are
  equal at the default `frame_skip=1`), and `domain_randomization=True` selects the
  default ranges.
* v1: the Coulomb contact law (`contact="coulomb"`: friction bounded by mu N with
  mu = 0.8, feet that stick; the `friction` factor of domain randomisation scales mu).
  Observations, actions and rewards as in v0. The stick anchors are part of the state
  (`get_state()["history"]`). Since the shipped robot files default to the Coulomb law,
  v0 passes `contact="paper"` explicitly and keeps the paper's law; v1 passes
  `substeps=1` and keeps one physics step of 0.033 s per control step.
* v2: converged physics, the latest id and the project's default: every contact law at its
  own number of physics steps per 0.033 s control step (`substeps=None`: 4 for the Coulomb
  law, where the fast gaits' speeds hold at finer steps; 1 for the paper's law). Actions,
  observations (the COM velocity over the last physics step) and rewards as in v1.
  The motors' law came without a new id: v0 and v1 pass `motor_model="speed"` and keep the
  speed limit alone; `info` gained `motor_torque` and `motor_limited` on every id.
* v2 also puts the motors on their torque-speed line (`motor_model="torque-speed"`, the class's
  default: the winding speed falls with the load torque, which stops at `max_torque`).
* Without a new id, on every id: the observation space bounds the unit vectors, the applied
  contraction and the gait phase by -1 and 1 (it was -Inf, Inf throughout); the observations
  are the same, clipped into [-1, 1] against rounding.
"""


def env_docstring(r: RobotDoc) -> str:
    """The class docstring of robot ``r``'s environment (module docstring)."""
    description = f"""## Description
{r.description.strip()}

Units are SI with +y up and the ground at y = 0; the robot faces +x at rest and its left
is -z. One environment step is `frame_skip` control steps of `timestep` = 0.033 s, each of
`substeps` physics steps; as in Gymnasium's MuJoCo environments, `env.unwrapped.dt` is the
duration of one environment step, `frame_skip * timestep`, and the control step is
`env.unwrapped.timestep` (`env.unwrapped.simulator.dt`).
"""
    return "\n".join([description, _action_section(r), _observation_section(r), _rewards_to_episode_end(r),
                      _arguments_section(r), _version_section(r)])
