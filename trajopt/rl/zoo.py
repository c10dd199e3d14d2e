"""The RL baseline's hyper-parameters as RL Baselines3 Zoo files (``rl_zoo3``), one entry per id.

rl_zoo3 reads ``hyperparams/<algo>.yml`` from its own package unless given ``--conf-file``; these
files (``trajopt/rl/zoo/ppo.yml``, ``sac.yml``) hold, for every task id (``SoftTripodWalk-v0`` ...)
and every robot id (``SoftTripod-v2`` ...), the values ``trajopt rl train`` uses: on a task id its
robot's tuned values where a study found better ones (``trajopt/rl/zoo/tuned.toml``,
:mod:`trajopt.rl.tuning.tuned`), else those of :mod:`trajopt.rl.hyperparams` (the one source:
:func:`zoo_entry`, and a test that the shipped files are what it writes), in rl_zoo3's
format: ``n_envs``, ``n_timesteps``, ``policy``, ``normalize`` (the ``VecNormalize`` keywords as a
Python string), ``policy_kwargs`` as a string, ``env_wrapper`` (the baseline's
:class:`~trajopt.rl.envs.DropHorizontalPosition`) and, for the robot ids, the baseline's episode
length (``env_kwargs``)::

    pip install soft-envs[zoo]
    python -m rl_zoo3.train --algo ppo --env SoftTripodClimbStep-v0 --gym-packages soft_envs \\
        --conf-file trajopt/rl/zoo/ppo.yml

``python -m trajopt.rl.zoo`` writes the files again (after a change of the hyper-parameters;
``trajopt rl tune --adopt`` does it itself).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from .hyperparams import ALGOS, SUITE_N_ENVS, SUITE_TIMESTEPS, vecnormalize_kwargs
from .tuning.tuned import task_hyperparams

__all__ = ["ZOO_DIR", "zoo_ids", "zoo_entry", "zoo_text", "write_zoo_files"]

#: where the files are (inside the package: ``--conf-file`` takes their path)
ZOO_DIR = Path(__file__).resolve().parent / "zoo"


def zoo_ids() -> list[str]:
    """Every id the files cover: the task ids, then the robots' latest ids."""
    from soft_envs import LATEST_ENV_IDS, TASK_ENV_IDS
    return list(TASK_ENV_IDS) + list(LATEST_ENV_IDS.values())


def _python(value: Any) -> str:
    """A value as the Python literal rl_zoo3 evaluates (dicts as ``dict(...)``)."""
    if isinstance(value, dict):
        return "dict(" + ", ".join(f"{k}={_python(v)}" for k, v in value.items()) + ")"
    if isinstance(value, list):
        return "[" + ", ".join(_python(v) for v in value) + "]"
    return repr(value)


def zoo_entry(algo: str, env_id: str) -> dict[str, Any]:
    """rl_zoo3's hyper-parameters of ``env_id`` for ``algo``: :func:`~trajopt.rl.tuning.tuned.task_hyperparams`
    (on a task id, its robot's tuned values where a study found better ones) with the
    suite's ``n_envs`` and budget, the normalisation of :func:`vecnormalize_kwargs`, the baseline's
    observation wrapper and, on a robot id, its episode length (task ids keep their own)."""
    from soft_envs import TASK_ENV_IDS
    from .envs import TRAIN_HORIZON
    hp, _ = task_hyperparams(algo, env_id, n_envs=SUITE_N_ENVS, timesteps=SUITE_TIMESTEPS)
    vn = vecnormalize_kwargs(algo, hp.get("gamma", 0.99))
    entry: dict[str, Any] = {"n_envs": SUITE_N_ENVS, "n_timesteps": float(SUITE_TIMESTEPS), "policy": "MlpPolicy",
                             "normalize": _python(vn), "env_wrapper": "trajopt.rl.envs.DropHorizontalPosition"}
    if env_id not in TASK_ENV_IDS:
        entry["env_kwargs"] = {"max_episode_steps": TRAIN_HORIZON}
    for key, value in hp.items():
        entry[key] = _python(_zoo_activation(value)) if key == "policy_kwargs" else value
    return entry


class _Code(str):
    """Python source rl_zoo3 evaluates as it is (``nn.ReLU``: its hyper-parameter files' way)."""

    def __repr__(self) -> str:
        return str(self)


def _zoo_activation(policy_kwargs: dict[str, Any]) -> dict[str, Any]:
    """``activation_fn`` named (``"relu"``) as rl_zoo3 writes it (``nn.ReLU``, evaluated with torch.nn as nn)."""
    from .training import ACTIVATIONS
    act = policy_kwargs.get("activation_fn")
    if isinstance(act, str):
        return {**policy_kwargs, "activation_fn": _Code(f"nn.{ACTIVATIONS[act]}")}
    return policy_kwargs


def _yaml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"!!float {value!r}"                 # every digit: the values trajopt rl train uses
    if isinstance(value, int):
        return str(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_yaml(v)}" for k, v in value.items()) + "}"
    return "'" + str(value).replace("'", "''") + "'"


def zoo_text(algo: str) -> str:
    """The YAML file of ``algo`` (every id of :func:`zoo_ids`)."""
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    lines = [f"# {algo.upper()} on the soft-envs ids: what trajopt rl train uses (trajopt/rl/hyperparams.py's values, "
             "a robot's tuned ones on its task ids where trajopt/rl/zoo/tuned.toml has them; written by "
             "`python -m trajopt.rl.zoo`; do not edit).",
             f"# python -m rl_zoo3.train --algo {algo} --env SoftTripodWalk-v0 --gym-packages soft_envs "
             f"--conf-file trajopt/rl/zoo/{algo}.yml", ""]
    for env_id in zoo_ids():
        lines.append(f"{env_id}:")
        lines += [f"  {k}: {_yaml(v)}" for k, v in zoo_entry(algo, env_id).items()]
        lines.append("")
    return "\n".join(lines)


def write_zoo_files(folder: str | Path = ZOO_DIR) -> list[Path]:
    """Write ``ppo.yml`` and ``sac.yml`` (atomically) into ``folder``."""
    from ..results.files import atomic_write_bytes
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for algo in ALGOS:
        paths.append(folder / f"{algo}.yml")
        atomic_write_bytes(paths[-1], zoo_text(algo).encode())
    return paths


if __name__ == "__main__":
    for p in write_zoo_files():
        print(f"wrote {p}")
