r"""Ground contact laws and their registry :data:`CONTACT_LAWS` (``robot.toml``'s ``[contact] model``).

===================  ==============================================================================
module               what
===================  ==============================================================================
:mod:`.penalty`      the one-sided quadratic ``Q``, ``Q'``, ``Q''`` (paper II-B; the cables use it
                     too) and the normal penalty ``Q_n(-y)`` of every law
:mod:`.law`          :class:`ContactLaw`, the base of the laws, and :class:`ContactParameter`, the
                     declaration of a ``[contact]`` key a law reads
:mod:`.paper`        ``"paper"``: :class:`GroundContact`, the paper's lagged friction (II-C)
:mod:`.coulomb`      ``"coulomb"``: :class:`CoulombContact`, Coulomb friction held by stick anchors
:mod:`.surface`      contact geometry on a height field (``Robot.ground``): penetration along the
                     normal, the normal penalty on it
:mod:`.paper_field`  the two laws on a height field (:data:`HEIGHT_FIELD_LAWS`,
:mod:`.coulomb_field` :func:`contact_term`)
===================  ==============================================================================

A law is a :class:`ContactLaw` subclass that declares its name (``model``), the ``[contact]``
keys it reads (``contact_parameters``: defaults, units, bounds) and its friction parameter
(``friction_parameter``: what calibration, domain randomisation and robustness studies scale as
"friction"; None for none). :class:`~soft_envs.sim.system.EnergySystem` builds the robot's law
from this registry, :class:`ContactParams` (the ``[contact]`` table, defined here and
re-exported by :mod:`soft_envs.sim.robot`) validates ``model`` and the
keys against it, and :mod:`soft_envs.sim.parameters` asks the law for its friction parameter.

Adding a law: write the class (``energy`` and ``assemble`` at least, see :class:`ContactLaw`)
and register it::

    register_contact_law(MyLaw)            # then [contact] model = "mine" (MyLaw.model) works

A law may read only keys that are fields of ``ContactParams`` (a new key is a new field there),
and its friction parameter must be one of them (and a name of ``parameters.PARAMETERS`` to be
calibrated or randomised).
:func:`unregister_contact_law` removes a law again (tests). Its derivatives are checked by
``tests/test_energy_derivatives.py`` like every other term's (``tests/test_contact_registry.py``
shows a whole third law, frictionless contact).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

from .coulomb import CoulombContact
from .coulomb_field import CoulombFieldContact
from .law import BLEND, STIFFNESS, ContactLaw, ContactParameter
from .paper import GroundContact, contact_assemble, friction_cross, friction_cross_T, normal_forces
from .paper_field import PaperFieldContact
from .penalty import normal_penalty

__all__ = ["CONTACT_LAWS", "ContactLaw", "ContactParameter", "register_contact_law", "unregister_contact_law",
           "contact_law", "friction_parameters", "check_contact_parameters", "contact_default", "ContactParams",
           "GroundContact", "CoulombContact", "STIFFNESS", "BLEND", "HEIGHT_FIELD_LAWS", "contact_term",
           # the old module soft_envs.sim.contact (now .paper)
           "contact_assemble", "friction_cross", "friction_cross_T", "normal_forces", "normal_penalty"]

#: The contact laws by name (``[contact] model``); add one with :func:`register_contact_law`.
CONTACT_LAWS: dict[str, type[ContactLaw]] = {GroundContact.model: GroundContact,
                                             CoulombContact.model: CoulombContact}


#: A law's variant on a height field (``Robot.ground``, :mod:`.surface`): the law class -> its
#: subclass that contacts the field instead of the plane ``y = 0``.
HEIGHT_FIELD_LAWS: dict[type[ContactLaw], type[ContactLaw]] = {GroundContact: PaperFieldContact,
                                                                CoulombContact: CoulombFieldContact}


def contact_term(robot) -> ContactLaw:
    """The contact energy term of ``robot``: its law (``robot.contact.law``) against the plane
    ``y = 0`` when ``robot.ground`` is None (the original kernels), else the law's
    :data:`HEIGHT_FIELD_LAWS` variant against the field (a ValueError for a law without one)."""
    law = robot.contact.law
    if getattr(robot, "ground", None) is None:
        return law(robot)
    if law not in HEIGHT_FIELD_LAWS:
        raise ValueError(f"{robot.source}: contact law {law.model!r} has no height-field variant "
                         f"(ground given; laws with one: {', '.join(k.model for k in HEIGHT_FIELD_LAWS)})")
    return HEIGHT_FIELD_LAWS[law](robot)


def register_contact_law(law: type[ContactLaw]) -> type[ContactLaw]:
    """Add ``law`` to :data:`CONTACT_LAWS` under ``law.model`` and return it (so it also works as
    a class decorator). A ValueError when the name is taken or empty, when a key in
    ``law.contact_parameters`` is not a field of :class:`ContactParams`, or when its friction
    parameter is not one of the keys it declares (to be calibrated or randomised it must also
    be a name of ``parameters.PARAMETERS``; :func:`~soft_envs.sim.parameters.check_parameters`
    refuses it otherwise)."""
    if not (isinstance(law, type) and issubclass(law, ContactLaw)):
        raise ValueError(f"a contact law must be a ContactLaw subclass, got {law!r}")
    if not law.model or law.model in CONTACT_LAWS:
        raise ValueError(f"{law.__name__}.model must be a new name, got {law.model!r} "
                         f"(registered: {', '.join(map(repr, CONTACT_LAWS))})")
    fields = {f.name for f in dataclasses.fields(ContactParams)} - {"model"}
    for p in law.contact_parameters:
        if p.name not in fields:
            raise ValueError(f"{law.__name__} reads [contact] key {p.name!r}, not a field of ContactParams "
                             f"({', '.join(sorted(fields))})")
    fp = law.friction_parameter
    if fp is not None and fp not in {p.name for p in law.contact_parameters}:
        raise ValueError(f"{law.__name__}.friction_parameter {fp!r} must be one of the [contact] keys the "
                         "law declares (contact_parameters)")
    CONTACT_LAWS[law.model] = law
    return law


def unregister_contact_law(model: str) -> None:
    """Remove the law ``model`` registered by :func:`register_contact_law` (the shipped laws
    stay)."""
    if model in (GroundContact.model, CoulombContact.model):
        raise ValueError(f"contact law {model!r} is built in and cannot be removed")
    CONTACT_LAWS.pop(model, None)


def contact_law(model: str) -> type[ContactLaw]:
    """The law registered as ``model``; a ValueError naming the field and the known laws."""
    try:
        return CONTACT_LAWS[model]
    except (KeyError, TypeError):
        raise ValueError(f"contact.model must be one of the contact laws {', '.join(map(repr, CONTACT_LAWS))}, "
                         f"got {model!r}") from None


def friction_parameters() -> tuple[str, ...]:
    """The friction parameters of the registered laws (each law's ``friction_parameter``)."""
    return tuple(dict.fromkeys(law.friction_parameter for law in CONTACT_LAWS.values()
                               if law.friction_parameter is not None))


def _declaration(key: str) -> ContactParameter | None:
    """The declaration of ``key`` by the first registered law that reads it."""
    return next((p for law in CONTACT_LAWS.values() for p in law.contact_parameters if p.name == key), None)


def contact_default(key: str) -> float:
    """The default of the ``[contact]`` key ``key`` (declared by the first law that reads it)."""
    p = _declaration(key)
    if p is None:
        raise ValueError(f"no contact law reads [contact] key {key!r}")
    return p.default


def check_contact_parameters(model: str, values: Mapping[str, float]) -> None:
    """``model`` a registered law and every value in ``values`` (``[contact]`` key -> value)
    within its bounds: the keys the law reads by its own declarations, the others by the first
    law that reads them (so a robot switched to another law later stays valid). A ValueError
    ``contact.<key> must be ..., got <value>`` otherwise."""
    own = {p.name: p for p in contact_law(model).contact_parameters}
    for key, value in values.items():
        p = own.get(key) or _declaration(key)
        if p is not None:
            p.check(value)


@dataclass(frozen=True)
class ContactParams:
    """Ground contact, the ``[contact]`` table of ``robot.toml``: a contact law ``model`` (a name
    of :data:`~soft_envs.sim.contact.CONTACT_LAWS`) and the parameters the laws read.

    ``"paper"`` (paper II-C, :mod:`soft_envs.sim.contact.paper`: friction energy
    ``friction * N_{k-1} |dx_t|^2`` with the weight ``friction`` [1/m]; viscous-like and
    time-step dependent) or ``"coulomb"`` (:mod:`soft_envs.sim.contact.coulomb`: tangential
    force bounded by ``friction_coefficient * N_{k-1}``, held by stick anchors until a node is
    ``slip_distance`` [m] from its anchor). Both: normal penalty ``stiffness`` [N/m] per node
    with a C2 ``blend`` [m] of the one-sided quadratic (``blend = 0``: the half-quadratic,
    Coulomb model only). Each law reads only its own parameters, declares them (defaults,
    units, bounds: ``contact_parameters``) and is validated by its declarations; the other
    fields by the law that reads them (:func:`~soft_envs.sim.contact.check_contact_parameters`)."""

    stiffness: float = contact_default("stiffness")
    friction: float = contact_default("friction")
    blend: float = contact_default("blend")
    model: str = "paper"
    friction_coefficient: float = contact_default("friction_coefficient")
    slip_distance: float = contact_default("slip_distance")

    def __post_init__(self):
        check_contact_parameters(self.model, {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                                              if f.name != "model"})

    @property
    def law(self) -> type[ContactLaw]:
        """The contact law class of :attr:`model` (an energy term: ``law(robot)``)."""
        return contact_law(self.model)
