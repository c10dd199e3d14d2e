"""soft_envs: simulation and Gymnasium environments of cable-driven soft robots.

Its layers and what each may import (arrows point one way, ``trajopt -> soft_envs.envs ->
soft_envs.sim``; the rules hold at import time, ``tests/test_layers.py`` checks them):

* :mod:`soft_envs.sim` is the physics alone: robots, the finite-element energy, implicit-Euler
  rollouts and their exact sensitivities. It imports numpy, scipy, numba, meshio and cvxopt,
  never Gymnasium, :mod:`soft_envs.envs` or ``trajopt``; it imports without Gymnasium installed.
* :mod:`soft_envs.envs` is the Gymnasium environments (``SoftTripod-v2``, ``SoftPuppy-v2``,
  ``SoftHexapod-v2``, ``SoftInchworm-v2``) and
  the gradient protocol (:class:`~soft_envs.envs.GradientEnv`) through which ``trajopt`` reaches
  the physics. It imports :mod:`soft_envs.sim`, Gymnasium and :mod:`soft_envs.render`, never
  ``trajopt``.
* :mod:`soft_envs.render` draws frames offscreen with matplotlib (no OpenGL) and
  :mod:`soft_envs.animation` writes them to GIF or MP4; they import matplotlib, Pillow and the
  mesh helpers of :mod:`soft_envs.sim` only.

Importing the package registers the environments with Gymnasium when Gymnasium is installed
(``gymnasium.make("SoftPuppy-v2")`` after ``import soft_envs``, or
``gymnasium.make("soft_envs:SoftPuppy-v2")`` without the import). The environment classes are
only imported when an environment is made.
"""
from .kernel_cache import use_source_keyed_cache

use_source_keyed_cache()          # before any kernel is compiled: stale kernels never run

__all__ = ["ENV_VERSIONS", "LATEST_VERSION", "ENV_IDS_BY_ROBOT", "ENV_IDS", "ENV_ROBOTS", "ENV_KWARGS", "LATEST_ENV_IDS",
           "MAX_EPISODE_STEPS", "TASKS", "TASK_ENV_IDS", "TASK_IDS_BY_TASK"]

#: The versions of the environments (Gymnasium's convention: a new version when the dynamics
#: change), each the keywords its ids pass: ``-v0`` the paper's contact law at the paper's
#: integration, one implicit-Euler step of 0.033 s per control step (Table I); ``-v1`` the
#: Coulomb law (:mod:`soft_envs.sim.contact.coulomb`: feet that stick) at the same integration
#: (the default of release 0.1.0); both keep the motors of their making, the speed limit alone
#: (``motor_model="speed"``). ``-v2``, the latest and the default: every law at its own converged
#: physics (``substeps=None``: :attr:`soft_envs.sim.contact.ContactLaw.default_substeps`, 4
#: physics steps per control step for the Coulomb law, docs/fidelity.md) and the motors on their
#: torque-speed line (the class's ``motor_model="torque-speed"``, :mod:`soft_envs.sim.motors`), the
#: Coulomb law by default (``gym.make("SoftTripod-v2", contact="paper")`` runs the paper's law, at
#: its own 33 ms).
ENV_VERSIONS = {
    "v0": {"contact": "paper", "substeps": 1, "motor_model": "speed"},
    "v1": {"contact": "coulomb", "substeps": 1, "motor_model": "speed"},
    "v2": {"contact": "coulomb"},
}
#: The latest version: the one the project makes (RL baseline, examples, trajopt).
LATEST_VERSION = "v2"
_ENV_NAMES = {"tripod": "SoftTripod", "puppy": "SoftPuppy"}
#: Robots shipped after the v2 physics (the Hexapod and the Inchworm, made with ``trajopt mesh``,
#: docs/robots.md): registered at the latest version only, ``SoftHexapod-v2`` and
#: ``SoftInchworm-v2`` (there is no Table I of theirs for a ``-v0`` to keep); no task ids yet.
_LATEST_ONLY_NAMES = {"hexapod": "SoftHexapod", "inchworm": "SoftInchworm"}
#: The id the project makes for each of the paper's robots under each contact law: the latest (``-v2``)
#: for the Coulomb law; the paper's law is ``contact="paper"`` on it, and ``-v0`` keeps Table I's.
ENV_IDS_BY_ROBOT = {robot: {"paper": f"{name}-v0", "coulomb": f"{name}-{LATEST_VERSION}"}
                    for robot, name in _ENV_NAMES.items()}
_ENTRY_POINTS = {"tripod": "soft_envs.envs.tripod:SoftTripodEnv", "puppy": "soft_envs.envs.puppy:SoftPuppyEnv",
                 "hexapod": "soft_envs.envs.hexapod:SoftHexapodEnv",
                 "inchworm": "soft_envs.envs.inchworm:SoftInchwormEnv"}
#: every registered (robot, id stem, version)
_REGISTERED = ([(robot, name, version) for robot, name in _ENV_NAMES.items() for version in ENV_VERSIONS]
               + [(robot, name, LATEST_VERSION) for robot, name in _LATEST_ONLY_NAMES.items()])
#: Each registered id's entry point (every version of the paper's robots, the latest of the others).
ENV_IDS = {f"{name}-{version}": _ENTRY_POINTS[robot] for robot, name, version in _REGISTERED}
#: The shipped robot of each registered id.
ENV_ROBOTS = {f"{name}-{version}": robot for robot, name, version in _REGISTERED}
#: Keyword arguments each id passes to its environment: its version's (a keyword given to
#: ``gymnasium.make`` replaces it: ``contact="paper"`` on ``-v2``).
ENV_KWARGS = {f"{name}-{version}": dict(ENV_VERSIONS[version]) for _, name, version in _REGISTERED}
#: The latest id of each shipped robot (``-v2``): the one the project makes (RL baseline,
#: examples); the paper's law is its ``contact="paper"``, never ``-v0`` unless Table I is asked for.
LATEST_ENV_IDS = {robot: f"{name}-{LATEST_VERSION}" for robot, name in {**_ENV_NAMES, **_LATEST_ONLY_NAMES}.items()}

#: The benchmark's tasks (issue #39; soft_envs.envs.tasks, docs/tasks.md): task key -> (id stem,
#: class in ``soft_envs.envs.tasks``). Each has an id per robot, ``<robot name><stem>-v0``
#: (``SoftTripodWalk-v0``, ``SoftPuppyReachGoal-v0``), on the latest physics (``-v2``'s).
TASKS = {"walk": ("Walk", "WalkEnv"), "turn": ("Turn", "TurnEnv"), "slope_up": ("SlopeUp", "SlopeUpEnv"),
         "slope_down": ("SlopeDown", "SlopeDownEnv"), "rough_terrain": ("RoughTerrain", "RoughTerrainEnv"),
         "climb_step": ("ClimbStep", "ClimbStepEnv"), "cross_trench": ("CrossTrench", "CrossTrenchEnv"),
         "reach_goal": ("ReachGoal", "ReachGoalEnv"), "carry": ("Carry", "CarryEnv"),
         "push_box": ("PushBox", "PushBoxEnv")}
#: Each task id's entry point and keywords (its robot): ``{id: (entry point, kwargs)}``.
TASK_ENV_IDS = {f"{name}{stem}-v0": (f"soft_envs.envs.tasks:{cls}", {"robot": robot})
                for robot, name in _ENV_NAMES.items() for stem, cls in TASKS.values()}
#: task key -> {robot: its id}
TASK_IDS_BY_TASK = {task: {robot: f"{name}{stem}-v0" for robot, name in _ENV_NAMES.items()}
                    for task, (stem, _) in TASKS.items()}

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
    for env_id, (entry_point, kwargs) in TASK_ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, max_episode_steps=MAX_EPISODE_STEPS, kwargs=dict(kwargs))


_register_environments()
