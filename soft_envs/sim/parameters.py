r"""Physical parameters of a robot by name: read, set, and the mass matrix's derivative.

The parameters that calibration fits and robustness studies perturb (the energy terms that
own each one give ``d(dE_t/dx)/dtheta``, :meth:`~.terms.EnergyTerm.add_parameter_jacobian`):

=========================  ======  ================================================================
name                       unit    what (owner)
=========================  ======  ================================================================
``youngs_modulus``         Pa      E of the neo-Hookean foam (elastic term, through mu and lambda)
``poisson_ratio``          --      nu of the foam (elastic term, through mu and lambda)
``density``                kg/m^3  foam density: body mass (gravity term and mass matrix)
``payload_mass``           kg      motor assembly on the payload nodes (gravity term and mass matrix)
``contact_stiffness``      N/m     normal penalty k_n (contact term: normal force and the lagged
                                   N_{k-1} of friction)
``friction``               1/m     the paper's friction weight mu_f (contact model "paper")
``friction_coefficient``   --      Coulomb's mu (contact model "coulomb")
``cable_stiffness``        N/m     stiffness of the cables (length control): the mean over the
                                   tendons; setting it scales every tendon's stiffness alike
=========================  ======  ================================================================

Each contact law owns ``contact_stiffness`` and its *friction parameter*
(``ContactLaw.friction_parameter``: ``friction`` for the paper's law, ``friction_coefficient``
for Coulomb's, none for a law without friction), which :func:`scale_parameters` (domain
randomisation, robustness studies) scales for the factor named ``"friction"``.

Masses are lumped (paper II-A): ``m_i = density * V_i + payload_mass / n_p`` on the ``n_p``
payload nodes, so ``dm_i/d density = V_i`` (the node's lumped volume) and ``dm_i/d payload_mass
= 1 / n_p`` there (:func:`node_mass_jacobian`).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from .contact import friction_parameters

__all__ = ["PhysicalParameter", "PARAMETERS", "MASS_PARAMETERS", "FRICTION", "check_parameters", "parameter_values",
           "with_parameters", "scale_parameters", "node_mass_jacobian", "lame_jacobian"]


@dataclass(frozen=True)
class PhysicalParameter:
    """One entry of :data:`PARAMETERS`: its ``name``, ``unit``, what it is, and whether it must
    be positive (all but the Poisson ratio)."""

    name: str
    unit: str
    description: str
    positive: bool = True


PARAMETERS: Mapping[str, PhysicalParameter] = MappingProxyType({p.name: p for p in (
    PhysicalParameter("youngs_modulus", "Pa", "Young's modulus of the foam"),
    PhysicalParameter("poisson_ratio", "", "Poisson ratio of the foam", positive=False),
    PhysicalParameter("density", "kg/m^3", "foam density (body mass)"),
    PhysicalParameter("payload_mass", "kg", "mass of the motor assembly on top"),
    PhysicalParameter("contact_stiffness", "N/m", "ground penalty stiffness k_n"),
    PhysicalParameter("friction", "1/m", "friction weight mu_f of the paper's law (contact.model = 'paper')"),
    PhysicalParameter("friction_coefficient", "", "Coulomb friction coefficient (contact.model = 'coulomb')"),
    PhysicalParameter("cable_stiffness", "N/m", "cable stiffness (mean over the tendons; all scale alike)"),
)})

#: parameters that change the lumped masses (and so the mass matrix and gravity)
MASS_PARAMETERS = ("density", "payload_mass")

#: the factor of :func:`scale_parameters` for the robot's contact law's friction parameter
FRICTION = "friction"

#: ``[contact]`` key of a contact parameter (the laws' friction parameters are read from the key
#: of their own name)
_CONTACT_KEYS = {"contact_stiffness": "stiffness"}


def _contact_key(name: str) -> str | None:
    """The ``[contact]`` key (ContactParams field) that parameter ``name`` is, None for none."""
    return _CONTACT_KEYS.get(name, name if name in friction_parameters() else None)


def check_parameters(robot, names: Sequence[str], control: str = "length") -> tuple[str, ...]:
    """``names`` as a tuple after checking that each is a known parameter, given once, and one
    that changes this robot's physics (ValueError naming the first that is not)."""
    names = tuple(names)
    for i, n in enumerate(names):
        if n not in PARAMETERS:
            raise ValueError(f"unknown physical parameter {n!r}; known: {', '.join(PARAMETERS)}")
        if n in names[:i]:
            raise ValueError(f"physical parameter {n!r} is given twice")
    model = robot.contact.model
    own = robot.contact.law.friction_parameter
    for n in names:
        why = None
        if n in friction_parameters() and n != own:
            why = f"the robot uses contact.model = {model!r}; " + \
                (f"its friction parameter is {own!r}" if own else "that contact law has no friction parameter")
        elif n == "payload_mass" and robot.payload_nodes.size == 0:
            why = "the robot has no payload (payload.mass = 0, no payload nodes)"
        elif n == "cable_stiffness" and (not robot.tendons or control != "length"):
            why = "it has no effect without tendons or in tension control"
        if why:
            raise ValueError(f"{robot.source}: cannot use parameter {n!r}: {why}")
    return names


def parameter_values(robot, names: Sequence[str]) -> np.ndarray:
    """The current values of the parameters ``names`` of ``robot`` (units of :data:`PARAMETERS`)."""
    def get(n):
        if n not in PARAMETERS:
            raise ValueError(f"unknown physical parameter {n!r}; known: {', '.join(PARAMETERS)}")
        if n == "cable_stiffness":
            return float(np.mean([t.stiffness for t in robot.tendons])) if robot.tendons else np.nan
        key = _contact_key(n)
        return getattr(robot.contact, key) if key else getattr(robot, n)
    return np.array([float(get(n)) for n in names], dtype=np.float64)


def with_parameters(robot, values: Mapping[str, float]):
    """A copy of ``robot`` with the parameters in ``values`` set (``robot`` itself when
    ``values`` is empty). ``cable_stiffness`` scales every tendon's stiffness by the ratio of the
    new mean to the old. Invalid values raise the robot's own ValueError."""
    values = {k: float(v) for k, v in values.items()}
    for n in values:
        if n not in PARAMETERS:
            raise ValueError(f"unknown physical parameter {n!r}; known: {', '.join(PARAMETERS)}")
    if not values:
        return robot
    contact = {_contact_key(n): v for n, v in values.items() if _contact_key(n)}
    changes = {k: values[k] for k in ("youngs_modulus", "poisson_ratio", "density", "payload_mass") if k in values}
    if contact:
        changes["contact"] = dataclasses.replace(robot.contact, **contact)
    if "cable_stiffness" in values:
        ratio = values["cable_stiffness"] / parameter_values(robot, ["cable_stiffness"])[0]
        changes["tendons"] = tuple(dataclasses.replace(t, stiffness=t.stiffness * ratio) for t in robot.tendons)
    return robot.replace(**changes)


def scale_parameters(robot, factors: Mapping[str, float]):
    """A copy of ``robot`` with its physical parameters multiplied by ``factors`` (``robot``
    itself when every factor is 1): the one scaling of domain randomisation and robustness
    studies. Keys are names of :data:`PARAMETERS`, or :data:`FRICTION` (``"friction"``) for
    the friction parameter of the robot's contact law (``ContactLaw.friction_parameter``:
    ``friction`` for the paper's law, ``friction_coefficient`` for Coulomb's). Factors of
    parameters the robot lacks (the friction of a law without friction, the cable stiffness
    without tendons) change nothing."""
    scaled = {}
    for name, factor in factors.items():
        if name == FRICTION:
            name = robot.contact.law.friction_parameter
        if name is None or float(factor) == 1.0 or (name == "cable_stiffness" and not robot.tendons):
            continue
        scaled[name] = parameter_values(robot, [name])[0] * float(factor)
    return with_parameters(robot, scaled)


def node_mass_jacobian(robot, names: Sequence[str]) -> np.ndarray:
    """``dm_i / dtheta_j`` (n_nodes, len(names)): nonzero for :data:`MASS_PARAMETERS` only."""
    out = np.zeros((robot.mesh.n_nodes, len(names)))
    for j, n in enumerate(names):
        if n == "density":
            out[:, j] = robot.mesh.lumped_masses(1.0)
            out[robot.box_nodes, j] = 0.0           # a box's mass is its own
        elif n == "payload_mass" and robot.payload_nodes.size:
            out[robot.payload_nodes, j] = 1.0 / robot.payload_nodes.size
    return out


def lame_jacobian(youngs_modulus: float, poisson_ratio: float) -> dict[str, tuple[float, float]]:
    """``{"youngs_modulus": (dmu/dE, dlam/dE), "poisson_ratio": (dmu/dnu, dlam/dnu)}`` of
    ``mu = E / (2 (1 + nu))`` and ``lam = E nu / ((1 + nu)(1 - 2 nu))``."""
    E, nu = float(youngs_modulus), float(poisson_ratio)
    a, b = 1.0 + nu, 1.0 - 2.0 * nu
    return {"youngs_modulus": (0.5 / a, nu / (a * b)),
            "poisson_ratio": (-0.5 * E / a**2, E * (1.0 + 2.0 * nu * nu) / (a * b) ** 2)}
