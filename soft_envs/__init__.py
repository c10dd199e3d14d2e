"""soft_envs: simulation and Gymnasium environments of cable-driven soft robots.

Its layers and what each may import (arrows point one way, ``trajopt -> soft_envs.envs ->
soft_envs.sim``; the rules hold at import time, ``tests/test_layers.py`` checks them):

* :mod:`soft_envs.sim` is the physics alone: robots, the finite-element energy, implicit-Euler
  rollouts and their exact sensitivities. It imports numpy, scipy, numba, meshio and cvxopt,
  never Gymnasium, :mod:`soft_envs.envs` or ``trajopt``; it imports without Gymnasium installed.
* :mod:`soft_envs.envs` is the Gymnasium environments (``SoftTripod-v1``, ``SoftPuppy-v1``) and
  the gradient protocol (:class:`~soft_envs.envs.GradientEnv`) through which ``trajopt`` reaches
  the physics. It imports :mod:`soft_envs.sim`, Gymnasium and :mod:`soft_envs.render`, never
  ``trajopt``.
* :mod:`soft_envs.render` draws frames offscreen with matplotlib (no OpenGL) and
  :mod:`soft_envs.animation` writes them to GIF or MP4; they import matplotlib, Pillow and the
  mesh helpers of :mod:`soft_envs.sim` only.

Importing the package registers the environments with Gymnasium when Gymnasium is installed
(``gymnasium.make("SoftPuppy-v1")`` after ``import soft_envs``, or
``gymnasium.make("soft_envs:SoftPuppy-v1")`` without the import). The environment classes are
only imported when an environment is made.
"""
__all__ = ["ENV_IDS_BY_ROBOT", "ENV_IDS", "ENV_KWARGS", "LATEST_ENV_IDS", "MAX_EPISODE_STEPS"]

#: The environment ids registered by this package (the one place they are written): the id of
#: each shipped robot under each contact law. ``-v1`` (``"coulomb"``, :mod:`soft_envs.sim.contact.coulomb`:
#: feet that stick) is the latest and the default, the law of the shipped robot files;
#: ``gym.make("SoftTripod-v1", contact="paper")`` runs it under the paper's law. ``-v0``
#: (``"paper"``: viscous-like lagged friction) is kept to reproduce Table I and always uses the
#: paper's law, whatever the robot file says (Gymnasium reports it "out of date" because a
#: ``-v1`` exists: its versioning convention, a new version when the dynamics change).
ENV_IDS_BY_ROBOT = {
    "tripod": {"paper": "SoftTripod-v0", "coulomb": "SoftTripod-v1"},
    "puppy": {"paper": "SoftPuppy-v0", "coulomb": "SoftPuppy-v1"},
}
_ENTRY_POINTS = {"tripod": "soft_envs.envs.tripod:SoftTripodEnv", "puppy": "soft_envs.envs.puppy:SoftPuppyEnv"}
#: Each id's entry point.
ENV_IDS = {env_id: _ENTRY_POINTS[robot] for robot, ids in ENV_IDS_BY_ROBOT.items() for env_id in ids.values()}
#: Keyword arguments each id passes to its environment: its contact law and its motors' law,
#: explicitly (a keyword given to ``gymnasium.make`` replaces it: ``contact="paper"`` on ``-v1``).
#: ``-v0`` and ``-v1`` keep the motors of their making, the speed limit alone
#: (``motor_model="speed"``; the environment class's default is ``"torque-speed"``, the motors'
#: torque-speed line: :mod:`soft_envs.sim.motors`).
ENV_KWARGS = {env_id: {"contact": law, "motor_model": "speed"}
              for ids in ENV_IDS_BY_ROBOT.values() for law, env_id in ids.items()}
#: The latest id of each shipped robot (``-v1``): the one the project makes (RL baseline,
#: examples); the paper's law is its ``contact="paper"``, never ``-v0`` unless Table I is asked for.
LATEST_ENV_IDS = {robot: ids["coulomb"] for robot, ids in ENV_IDS_BY_ROBOT.items()}

#: Episode length of ``gymnasium.make`` (its ``TimeLimit`` wrapper), in environment steps: 300
#: steps of 0.033 s are 10 s, about four of the paper's 72-step gait cycles. Pass
#: ``max_episode_steps`` to ``gymnasium.make`` for another length (``trajopt rl`` trains on
#: 168 steps, trajopt's optimisation horizon).
MAX_EPISODE_STEPS = 300


def _register_environments() -> None:
    try:
        from gymnasium.envs.registration import register, registry
    except ImportError:               # the physics (soft_envs.sim) does not need Gymnasium
        return
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in registry:    # re-imports (importlib.reload) must not re-register
            register(id=env_id, entry_point=entry_point, max_episode_steps=MAX_EPISODE_STEPS,
                     kwargs=dict(ENV_KWARGS.get(env_id, {})))


_register_environments()
