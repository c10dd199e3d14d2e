"""``SoftTripod-v0`` / ``SoftTripod-v1``: the two-motor Tripod of Bern et al. (RSS 2019), section IV-A."""
from __future__ import annotations

import os
from typing import Any

from ..sim import Robot
from .base import SoftRobotEnv

__all__ = ["SoftTripodEnv"]


class SoftTripodEnv(SoftRobotEnv):
    r"""
    ## Description
    The *Tripod* of Bern, Banzet, Poranne and Coros, "Trajectory optimization for cable-driven
    soft robot locomotion" (Robotics: Science and Systems 2019), section IV-A: a 14 cm foam
    body (24 g) with three legs and a 44 g motor assembly on top, simulated with linear
    tetrahedral finite elements (neo-Hookean foam, about 150 nodes in the shipped mesh),
    implicit Euler time stepping, ground contact with friction, and cables modelled as
    one-sided springs.
    Two motors drive the middle leg, each through a pair of cables: `front` bends it forward,
    `back` bends it backward, both together lift it. The two outer legs are passive. The goal is
    to walk forward (+x at rest) or, with `task="turn"`, to turn on the spot.

    Units are SI with +y up and the ground at y = 0; the robot faces +x at rest and its left
    is -z. One environment step is `frame_skip` simulation steps of `timestep` = 0.033 s; as in
    Gymnasium's MuJoCo environments, `env.unwrapped.dt` is the duration of one environment step,
    `frame_skip * timestep`, and the simulation step is `env.unwrapped.timestep`
    (`env.unwrapped.simulator.dt`).

    ## Action Space
    The action space is a `Box(-1, 1, (2,), float32)`. Action *a* commands the cable
    contraction (metres of cable pulled in by the motor) `u_cmd = u_min + (a + 1) / 2 (u_max - u_min)`;
    values outside [-1, 1] are clipped, NaN/inf or a wrong shape raise `ValueError`.
    The applied contraction follows the command at the motor's speed limit: in every
    simulation step it moves towards `u_cmd` by at most `v_max * timestep`, with
    `v_max = motor_speed_rpm * 2 pi / 60 * spool_radius` (Pololu 298:1 micro metal gearmotor,
    about 100 rpm no-load at 6 V, spool radius 5 mm: 52 mm/s, 1.7 mm per step; the full
    16 mm stroke of the shipped robot.toml takes 10 steps). `info["u"]` is the contraction
    applied at the end of the step and `info["u_substeps"]` (frame_skip, 2) the contraction of
    each simulation step.

    | Num | Action                                  | Control Min | Control Max | Name (robot.toml) | Type (Unit)       |
    |-----|-----------------------------------------|-------------|-------------|-------------------|-------------------|
    | 0   | Contraction of the middle leg's front cables (bends it forward) | -1 (u_min = 0) | 1 (u_max = 16 mm) | front | cable length (m) |
    | 1   | Contraction of the middle leg's back cables (bends it backward) | -1 (u_min = 0) | 1 (u_max = 16 mm) | back  | cable length (m) |

    ## Observation Space
    A `Box(-Inf, Inf, (20,), float64)`; `env.unwrapped.observation_structure` gives the
    size of each part. The orientation is the mass-weighted best-fit rotation *R* of the rest
    shape onto the current shape (Kabsch); its first two columns are the body's forward and
    up vectors (a continuous 6-D representation of the rotation; at rest (1, 0, 0) and (0, 1, 0)).

    | Num   | Observation                                                   | Min  | Max | Type (Unit)              |
    |-------|---------------------------------------------------------------|------|-----|--------------------------|
    | 0     | COM x relative to the COM at reset                            | -Inf | Inf | position (m)             |
    | 1     | COM height above the ground (y)                               | -Inf | Inf | position (m)             |
    | 2     | COM z relative to the COM at reset                            | -Inf | Inf | position (m)             |
    | 3-5   | COM velocity (x, y, z) over the last simulation step          | -Inf | Inf | velocity (m/s)           |
    | 6-8   | forward vector R e_x (world frame)                            | -1   | 1   | unit vector              |
    | 9-11  | up vector R e_y (world frame)                                 | -1   | 1   | unit vector              |
    | 12-15 | cable deformation Gamma of front_a, front_b, back_a, back_b divided by the motor's range u_max - u_min (> 0 stretched, < 0 slack) | -Inf | Inf | dimensionless |
    | 16-17 | applied contraction of front, back, scaled like the actions    | -1   | 1   | dimensionless            |
    | 18-19 | gait phase sin, cos of 2 pi t / gait_period (t since reset)    | -1   | 1   | dimensionless            |
    | 20-...| only with `observe_nodes=True`: node positions minus the COM, (n_nodes, 3) flattened: 3 n_nodes values (`env.unwrapped.robot.mesh.n_nodes`) | -Inf | Inf | position (m) |

    `info` holds `com`, `x_position`, `z_position`, `displacement` (COM minus the COM at
    reset), `yaw` (rad, from +x towards +z: clockwise seen from above), `tilt_deg`, `time`, `u`,
    `is_healthy` and, after a step, `forward_velocity` (body lengths per second along the
    target heading), `yaw_rate` (rad/s, > 0 turning right), `u_substeps` and the reward terms.

    ## Rewards
    The total reward is: ***reward*** *=* *healthy_reward + forward_reward - ctrl_cost*.

    - *forward_reward* (`info["reward_forward"]`): task progress times `forward_reward_weight`.
      With `task="walk"`, the speed of the COM along the target heading
      (`target_heading_deg`, 0 = +x) in body lengths per second over the step,
      $w_{forward} \times \frac{\Delta c \cdot d}{dt \cdot L}$ (*dt* = `env.unwrapped.dt`, the duration of the step) with *L* = 0.14 m.
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
      `healthy_height_fraction` (0.5) of its rest height (the robot fell over).
    - Always, when the simulation fails (the Newton solver raises `SimulationError`): the step
      returns `terminated=True`, reward 0, `info["sim_failure"]` with the reason, and the
      environment's state is left as it was before the step.

    ### Truncation
    `gymnasium.make` wraps the environment in a `TimeLimit` of `max_episode_steps` = 300
    environment steps (`soft_envs.MAX_EPISODE_STEPS`; 10 s at `frame_skip=1`, about four of the
    paper's gait cycles); `gym.make(..., max_episode_steps=N)` changes it. The environment
    itself never truncates. The RL baseline (`trajopt rl train`) passes 168, trajopt's
    optimisation horizon (24 prep steps + 2 cycles of 72), so both methods see the same episodes.

    ## Arguments
    ```python
    import gymnasium as gym
    import soft_envs
    env = gym.make("SoftTripod-v0", frame_skip=2, task="turn", turn_direction="left")
    ```

    | Parameter                  | Type               | Default        | Description |
    |----------------------------|--------------------|----------------|-------------|
    | `robot`                    | **str \| Path \| Robot** | `"tripod"` | shipped robot name, a `robot.toml` path (e.g. the fine mesh `assets/tripod/robot_fine.toml`) or a `Robot`; sizes in the tables above change accordingly |
    | `frame_skip`               | **int**            | `1`            | simulation steps per environment step; `env.unwrapped.dt = frame_skip * timestep` |
    | `timestep`                 | **float**          | `0.033`        | simulation time step [s] (`env.unwrapped.timestep`, `env.unwrapped.simulator.dt`; the paper's h) |
    | `task`                     | **str**            | `"walk"`       | `"walk"` (speed along the target heading) or `"turn"` (yaw rate) |
    | `target_heading_deg`       | **float**          | `0`            | walking direction, degrees from +x towards +z (90 = +z, the robot's right; the convention of `trajopt`); also the uphill direction |
    | `turn_direction`           | **str**            | `"right"`      | `"right"` (clockwise seen from above) or `"left"`; only with `task="turn"` |
    | `turn_radius`              | **float \| None**  | `None`         | radius [m] converting yaw rate to speed in the turn reward; `None` = body length |
    | `incline_deg`              | **float**          | `0`            | ground slope, rising along the target heading (gravity is rotated, `incline_gravity`) |
    | `forward_reward_weight`    | **float**          | `10`           | weight of *forward_reward* |
    | `ctrl_cost_weight`         | **float**          | `0.01`         | weight of *ctrl_cost* |
    | `healthy_reward`           | **float**          | `0.1`          | reward per healthy step |
    | `terminate_when_unhealthy` | **bool**           | `True`         | terminate when the robot falls over |
    | `healthy_tilt_deg`         | **float**          | `60`           | largest tilt of the up vector from +y that is healthy [deg] |
    | `healthy_height_fraction`  | **float**          | `0.5`          | lowest healthy COM height as a fraction of the rest height |
    | `reset_noise_scale`        | **float**          | `1e-4`         | half-width [m] of the uniform noise on initial positions and previous positions |
    | `motor_speed_rpm`          | **float \| None**  | `100`          | motor output speed limit [rpm] (times the spool radius: the contraction speed limit); `None`: no limit |
    | `gait_period`              | **float**          | `2.376`        | period [s] of the gait-phase observation (the paper's cycle: 72 steps) |
    | `observe_nodes`            | **bool**           | `False`        | append all node positions relative to the COM to the observation |
    | `domain_randomization`     | **dict \| bool \| None** | `None`   | multiplicative factors drawn uniformly at each reset (from `np_random`, keys in sorted order) for `friction`, `contact_stiffness`, `youngs_modulus`, `density`, `payload_mass`, as `{key: (low, high)}`, e.g. `{"friction": (0.7, 1.3)}`; `True`: `soft_envs.envs.DEFAULT_DOMAIN_RANDOMIZATION` = friction (0.7, 1.3), youngs_modulus (0.8, 1.2), density (0.9, 1.1), payload_mass (0.9, 1.1); `None` or `False`: the nominal robot. `env.unwrapped.domain_parameters` holds the episode's factors |
    | `contact`                  | **str \| None**   | `None`         | ground contact law: `"paper"` (paper II-C: viscous-like lagged friction, what Table I was made with; the robot file's default), `"coulomb"` (Coulomb friction bounded by `friction_coefficient` x the normal force, feet held by stick anchors: `soft_envs.sim.coulomb`), or `None` for the robot file's `[contact] model`. `SoftTripod-v1` passes `"coulomb"` |
    | `render_mode`              | **str \| None**    | `None`         | `"rgb_array"` (uint8 frames, offscreen matplotlib, no OpenGL) or `"human"` (matplotlib window) |
    | `width`, `height`          | **int**            | `480`, `360`   | frame size in pixels |
    | `camera_config`            | **dict \| None**   | `None`         | extra keyword arguments of `soft_envs.render.Renderer` (`elevation`, `azimuth`, `distance`, ...) |

    `gymnasium.make` also takes `max_episode_steps` (default 300, see Truncation).

    Gradient hooks for trajectory optimisation (`soft_envs.envs.GradientEnv`) are on
    `env.unwrapped`: `robot`, `timestep`, `control_mode`, `incline_deg`, `gravity`,
    `rollout(u, dudz=None, store_dxdz=False)` (one row of `u` per simulation step),
    `reset_state()`, `get_state()`, `set_state()`, `com()`, `cable_deformation(x=None, u=None)`,
    `cable_tension(x=None, u=None)`; also `simulator`, `action_to_control()`,
    `control_to_action()` and `domain_parameters`.

    ## Version History
    * v0: Initial version. Since then, without a new id (the dynamics and rewards are
      unchanged): `env.unwrapped.dt` is the duration of an environment step, as in Gymnasium's
      MuJoCo environments (it was the simulation step, now `env.unwrapped.timestep`; the two are
      equal at the default `frame_skip=1`), and `domain_randomization=True` selects the
      default ranges.
    * v1: the Coulomb contact law (`contact="coulomb"`: friction bounded by mu N with
      mu = 0.8, feet that stick; the `friction` factor of domain randomisation scales mu).
      Observations, actions and rewards as in v0. The stick anchors are part of the state
      (`get_state()["history"]`).
    """

    def __init__(self, robot: str | os.PathLike | Robot = "tripod", **kwargs: Any):
        super().__init__(robot, **kwargs)
