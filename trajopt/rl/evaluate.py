"""Evaluating an RL policy with trajopt's metric, and exporting it as a trajopt ``Result``.

The metric is :func:`trajopt.evaluation.measure_gait`, the very function that scores
optimised gaits: play ``n_prep`` = 24 steps + ``n_cycles`` (default 6) cycles of 72 steps,
then ``speed_bl_per_min`` = mean COM velocity along the target direction from the end of the
prep phase to the end of the last cycle, in body lengths per minute, and ``upright`` = the
body never tilts more than 60 degrees and the COM never drops below half its rest height.

The policy is run closed loop in the environment (deterministic actions, through the
``VecNormalize`` statistics saved with it), with ``terminate_when_unhealthy=False`` so that a
fall is measured rather than cut short, and by default from the exact rest state
(``reset_noise_scale=0``), the start of every ``trajopt`` rollout; the recorded states are
measured as they are. The applied contraction of every simulation step is recorded
(``info["u_substeps"]``, with the motor speed limit already applied); that control trajectory
is the exported :class:`~trajopt.results.Result`, which ``env.unwrapped.rollout`` (no speed
limit, nothing clipped) replays to the same trajectory up to the Newton tolerance.
"""
from __future__ import annotations

import json
import os
import pickle
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from soft_envs.envs import PAPER_TIMESTEP, heading_vector
from soft_envs.envs.actuation import MOTOR_SPEED_FROM_ROBOT

from ..evaluation import evaluate_controls, evaluate_result, measure_gait, zero_slack_controls
from ..optim.gait import GaitSpec
from ..results.result import Result
from ..results.robot_match import fingerprint_of
from . import require_sb3
from .envs import DEFAULT_EVAL_CYCLES, GAIT, make_env, run_contact, run_substeps
from .training import CONFIG_NAME, MODEL_NAME, VECNORM_NAME

__all__ = ["LoadedPolicy", "load_policy", "run_policy", "evaluate_policy_metric", "export_result",
           "evaluate_trajopt_result", "play_controls_in_env", "run_metric"]


@dataclass
class LoadedPolicy:
    """A trained model with its normalisation statistics and run configuration."""

    model: Any
    vecnormalize: Any | None
    config: dict[str, Any]
    path: Path

    @property
    def robot(self) -> str:
        return self.config["robot"]

    @property
    def algo(self) -> str:
        return self.config["algo"]

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The deterministic action for one (unnormalised) observation."""
        if self.vecnormalize is not None:
            obs = self.vecnormalize.normalize_obs(np.asarray(obs, dtype=np.float64))
        action, _ = self.model.predict(obs, deterministic=True)
        return np.asarray(action, dtype=np.float64)


def _resolve(path: Path) -> tuple[Path, Path | None, Path]:
    """(model .zip, VecNormalize .pkl or None, rl_config.json) for a run directory, its
    model.zip or one of its checkpoints."""
    path = Path(path)
    if path.is_dir():
        path = path / MODEL_NAME
    if path.suffix != ".zip" and path.with_suffix(".zip").is_file():
        path = path.with_suffix(".zip")
    if not path.is_file():
        raise ValueError(f"{path}: model file not found (give a run directory, its model.zip or a "
                         "checkpoint model_<N>_steps.zip)")
    if path.name == MODEL_NAME:
        vecnorm = path.with_name(VECNORM_NAME)
    else:                                           # checkpoints/model_<N>_steps.zip
        vecnorm = path.with_name(path.name.replace("model_", "model_vecnormalize_", 1)
                                 .replace(".zip", ".pkl"))
    for cfg in (path.with_name(CONFIG_NAME), path.parent.parent / CONFIG_NAME):
        if cfg.is_file():
            break
    else:
        raise ValueError(f"{path}: no {CONFIG_NAME} next to it or in its parent directory")
    return path, (vecnorm if vecnorm.is_file() else None), cfg


def load_policy(path: str | os.PathLike, *, torch_threads: int | None = 1) -> LoadedPolicy:
    """Load a run directory, a ``model.zip`` or a checkpoint (with its VecNormalize stats)."""
    sb3 = require_sb3()
    model_path, vecnorm_path, cfg_path = _resolve(Path(path))
    config = json.loads(cfg_path.read_text())
    if torch_threads is not None:
        import torch
        torch.set_num_threads(int(torch_threads))
    cls = {"ppo": sb3.PPO, "sac": sb3.SAC}[config["algo"]]
    model = cls.load(model_path, device="cpu")
    vecnorm = None
    if vecnorm_path is not None:
        with open(vecnorm_path, "rb") as fh:
            vecnorm = pickle.load(fh)       # VecNormalize without its venv: normalize_obs only
        vecnorm.training = False
    return LoadedPolicy(model=model, vecnormalize=vecnorm, config=config, path=model_path)


def play_controls_in_env(env, policy, n_steps: int, *, seed: int | None = 0) -> dict[str, Any]:
    """Reset ``env`` (seeded) and step it ``n_steps`` times with ``policy(obs, k) -> action``.

    Returns the applied contraction of every simulation step ``u`` (K, M), the states ``x``
    (K+1, n, 3) and COM ``com`` (K+1, 3) of every simulation step (intermediate states of a
    step with ``frame_skip > 1`` are not observable: then ``x`` is None), the actions, and
    ``sim_failure`` if the simulation failed (the run stops there)."""
    base = env.unwrapped
    obs, info = env.reset(seed=seed)
    fs = base.frame_skip
    us, actions = [], []
    xs = [base.get_state()["x"]]
    coms = [np.asarray(info["com"], dtype=np.float64)]
    failure = None
    for k in range(n_steps):
        a = np.asarray(policy(obs, k), dtype=np.float64)
        actions.append(a)
        obs, _, terminated, _, info = env.step(a)
        if "sim_failure" in info:
            failure = info["sim_failure"]
            break
        us.extend(np.asarray(info["u_substeps"], dtype=np.float64))
        xs.append(base.get_state()["x"])
        coms.append(np.asarray(info["com"], dtype=np.float64))
    return {"u": np.array(us).reshape(-1, len(base.action_space.low)),
            "x": np.array(xs) if fs == 1 else None, "com": np.array(coms), "actions": np.array(actions),
            "sim_failure": failure}


def run_metric(env, u: np.ndarray, x: np.ndarray | None, *, gait: GaitSpec = GAIT,
               heading_deg: float = 0.0) -> dict[str, Any]:
    """trajopt's metric of a run recorded by :func:`play_controls_in_env`: :func:`measure_gait`
    of its states ``x`` (the COM computed as :meth:`Simulator.rollout` does), with ``gait``'s
    prep and cycle lengths; when the per-step states were not observed (frame_skip > 1), of the
    replay of its applied controls ``u`` from the reset state (:func:`evaluate_controls`)."""
    base = env.unwrapped
    if x is not None:
        robot = base.robot
        traj = SimpleNamespace(x=x, com=np.einsum("kni,n->ki", x, robot.node_masses) / robot.total_mass)
        return measure_gait(traj, base, n_prep=gait.n_prep, n_cycle=gait.n_cycle, heading_deg=heading_deg)
    return evaluate_controls(base, u, n_prep=gait.n_prep, n_cycle=gait.n_cycle, heading_deg=heading_deg)


def _eval_env(policy: LoadedPolicy, n_env_steps: int, reset_noise_scale: float, substeps: int | None = None):
    cfg = policy.config["env"]
    kwargs = dict(cfg.get("env_kwargs", {}))
    kwargs["contact"] = run_contact(policy.config)          # runs made before it was recorded: their id's law
    kwargs["substeps"] = run_substeps(policy.config) if substeps is None else int(substeps)   # ... its physics
    kwargs.update(reset_noise_scale=float(reset_noise_scale), terminate_when_unhealthy=False)
    return make_env(cfg["robot"], frame_skip=int(cfg.get("frame_skip", 1)), max_episode_steps=n_env_steps,
                    drop_com_xz=bool(cfg.get("drop_com_xz", True)), env_kwargs=kwargs)


def run_policy(policy: LoadedPolicy, *, n_cycles: int = DEFAULT_EVAL_CYCLES, seed: int = 0,
               reset_noise_scale: float = 0.0, gait: GaitSpec = GAIT, substeps: int | None = None
               ) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """Run the policy deterministically for ``gait.n_prep + n_cycles * gait.n_cycle`` simulation
    steps. Returns (evaluation, recording, env); see :func:`evaluate_policy_metric`. ``substeps``:
    physics steps per control step (default: the run's own)."""
    if n_cycles < 1:
        raise ValueError(f"n_cycles must be >= 1, got {n_cycles}")
    fs = int(policy.config["env"].get("frame_skip", 1))
    n_prep, n_cycle = gait.n_prep, gait.n_cycle
    K = gait.n_steps(n_cycles)
    if n_prep % fs or n_cycle % fs:
        raise ValueError(f"frame_skip {fs} must divide n_prep {n_prep} and n_cycle {n_cycle}")
    env = _eval_env(policy, K // fs, reset_noise_scale, substeps)
    try:
        import torch
        torch.manual_seed(seed)
    except ImportError:   # pragma: no cover
        pass
    env.action_space.seed(seed)
    rec = play_controls_in_env(env, lambda obs, k: policy.act(obs), K // fs, seed=seed)
    heading = float(policy.config["env"].get("env_kwargs", {}).get("target_heading_deg", 0.0))
    if rec["sim_failure"] is not None:
        ev = {"cycles": n_cycles, "speed_bl_per_min": float("nan"), "upright": False,
              "sim_failure": rec["sim_failure"], "sim_steps": len(rec["u"])}
    else:
        ev = run_metric(env, rec["u"], rec["x"], gait=gait, heading_deg=heading)
    com = rec["com"]
    d = heading_vector(heading)
    i0 = n_prep // fs
    ev["displacement_m"] = float((com[-1] - com[i0]) @ d) if len(com) == K // fs + 1 else float("nan")
    ev.update(n_prep=n_prep, n_cycle=n_cycle, seed=int(seed), reset_noise_scale=float(reset_noise_scale),
              heading_deg=heading, frame_skip=fs, substeps=int(env.unwrapped.substeps),
              method="closed-loop policy, deterministic",
              model=str(policy.path), algo=policy.algo, robot=policy.robot)
    return ev, rec, env


def evaluate_policy_metric(model: str | os.PathLike | LoadedPolicy, *, n_cycles: int = DEFAULT_EVAL_CYCLES,
                           seed: int = 0, reset_noise_scale: float = 0.0, substeps: int | None = None
                           ) -> dict[str, Any]:
    """trajopt's metric for an RL policy (see the module docstring): a dict with
    ``speed_bl_per_min``, ``upright``, ``speed_per_cycle_bl_per_min``, ``max_tilt_deg``,
    ``heading_change_deg``, ``displacement_m`` (COM displacement along the target direction
    over the measured cycles), ``com`` (K+1, 3) and the settings. ``seed`` seeds the reset
    (irrelevant with the default ``reset_noise_scale=0``) and PyTorch; the same model and
    seed give the same numbers. ``substeps``: physics steps per control step (default: the
    run's own; more: the policy closed loop on finer physics, :func:`policy_fidelity`)."""
    policy = model if isinstance(model, LoadedPolicy) else load_policy(model)
    ev, _, env = run_policy(policy, n_cycles=n_cycles, seed=seed, reset_noise_scale=reset_noise_scale,
                            substeps=substeps)
    env.close()
    return ev


def policy_fidelity(model: str | os.PathLike | LoadedPolicy, factors=None, *, n_cycles: int = DEFAULT_EVAL_CYCLES,
                    seed: int = 0, reference: dict | None = None) -> dict[str, Any]:
    """How credible a policy's speed is, by the protocol of :func:`trajopt.fidelity.fidelity`:
    the policy closed loop (deterministic, from the exact rest state) with its run's physics
    steps per control step and ``factors`` (default 2, 4 and 8; 0.5: half as many) times as many; the same dict
    (``substeps``, ``rows`` with each speed and its deviation, ``spread``). ``reference``: the
    evaluation at the run's own physics when already made."""
    from ..fidelity import FIDELITY_FACTORS, fidelity_rows, substeps_at
    policy = model if isinstance(model, LoadedPolicy) else load_policy(model)
    own = reference if reference is not None else evaluate_policy_metric(policy, n_cycles=n_cycles, seed=seed)
    n = int(own["substeps"])
    factors = FIDELITY_FACTORS if factors is None else factors
    steps = {f: substeps_at(n, f) for f in factors}                   # a factor that is no whole step fails first
    evs = {1: own}
    for f in factors:
        evs[f] = evaluate_policy_metric(policy, n_cycles=n_cycles, seed=seed, substeps=steps[f])
    return fidelity_rows(n, 1e3 * float(policy.config["env"].get("env_kwargs", {}).get("timestep", PAPER_TIMESTEP)), evs)


def export_result(model: str | os.PathLike | LoadedPolicy, out: str | os.PathLike | None = None, *,
                  n_cycles: int = DEFAULT_EVAL_CYCLES, seed: int = 0,
                  reset_noise_scale: float = 0.0, overwrite: bool = True) -> Result:
    """The policy's deterministic rollout as a trajopt :class:`Result` (task "rl"), saved to
    ``out`` when given (``overwrite=False``: an existing ``out`` is refused, ValueError). ``u``
    holds the applied contraction of each simulation step (24 prep + ``n_cycles`` x 72),
    ``u_post`` its zero-slack version (paper III-B-2, what the hardware plays, as for optimised
    gaits), ``com`` the simulated COM, ``evaluation`` the metric of
    :func:`evaluate_policy_metric`, ``settings`` n_prep, n_cycle, the algorithm, budget, seed and
    environment settings, ``robot_fingerprint`` the robot's. ``z`` and ``target`` are empty."""
    policy = model if isinstance(model, LoadedPolicy) else load_policy(model)
    ev, rec, env = run_policy(policy, n_cycles=n_cycles, seed=seed, reset_noise_scale=reset_noise_scale)
    if rec["sim_failure"] is not None:
        env.close()
        raise ValueError(f"{policy.path}: the simulation failed during the policy's rollout "
                         f"({rec['sim_failure']}); nothing to export")
    base = env.unwrapped
    robot = base.robot
    u = rec["u"]
    traj = base.rollout(u)        # open-loop replay: the Result's own physics
    env.close()
    cfg = policy.config
    env_kwargs = cfg["env"].get("env_kwargs", {})
    motor_rpm = env_kwargs.get("motor_speed_rpm", MOTOR_SPEED_FROM_ROBOT)      # the override, or the robot's
    settings = {
        "n_prep": GAIT.n_prep, "n_cycle": GAIT.n_cycle, "eval_cycles": int(n_cycles), "algo": cfg["algo"],
        "timesteps": int(cfg.get("timesteps_done", cfg.get("timesteps", 0))),
        "timesteps_requested": int(cfg.get("timesteps", 0)), "seed": int(cfg.get("seed", 0)),
        "eval_seed": int(seed), "sim_steps_training": int(cfg.get("sim_steps", 0)),
        "training_wall_time_s": cfg.get("wall_time_s"), "model": str(policy.path),
        "env_id": cfg.get("env_id"), "frame_skip": int(cfg["env"].get("frame_skip", 1)),
        "env_kwargs": env_kwargs, "reset_noise_scale": float(reset_noise_scale),
        "heading_deg": float(env_kwargs.get("target_heading_deg", 0.0)),
        "incline_deg": float(env_kwargs.get("incline_deg", 0.0)), "contact": base.contact_model,
        "substeps": int(base.substeps),
        "motor_speed_rpm": motor_rpm if motor_rpm != MOTOR_SPEED_FROM_ROBOT else [m.max_speed_rpm for m in robot.motors],
        "control": "length", "source": str(policy.path),
    }
    evaluation = dict(ev)
    evaluation["replay_max_com_error_m"] = float(np.abs(traj.com - np.asarray(ev["com"])).max())
    res = Result(robot=cfg["robot"], task="rl", motor_names=list(robot.motor_names), dt=float(base.timestep),
                 z=np.zeros(0), u=u, u_post=zero_slack_controls(u, traj.cable_deformation, robot.tendon_motor,
                                                                 robot.u_bounds),
                 target=np.zeros((0, 2)), com=np.asarray(ev["com"], dtype=np.float64), settings=settings,
                 evaluation=evaluation, status=f"rl:{cfg.get('status', 'done')}",
                 robot_fingerprint=fingerprint_of(robot))
    res.validate(str(out or policy.path))
    if out is not None:
        res.save(out, overwrite=overwrite)
    return res


def evaluate_trajopt_result(result: Result | str | os.PathLike, n_cycles: int = DEFAULT_EVAL_CYCLES
                            ) -> dict[str, Any]:
    """``trajopt evaluate`` as a function (:func:`trajopt.evaluation.evaluate_result`): the metric
    of a saved gait over ``n_cycles`` cycles (keyframe results are re-expanded; others, like
    exported RL gaits, play their ``u``)."""
    res = result if isinstance(result, Result) else Result.load(result)
    return evaluate_result(res, n_cycles)
