"""Hyper-parameters of the RL baseline, and why.

The environments are small (Tripod: 18 observations after :class:`DropHorizontalPosition`, 2
actions; Puppy: 36 and 8), the episodes short (168 steps = 5.5 s, trajopt's horizon), a
simulation step is expensive (about 7 ms for the Tripod, 11 ms for the Puppy on one core,
hundreds of times a MuJoCo step) and the budgets are therefore small (10^4 - 10^5 steps). The
choices follow the Stable-Baselines3 / RL Zoo defaults for continuous control, scaled to this:

PPO
  * ``n_steps`` = 1024 transitions per update in total (``1024 // n_envs`` per environment):
    about six 168-step episodes, i.e. about 14 gait cycles, per policy update; 30 - 50
    updates in a 30k - 50k budget. A smaller budget is one rollout of its size
    (:func:`ppo_rollout`: SB3 collects whole rollouts and would overshoot it).
  * ``batch_size`` 64, ``n_epochs`` 10, ``learning_rate`` 3e-4, ``clip_range`` 0.2,
    ``gae_lambda`` 0.95, ``max_grad_norm`` 0.5: the SB3 defaults (MuJoCo-tested).
  * ``gamma`` 0.99: an effective horizon of ~100 steps (3.3 s), longer than one 72-step
    gait cycle, so the value of a stride is credited to the actions that set it up.
  * ``ent_coef`` 0: the Gaussian policy's own noise explores; its initial standard deviation
    is 1 (``log_std_init`` 0, SB3's default) in action units, i.e. the full contraction
    range, which the motor speed limit filters into a random walk of the cables.
  * networks ``pi = vf = [64, 64]`` tanh: enough for 18-36 inputs, cheap on a CPU.
  * ``VecNormalize`` of observations *and* rewards (``gamma`` matched): the observation mixes
    metres (COM height ~0.05 m), m/s, unit vectors and dimensionless cable strains; the
    return scale is unknown a priori. The statistics are saved with the model.

SAC
  * ``learning_rate`` 3e-4, ``batch_size`` 256, ``tau`` 0.005, ``gamma`` 0.99,
    ``ent_coef="auto"`` (target entropy -dim(A)): the SB3 defaults.
  * ``buffer_size`` = the whole budget (nothing is ever discarded at these budgets).
  * ``learning_starts`` 1000 steps of uniform random actions (~6 episodes) before updates.
  * ``train_freq`` 1 environment step, ``gradient_steps`` 1 per vector step: with
    ``n_envs`` environments that is 1/n_envs gradient updates per transition. A gradient step
    costs about as much CPU time as a simulation step at these network sizes, so this keeps
    the wall time of SAC within ~2x of PPO's for the same number of simulation steps.
  * networks ``[128, 128]`` (actor and both critics) instead of SB3's [256, 256]: ~2x
    faster updates on a CPU (measured 13 vs 22 ms per update), ample for these inputs.
  * ``VecNormalize`` of observations only: SAC's entropy temperature is tuned against the
    reward scale, normalising rewards on the fly would move that target.

Everything can be overridden (``trajopt rl train ... --hp learning_rate=1e-3 --hp
batch_size=128``, or ``train(hyperparams={...})``); the values used are written to the run's
``rl_config.json``. ``trajopt rl tune ID`` (:mod:`trajopt.rl.tuning`) searches for better ones
on a task id, starting from these.
"""
from __future__ import annotations

import ast
import copy
from typing import Any

__all__ = ["ALGOS", "default_hyperparams", "ppo_rollout", "vecnormalize_kwargs", "parse_overrides", "jsonable",
           "SUITE_TIMESTEPS", "SUITE_N_ENVS"]

ALGOS = ("ppo", "sac")
#: the task suite's budget per RL run (environment steps; examples/suite.toml, the rl_zoo3 files'
#: ``n_timesteps``): PPO on the Tripod's walk learns a gait within about 3e4 steps
SUITE_TIMESTEPS = 30_000
#: environments stepped per RL run in the suite (in its own process, no subprocesses)
SUITE_N_ENVS = 2

_PPO = dict(
    learning_rate=3e-4,
    n_steps=1024,                 # in total per update; divided by n_envs in default_hyperparams
    batch_size=64,
    n_epochs=10,
    gamma=0.99,
    gae_lambda=0.95,
    clip_range=0.2,
    ent_coef=0.0,
    vf_coef=0.5,
    max_grad_norm=0.5,
    policy_kwargs=dict(net_arch=dict(pi=[64, 64], vf=[64, 64]), log_std_init=0.0),
)

_SAC = dict(
    learning_rate=3e-4,
    buffer_size=1_000_000,        # capped at the budget in default_hyperparams
    learning_starts=1000,
    batch_size=256,
    tau=0.005,
    gamma=0.99,
    train_freq=1,
    gradient_steps=1,
    ent_coef="auto",
    policy_kwargs=dict(net_arch=[128, 128]),
)


def default_hyperparams(algo: str, *, n_envs: int = 1, timesteps: int | None = None) -> dict[str, Any]:
    """The documented defaults for ``algo`` ("ppo" | "sac") with ``n_envs`` environments and
    a budget of ``timesteps`` environment steps (a fresh copy; safe to modify)."""
    algo = algo.lower()
    if algo == "ppo":
        hp = copy.deepcopy(_PPO)
        hp["n_steps"], hp["batch_size"] = ppo_rollout(hp["n_steps"], hp["batch_size"], n_envs=n_envs,
                                                      timesteps=timesteps)
        return hp
    if algo == "sac":
        hp = copy.deepcopy(_SAC)
        if timesteps is not None:
            hp["buffer_size"] = int(min(hp["buffer_size"], max(int(timesteps), 1000)))
            # a budget shorter than the random warm-up would never learn
            hp["learning_starts"] = int(min(hp["learning_starts"], max(int(timesteps) // 5, 1)))
        return hp
    raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")


def ppo_rollout(n_steps_total: int, batch_size: int, *, n_envs: int = 1,
                timesteps: int | None = None) -> tuple[int, int]:
    """PPO's ``(n_steps, batch_size)``: ``n_steps_total`` transitions per update shared by the
    ``n_envs`` environments (at least 16 each), at most ``timesteps`` when the budget is smaller
    than one rollout (Stable-Baselines3 collects whole rollouts: a budget of 256 steps would
    otherwise take 1024), and minibatches no larger than a rollout."""
    n_envs = max(int(n_envs), 1)
    n_steps = max(int(n_steps_total) // n_envs, 16)
    if timesteps is not None and n_steps * n_envs > int(timesteps):
        n_steps = max(-(-int(timesteps) // n_envs), 16)          # the fewest that cover the budget
    return n_steps, min(int(batch_size), n_steps * n_envs)


def vecnormalize_kwargs(algo: str, gamma: float) -> dict[str, Any]:
    """Arguments of ``VecNormalize`` for ``algo`` (see the module docstring)."""
    return {"norm_obs": True, "norm_reward": algo.lower() == "ppo", "clip_obs": 10.0,
            "clip_reward": 10.0, "gamma": float(gamma)}


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """``["learning_rate=1e-3", "policy_kwargs=dict(net_arch=[32, 32])"]`` -> dict. Values
    are Python literals (``dict(...)`` with literal arguments is accepted too); anything
    else is kept as a string."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key.isidentifier():
            raise ValueError(f"hyper-parameter override must be KEY=VALUE, got {item!r}")
        out[key] = _literal(value.strip())
    return out


def _literal(text: str) -> Any:
    try:
        node = ast.parse(text, mode="eval").body
    except SyntaxError:
        return text
    return _eval_node(node, text)


def _eval_node(node: ast.AST, text: str) -> Any:
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict"
            and not node.args):
        return {kw.arg: _eval_node(kw.value, text) for kw in node.keywords}
    try:
        return ast.literal_eval(node)
    except ValueError:
        return text


def jsonable(obj: Any) -> Any:
    """A JSON-friendly copy of a hyper-parameter dict (classes and callables by name)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    if isinstance(obj, type) or callable(obj):
        return f"{getattr(obj, '__module__', '')}.{getattr(obj, '__qualname__', repr(obj))}"
    try:
        return obj.item()
    except AttributeError:
        return repr(obj)
