"""What a ground contact law is: the :class:`ContactLaw` base of the contact energy terms, and
the :class:`ContactParameter` declarations of the ``[contact]`` keys a law reads.

Every law is an :class:`~soft_envs.sim.terms.EnergyTerm` over the *contact nodes* (the boundary
nodes that are not fixed) against the ground plane ``y = 0``: the normal penalty ``Q_n(-y_i)``
of stiffness ``k_n`` and blend ``eps_n`` (:mod:`.penalty`) plus, per law, a friction energy.
A law declares, as class attributes:

* ``model``: its name, the ``[contact] model`` of ``robot.toml`` and its key in
  :data:`soft_envs.sim.contact.CONTACT_LAWS`;
* ``contact_parameters``: the ``[contact]`` keys it reads (fields of
  :class:`~soft_envs.sim.robot.ContactParams`), each a :class:`ContactParameter` with its default,
  unit and lower bound; a robot's values are validated against the declarations of its law;
* ``friction_parameter``: the physical parameter (a name of
  :data:`soft_envs.sim.parameters.PARAMETERS`, read from the ``[contact]`` key of the same name)
  that calibration, domain randomisation and robustness studies scale as "friction", or None
  for a law without friction;
* ``parameters``: the physical parameters its gradient depends on
  (:meth:`~soft_envs.sim.terms.EnergyTerm.add_parameter_jacobian`); unless a law sets it,
  ``contact_stiffness`` and its friction parameter;
* ``default_substeps``: the physics steps per 0.033 s control step it is simulated with when
  none are asked for (the environments' ``substeps=None``, ``trajopt``'s default): the sub-steps
  that make its gaits' speeds converge (docs/fidelity.md). 1 unless a law sets it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..terms import EnergyTerm
from .penalty import normal_forces

__all__ = ["ContactParameter", "ContactLaw", "STIFFNESS", "BLEND"]


@dataclass(frozen=True)
class ContactParameter:
    """A ``[contact]`` key that a law reads: its ``name`` (a field of ``ContactParams``), its
    ``default``, ``unit`` and meaning, and its lower bound ``minimum`` (allowed itself when
    ``inclusive``; ``note`` says why in the error message)."""

    name: str
    default: float
    unit: str
    description: str
    minimum: float = 0.0
    inclusive: bool = False
    note: str = ""

    @property
    def requirement(self) -> str:
        """``"positive"``, ``">= 0"`` ... (what :meth:`check` demands, in words)."""
        if self.minimum == 0.0:
            text = ">= 0" if self.inclusive else "positive"
        else:
            text = f"{'>=' if self.inclusive else '>'} {self.minimum:g}"
        return f"{text} ({self.note})" if self.note else text

    def check(self, value: float) -> None:
        """ValueError ``contact.<name> must be <requirement>, got <value>`` unless ``value`` is
        finite and within the bound."""
        v = float(value)
        if not (math.isfinite(v) and (v >= self.minimum if self.inclusive else v > self.minimum)):
            raise ValueError(f"contact.{self.name} must be {self.requirement}, got {value!r}")


#: the normal penalty's stiffness k_n, read by every law
STIFFNESS = ContactParameter("stiffness", 2000.0, "N/m", "normal penalty stiffness k_n per contact node")
#: the width of the normal penalty's C2 blend eps_n (positive; the Coulomb law also allows 0)
BLEND = ContactParameter("blend", 5e-4, "m", "width eps_n of the normal penalty's C2 blend")


class ContactLaw(EnergyTerm):
    """Base of the ground contact laws (module docstring): the contact nodes, ``k_n`` and
    ``eps_n`` from ``robot.contact``, the normal forces and the normal penalty's parameter
    derivative. A law adds its friction: :meth:`energy` and :meth:`assemble` (the normal
    penalty of each node is :func:`.penalty.normal_penalty`) and the other
    :class:`~soft_envs.sim.terms.EnergyTerm` methods its energy needs."""

    name = "contact"
    model = ""
    contact_parameters: tuple[ContactParameter, ...] = (STIFFNESS, BLEND)
    friction_parameter: str | None = None
    parameters: tuple[str, ...] = ("contact_stiffness",)
    default_substeps: int = 1

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "parameters" not in cls.__dict__:
            cls.parameters = ("contact_stiffness",) + ((cls.friction_parameter,) if cls.friction_parameter else ())

    def __init__(self, robot):
        c = robot.contact
        self.k_n, self.eps_n = c.stiffness, c.blend
        self.nodes = np.setdiff1d(robot.mesh.boundary_nodes, robot.fixed_nodes).astype(np.int64)
        self._scratch = np.zeros(3 * robot.mesh.n_nodes)

    def normal_forces(self, x: np.ndarray) -> np.ndarray:
        """N_i = Q_n'(-y_i) at every contact node [N]."""
        return normal_forces(x, self.nodes, self.k_n, self.eps_n)

    def add_parameter_jacobian(self, x, x_prev, u, hist, names, out) -> None:
        """The normal penalty's part: Q_n' is linear in k_n, so the normal force ``-N(y)``
        gives ``-N / k_n``. A law with friction adds its own."""
        for j, n in enumerate(names):
            if n == "contact_stiffness":
                out[3 * self.nodes + 1, j] -= self.normal_forces(x) / self.k_n
