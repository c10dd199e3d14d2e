"""The paper's time discretisation (Bern et al. 2019, section IV): one home for both numbers.

:data:`DEFAULT_DT` is the default of every time step in the package (the simulator's, the
environments' ``timestep``, the kernels' warm-up); at run time the one owner of a simulation's
step is its :class:`~soft_envs.sim.integrator.NewtonSolver` (``Simulator.dt`` reads it, the
environments read the simulator's). :data:`GAIT_CYCLE_STEPS` is the length of the paper's gait
cycle in simulation steps (the environments' gait-phase period is ``GAIT_CYCLE_STEPS *
DEFAULT_DT``; ``trajopt``'s ``GaitSpec().n_cycle`` cannot import this package, which is too heavy
for its command line, and ``tests/test_state.py`` pins it to this value).
"""
from __future__ import annotations

__all__ = ["DEFAULT_DT", "GAIT_CYCLE_STEPS"]

#: [s] the implicit-Euler time step h (paper IV: "constant time-step h = 0.033 s")
DEFAULT_DT = 0.033
#: simulation steps of one gait cycle (paper IV: "72 time-steps in the cyclic phase")
GAIT_CYCLE_STEPS = 72
