"""Physics of cable-driven soft robots (Bern et al., RSS 2019, section II and III-A).

This layer imports numpy, scipy, numba, meshio and cvxopt only: no Gymnasium, nothing from
``soft_envs.envs`` or ``trajopt`` (``tests/`` check it at import time). Public names:
:class:`Robot`, :func:`load_robot`, :class:`Simulator`, :class:`Trajectory`,
:class:`State`, :class:`SimulationError`, :class:`NewtonOptions`, :class:`FactorCache`,
:class:`TetMesh`, :func:`load_mesh`, :func:`incline_gravity`, :class:`HeightField` (a ground that
is not flat, ``Robot.ground``), :class:`Box` and :func:`with_box` (a second body,
``Robot.box``), :data:`DEFAULT_DT` (the paper's time
step, 0.033 s) and :data:`GAIT_CYCLE_STEPS` (its gait cycle, 72 steps).

Structure: a :class:`Robot` is static data (mesh, material, payload, cables, motors, contact);
the potential energy is a list of :class:`~.terms.EnergyTerm` objects over explicit inputs
(positions ``x``, previous positions ``x_prev``, controls ``u``) in
:class:`~.system.EnergySystem`; :class:`~.integrator.NewtonSolver` takes implicit-Euler steps;
a :class:`~.state.State` (positions, previous positions, stick anchors) is what one step hands
the next (:func:`~.state.advance`); :mod:`.rest` finds the rest state; :mod:`.sensitivity`
differentiates whole rollouts; :class:`Simulator` strings them together.

Where each equation of the paper lives (one function each):

=====================================  ==========================================================
paper                                  implementation
=====================================  ==========================================================
eq. 1, neo-Hookean energy density      :func:`.materials.psi`; element gradient and Hessian
                                       :func:`.materials.element_gradient_hessian`; the term
                                       :class:`.elastic.Elastic`
II-A, lumped mass + payload            :attr:`.robot.Robot.node_masses`
eq. 2, cable deformation Gamma         :meth:`.cables.Cables.deformation`
eq. 3, rest length alpha(u)            :meth:`.cables.Cables.rest_lengths`; the cable energy
                                       Q(Gamma) is the term :class:`.cables.Cables`
II-B, one-sided quadratic Q            :func:`.contact.penalty.Q`
                                       (:func:`.contact.penalty.one_sided_quadratic`)
II-C, contact energy (lagged friction) :func:`.contact.paper.contact_assemble`; the term
                                       :class:`.contact.paper.GroundContact` (the contact
                                       laws: :data:`.contact.CONTACT_LAWS`)
II-D, gravity; IV-B, incline           :class:`.gravity.Gravity`, :func:`.gravity.incline_gravity`
eq. 4, implicit Euler by Newton        :meth:`.integrator.NewtonSolver.step` (minimises Phi,
                                       :meth:`.integrator.NewtonSolver.phi_assemble`); what a
                                       step needs, :class:`.state.State`; one step from a state
                                       to the next, :func:`.state.advance`
eqs. 6-9, the whole-rollout system     :mod:`.sensitivity` (module docstring)
eqs. 10-11, forward recurrence         :meth:`.sensitivity.ForwardSensitivities.step`
adjoint of eq. 10                      :func:`.sensitivity.adjoint_pass`
eq. 10 for physical parameters         the parameter block of :class:`.sensitivity.ForwardSensitivities`
(calibration, beyond the paper)        (``d(dE_t/dx)/dtheta``: ``EnergyTerm.add_parameter_jacobian``;
                                       names in :mod:`.parameters`); rest state:
                                       :meth:`.simulator.Simulator.rest_sensitivity`; tracked
                                       markers :mod:`.markers`
appendix A, tension control            :class:`.cables.CableTensions`
=====================================  ==========================================================

The optimisation side (eqs. 5, 12, 13 and the zero-slack post-processing) is in ``trajopt``.
"""
from .box import Box, with_box
from .gravity import incline_gravity
from .ground import HeightField
from .integrator import NewtonOptions, SimulationError
from .linsolve import FactorCache
from .mesh import TetMesh, load_mesh
from .markers import Marker, MarkerSet
from .robot import ContactParams, Motor, Robot, Tendon
from .rollout import RolloutStopped
from .simulator import Simulator, Trajectory
from .state import State
from .timing import DEFAULT_DT, GAIT_CYCLE_STEPS

__all__ = ["Robot", "Tendon", "Motor", "ContactParams", "Marker", "MarkerSet", "Simulator", "Trajectory", "State",
           "RolloutStopped",
           "SimulationError", "NewtonOptions", "FactorCache", "TetMesh", "load_mesh", "incline_gravity", "HeightField",
           "Box", "with_box", "load_robot",
           "DEFAULT_DT", "GAIT_CYCLE_STEPS"]


def load_robot(name_or_path, **overrides):
    """Load a shipped robot by name (``"tripod"``, ``"puppy"``, ``"hexapod"``, ``"inchworm"``) or a ``robot.toml`` path."""
    from .robot_file import load_robot as _load
    return _load(name_or_path, **overrides)
