"""soft_envs: simulation and Gymnasium environments of cable-driven soft robots.

Importing the package registers the environments ``SoftTripod-v0`` and ``SoftPuppy-v0`` with
Gymnasium (``gymnasium.make("SoftPuppy-v0")`` after ``import soft_envs``, or
``gymnasium.make("soft_envs:SoftPuppy-v0")`` without the import). The environment classes are
only imported when an environment is made; :mod:`soft_envs.sim` is the physics alone.
"""
from gymnasium.envs.registration import register, registry

__all__ = ["ENV_IDS"]

#: Environment ids registered by this package and their entry points.
ENV_IDS = {
    "SoftTripod-v0": "soft_envs.envs.tripod:SoftTripodEnv",
    "SoftPuppy-v0": "soft_envs.envs.puppy:SoftPuppyEnv",
}

for _env_id, _entry_point in ENV_IDS.items():
    if _env_id not in registry:       # re-imports (importlib.reload) must not re-register
        register(id=_env_id, entry_point=_entry_point, max_episode_steps=300)
del _env_id, _entry_point
