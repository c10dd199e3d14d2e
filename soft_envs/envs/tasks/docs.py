"""The specification of each benchmark task, in Gymnasium's MuJoCo layout (Description, Action
Space, Observation Space, Rewards, Starting State, Episode End, Arguments, Version History):
:data:`TASK_DOCS` holds what differs between tasks, :func:`task_docstring` writes the rest. The
robot's own parts (its motors, tendons, observation) are the robot environment's
(:class:`~soft_envs.envs.tripod.SoftTripodEnv`, :class:`~soft_envs.envs.puppy.SoftPuppyEnv`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..env_docs import markdown_table
from ..puppy import DOC as PUPPY
from ..tripod import DOC as TRIPOD
from .difficulty import LEVELS, SCALES

__all__ = ["TaskDoc", "TASK_DOCS", "TASK_STEMS", "task_docstring"]

ROBOTS = (TRIPOD, PUPPY)


@dataclass(frozen=True)
class TaskDoc:
    """One task's specification: ``key`` (of :data:`~.difficulty.LEVELS`), ``stem`` (the ids'
    middle: ``SoftTripod<stem>-v0``), ``description``, ``observation`` (rows ``(part, size, what,
    unit)`` appended after the robot's), ``forward`` (what the forward reward measures),
    ``success`` (when the task succeeds, or "" for none), ``levels`` (difficulty -> what it sets,
    in words), ``arguments`` (rows of the task's own keywords), ``owned`` (the robot keywords
    the task sets), ``termination`` (an end of the task's own, or "") and ``extra_reward`` (a reward
    term of the task's own: its name in the formula and its bullet, or empty)."""

    key: str
    stem: str
    description: str
    forward: str
    levels: dict[str, str]
    owned: tuple[str, ...]
    observation: tuple[tuple[str, int, str, str], ...] = ()
    success: str = ""
    arguments: tuple[tuple[str, str, str, str], ...] = ()
    termination: str = ""
    extra_reward: tuple[str, str] = ("", "")


def _dr(v) -> str:
    if v is None:
        return "none: the nominal robot"
    return ", ".join(f"{k} x U({lo:g}, {hi:g})" for k, (lo, hi) in sorted(v.items()))


def _per_level(key: str, fmt) -> dict[str, str]:
    return {name: fmt(values) for name, values in LEVELS[key].items()}


#: the robot keywords a terrain task sets itself (its ``owned``)
TERRAIN_OWNED = ("task", "ground", "target_heading_deg", "incline_deg")
_TERRAIN_PART = (("terrain", 3, "COM height above the ground under it; the ground's height 0.5 and 1 body length "
                  "ahead (along the body's forward vector in the ground plane) minus the ground's under the COM",
                  "position (m)"),)
def _in_mm(length_bl: float, digits: int) -> str:
    """``"0.1 L (Tripod 14.0 mm, Puppy 13.0 mm)"``: a length in body lengths and on each robot."""
    return (f"{length_bl:g} L (Tripod {1e3 * length_bl * TRIPOD.body_length_m:.{digits}f} mm, Puppy "
            f"{1e3 * length_bl * PUPPY.body_length_m:.{digits}f} mm)")


_BOX_PARTS = (("box_offset", 3, "the box's centre minus the COM (world frame)", "position (m)"),
              ("box_velocity", 3, "the box centre's velocity over the last physics step", "velocity (m/s)"),
              ("box_axes", 6, "the box's x axis, then its y axis, in the world frame", "unit vector"))
_WALK = "the COM's speed along the target heading (`target_heading_deg`, 0 = +x) in body lengths per second"
_SUCCESS_ARGS = (("`success_reward`", "**float**", "`10`", "reward of the step that first succeeds"),
                 ("`terminate_on_success`", "**bool**", "`True`", "a success ends the episode (`terminated=True`)"))

TASK_DOCS = {
    "walk": TaskDoc(
        "walk", "Walk", "Walk forward (+x at rest, or along `target_heading_deg`) on the plane, as fast as "
        "possible, with the physical parameters of each episode drawn within the level's ranges.",
        _WALK, _per_level("walk", lambda v: _dr(v["domain_randomization"])), ("task", "domain_randomization")),
    "turn": TaskDoc(
        "turn", "Turn", "Turn on the spot (`turn_direction`: right, clockwise seen from above, by default) on the "
        "plane, with the physical parameters of each episode drawn within the level's ranges.",
        "the yaw rate in `turn_direction` times `turn_radius` (default one body length), in body lengths per "
        "second", _per_level("turn", lambda v: _dr(v["domain_randomization"])), ("task", "domain_randomization")),
    "slope_up": TaskDoc(
        "slope_up", "SlopeUp", "Walk up a slope rising along the target heading (+x): gravity is rotated by "
        "`incline_deg` (the ground stays the plane y = 0 of the robot's frame).",
        _WALK + " (up the slope)", _per_level("slope_up", lambda v: f"{v['incline_deg']:g} degrees"),
        ("task", "incline_deg", "ground")),
    "slope_down": TaskDoc(
        "slope_down", "SlopeDown", "Walk down a slope falling along the target heading (+x), without tumbling: "
        "gravity is rotated by `incline_deg` < 0.",
        _WALK + " (down the slope)", _per_level("slope_down", lambda v: f"{v['incline_deg']:g} degrees"),
        ("task", "incline_deg", "ground")),
    "rough_terrain": TaskDoc(
        "rough_terrain", "RoughTerrain", "Walk along +x over rough ground: a height field of 16 random plane waves "
        "(`HeightField.rough`) of wavelength 0.4 body lengths, a new one at each reset (its seed drawn from "
        "`np_random`) unless `terrain_seed` fixes it.",
        _WALK, _per_level("rough_terrain", lambda v: f"RMS height {_in_mm(v['amplitude_bl'], 1)}"),
        TERRAIN_OWNED, _TERRAIN_PART,
        arguments=(("`terrain_seed`", "**int \\| None**", "`None`",
                    "seed of a fixed terrain; `None`: a new terrain at each reset, its seed from `np_random` "
                    "(`info[\"terrain_seed\"]`; redrawn, at most 10 times, when the robot cannot be placed at rest "
                    "on it: `info[\"terrain_draws\"]`)"),)),
    "climb_step": TaskDoc(
        "climb_step", "ClimbStep", "Walk along +x and climb a step (`HeightField.step`, its edge smoothed over "
        "0.07 body lengths) whose foot is 0.15 body lengths ahead of the robot's front at rest.",
        _WALK, _per_level("climb_step", lambda v: f"step height {_in_mm(v['height_bl'], 1)}"),
        TERRAIN_OWNED, _TERRAIN_PART,
        "the COM is half a body length beyond the step's top edge (`env.unwrapped.finish_x`) and the robot "
        "healthy", _SUCCESS_ARGS),
    "cross_trench": TaskDoc(
        "cross_trench", "CrossTrench", "Walk along +x across a trench 0.05 body lengths deep "
        "(`HeightField.trench`, edges smoothed over 0.07 body lengths) whose near edge is 0.15 body lengths "
        "ahead of the robot's front at rest.",
        _WALK, _per_level("cross_trench", lambda v: f"trench length {_in_mm(v['length_bl'], 0)}"),
        TERRAIN_OWNED, _TERRAIN_PART,
        "the COM is half a body length beyond the trench's far edge (`env.unwrapped.finish_x`) and the robot "
        "healthy", _SUCCESS_ARGS),
    "reach_goal": TaskDoc(
        "reach_goal", "ReachGoal", "Walk to a goal point on the plane, drawn at each reset from `np_random`: "
        "at the level's distance from the COM, in a direction uniform within the level's angle of +x (the "
        "robot's forward direction at rest). `env.unwrapped.goal` is the goal.",
        "the speed towards the goal (the decrease of the COM's horizontal distance to it over the step, in body "
        "lengths per second)",
        _per_level("reach_goal", lambda v: f"{v['distance_bl']:g} body lengths away, direction within "
                   f"+-{v['half_angle_deg']:g} degrees of +x"),
        ("task", "target_heading_deg", "turn_direction", "turn_radius"),
        (("goal_offset", 2, "goal minus COM, x and z (world frame)", "position (m)"),),
        "the COM is within `goal_radius_bl` body lengths of the goal (horizontally) and the robot healthy",
        (("`goal_radius_bl`", "**float**", "`0.25`", "success radius [body lengths]"),
         ("`forward_reward_weight`", "**float**", "`10`", "weight of *forward_reward* (progress towards the goal)"),
         *_SUCCESS_ARGS)),
    "carry": TaskDoc(
        "carry", "Carry", "Walk along +x carrying a payload, a stiff box resting on the robot's top (0.6 x 0.1 body "
        "lengths, 1.1 times the robot's width across; a second body in the same implicit solve, held by contact "
        "and Coulomb friction with the robot's nodes), without dropping it. `env.unwrapped.box` is the box; the "
        "gradient hooks (`rollout` with `dudz`) differentiate through it.",
        _WALK, _per_level("carry", lambda v: f"payload {v['mass_fraction']:g} of the robot's mass, friction "
                          f"coefficient {v['friction_coefficient']:g} on the robot"),
        ("task", "target_heading_deg"), _BOX_PARTS,
        arguments=(("`drop_penalty`", "**float**", "`10`", "subtracted in the step the payload falls "
                    "(`info[\"reward_drop\"]`)"),
                   ("`fall_height_fraction`", "**float**", "`0.5`", "the payload falls when its centre's height "
                    "above the ground drops below this fraction of its height at rest"),
                   ("`fall_tilt_deg`", "**float**", "`60`", "... or when its y axis tilts more than this from +y")),
        extra_reward=("drop_reward", "*drop_reward* (`info[\"reward_drop\"]`): `-drop_penalty` (-10) in the step "
                      "the payload falls, else 0."),
        termination="The payload falls (`info[\"payload_fell\"]`, `fall_height_fraction`, `fall_tilt_deg`), "
        "whatever `terminate_when_unhealthy` says; its step adds `-drop_penalty`."),
    "push_box": TaskDoc(
        "push_box", "PushBox", "Push a stiff box (0.25 x 0.25 body lengths, 1.2 times the robot's width across) "
        "standing on the ground 0.1 body lengths ahead of the robot's front along +x: a second body in the same "
        "implicit solve, sliding on the ground under the robot's contact law, pushed by the robot's nodes. "
        "`env.unwrapped.box` is the box; the gradient hooks (`rollout` with `dudz`) differentiate through it.",
        "the box's speed along +x (its centre's displacement over the step, in body lengths per second)",
        _per_level("push_box", lambda v: f"box {v['mass_fraction']:g} of the robot's mass"),
        ("task", "target_heading_deg"), _BOX_PARTS,
        "the box has moved `push_distance_bl` body lengths along +x since the reset and the robot is healthy",
        (("`push_distance_bl`", "**float**", "`0.5`", "how far the box must move along +x [body lengths]"),
         ("`forward_reward_weight`", "**float**", "`10`", "weight of *forward_reward* (the box's speed)"),
         *_SUCCESS_ARGS)),
}
#: task key -> id stem
TASK_STEMS = {key: doc.stem for key, doc in TASK_DOCS.items()}

_BASE_PARTS = (("com_position", "COM x, height (y), z; x and z relative to the COM at reset", "position (m)",
                "-Inf", "Inf"),
               ("com_velocity", "COM velocity over the last physics step", "velocity (m/s)", "-Inf", "Inf"),
               ("forward_vector", "the body's forward vector R e_x", "unit vector", "-1", "1"),
               ("up_vector", "the body's up vector R e_y", "unit vector", "-1", "1"),
               ("cable_deformation", "each tendon's cable deformation / its motor's range", "dimensionless",
                "-Inf", "Inf"),
               ("contraction", "each motor's applied contraction, scaled like the actions", "dimensionless",
                "-1", "1"),
               ("gait_phase", "sin, cos of 2 pi t / gait_period", "dimensionless", "-1", "1"),
               ("nodes", "only with `observe_nodes=True`: node positions minus the COM, 3 n_nodes entries "
                "(none by default; the task's parts then follow them)", "position (m)", "-Inf", "Inf"))


def _span(start: int, size: int) -> str:
    return str(start) if size == 1 else f"{start}-{start + size - 1}"


def _observation_rows(t: TaskDoc) -> list[tuple[str, ...]]:
    sizes = {r.name: {"com_position": 3, "com_velocity": 3, "forward_vector": 3, "up_vector": 3,
                      "cable_deformation": r.n_tendons, "contraction": r.n_motors, "gait_phase": 2} for r in ROBOTS}
    rows, at = [], {r.name: 0 for r in ROBOTS}
    parts = [(name, what, unit, lo, hi) for name, what, unit, lo, hi in _BASE_PARTS] + \
            [(name, what, unit, "-Inf", "Inf") for name, _, what, unit in t.observation]
    extra = {name: size for name, size, _, _ in t.observation}
    for name, what, unit, lo, hi in parts:
        cells = []
        if name == "nodes":
            rows.append(("-", "-", f"`{name}`: {what}", lo, hi, unit))
            continue
        for r in ROBOTS:
            n = sizes[r.name].get(name, extra.get(name))
            cells.append(_span(at[r.name], n))
            at[r.name] += n
        rows.append((*cells, f"`{name}`: {what}", lo, hi, unit))
    return rows


def task_docstring(t: TaskDoc) -> str:
    """The class docstring of task ``t`` (module docstring)."""
    ids = ", ".join(f"`{r.env_name}{t.stem}-v0`" for r in ROBOTS)
    n_obs = {r.name: r.n_observations + sum(s for _, s, _, _ in t.observation) for r in ROBOTS}
    action_rows = [(f"`{r.env_name}{t.stem}-v0`", f"`Box(-1, 1, ({r.n_motors},), float32)`",
                    ", ".join(name for _, name in r.actions)) for r in ROBOTS]
    obs_table = markdown_table(("Tripod", "Puppy", "Observation (`observation_structure` part)", "Min", "Max",
                                "Type (Unit)"), _observation_rows(t))
    success = (f"\n- *success_reward* (`info[\"reward_success\"]`): `success_reward` (10) in the step in which "
               f"the task first succeeds: {t.success}; `info[\"is_success\"]` says whether it has."
               if t.success else
               "\n- *success_reward* (`info[\"reward_success\"]`): always 0 (this task has no success; "
               "`info[\"is_success\"]` is False).")
    level_rows = [(f'`"{k}"`' + (" (default)" if k == "medium" else ""), v) for k, v in t.levels.items()]
    args = [("`difficulty`", "**str**", '`"medium"`', f'`"easy"`, `"medium"` or `"hard"`: {SCALES[t.key]}'),
            *t.arguments]
    if not t.success:
        args.append(("`success_reward`, `terminate_on_success`", "**float**, **bool**", "`10`, `True`",
                     "accepted for a common signature; unused (no success)"))
    owned = ", ".join(f"`{k}`" for k in t.owned)
    extra_term = f" + {t.extra_reward[0]}" if t.extra_reward[0] else ""
    extra_bullet = f"\n- {t.extra_reward[1]}" if t.extra_reward[1] else ""
    ends = ("\n- Success, with `terminate_on_success` (default True)." if t.success else "") + \
        (f"\n- {t.termination}" if t.termination else "")
    return f"""## Description
{t.description}

Ids: {ids} (the robot's `-v2` physics: Coulomb contact at 4 physics steps per 33 ms control
step, motors on their torque-speed line). A task is the robot environment
(`soft_envs.envs.SoftTripodEnv`, `soft_envs.envs.SoftPuppyEnv`) with the keywords its difficulty
sets, the observation parts and reward terms below; docs/tasks.md lists every task.

## Action Space
As the robot environment's (its Action Space section: the per-motor table and the motors' law):
action *a* in [-1, 1] commands each motor's cable contraction.

{markdown_table(("Id", "Action space", "Motors (robot.toml order)"), action_rows)}

## Observation Space
A `Box(low, high, (n,), float64)`: n = {n_obs['tripod']} for the Tripod, n = {n_obs['puppy']} for the
Puppy. The robot environment's parts (its Observation Space section), then the task's; the first
two columns are each part's entries.

{obs_table}

`info` holds the robot environment's entries, the reward terms and `is_success`{_info_entries(t.key)}.

## Rewards
***reward*** *= healthy_reward + forward_reward - ctrl_cost + success_reward{extra_term}*

- *forward_reward* (`info["reward_forward"]`): `forward_reward_weight` (10) times {t.forward}.
- *ctrl_cost* (`info["reward_ctrl"]` = -ctrl_cost): `ctrl_cost_weight` (0.01) times the sum of
  ((a + 1) / 2)^2, the commanded contraction as a fraction of its range.
- *healthy_reward* (`info["reward_survive"]`): `healthy_reward` (0.1) in every healthy step.{success}{extra_bullet}

## Starting State
The robot at rest on the task's ground, with `reset_noise_scale` noise on the positions; the
task's draws (physical parameters, terrain, goal) come from `self.np_random` too, so
`reset(seed=...)` replays an episode bit for bit.

## Episode End
### Termination
- Unhealthy (`terminate_when_unhealthy`, default True): the body's up vector tilts more than
  `healthy_tilt_deg` (60) from the ground's normal, or the COM's height above the ground under
  it falls below `healthy_height_fraction` (0.5) of its height at rest, measured the same way
  (`soft_envs.envs.ground_reference`).
- The simulation fails (`info["sim_failure"]`, reward 0).{ends}

### Truncation
`gymnasium.make`'s `TimeLimit`: 300 steps (`soft_envs.MAX_EPISODE_STEPS`, 10 s).

## Arguments
```python
import gymnasium as gym
import soft_envs
env = gym.make("SoftTripod{t.stem}-v0", difficulty="hard")
```

`difficulty` sets ({SCALES[t.key]}):

{markdown_table(("difficulty", "what it sets"), level_rows)}

{markdown_table(("Parameter", "Type", "Default", "Description"), args)}

Every other keyword of the robot environment (its Arguments table) is accepted and passed on,
except those the task sets: {owned} (a ValueError names it).

## Version History
* v0: Initial version (issue #39).
"""


#: the task's own ``info`` entries
_INFO = {"walk": (), "turn": (), "slope_up": ("incline_deg",), "slope_down": ("incline_deg",),
         "rough_terrain": ("height_above_ground", "terrain_seed", "terrain_draws"),
         "climb_step": ("height_above_ground",), "cross_trench": ("height_above_ground",),
         "reach_goal": ("goal", "goal_distance"),
         "carry": ("box_position", "box_displacement", "box_tilt_deg", "payload_fell", "payload_height"),
         "push_box": ("box_position", "box_displacement", "box_tilt_deg", "box_pushed")}


def _info_entries(key: str) -> str:
    names = _INFO[key]
    return "" if not names else ", and this task's " + ", ".join(f"`{n}`" for n in names)
