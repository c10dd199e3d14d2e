r"""The parameter block of the sensitivity recurrence: what a set of parameters theta must give
for ``S_k = dx_k/dtheta`` to run alongside a rollout (paper III-A, eqs. 8-10 with theta in
place of the controls).

Differentiating every step's ``R_k = dE/dx(x_k; x_{k-1}, u_k, p_{k-1}; theta) + M(theta) a_k =
0`` with respect to theta adds ``-dR_k/dtheta = -(d(dE/dx)/dtheta + dM/dtheta a_k)`` to the
right-hand side of eq. 10, and the histories follow ``P_k = ... + dPi/dtheta``. A block gives
these three partial derivatives at fixed states:

* :meth:`ParameterBlock.force_jacobian`: ``d(dE/dx)/dtheta`` (3n, ntheta) of an energy system
  (the system is passed in: the rest relaxation runs its own, with its own gravity);
* :meth:`ParameterBlock.mass_jacobian`: ``dm/dtheta`` per dof (3n, ntheta);
* :meth:`ParameterBlock.history_jacobian`: per term ``d next_history/dtheta`` (or None);
* :meth:`ParameterBlock.rest_position_jacobian`: ``dX/dtheta`` of the rest mesh (or None), where
  the rest relaxation starts;
* :meth:`ParameterBlock.deformation_jacobian`: ``dGamma/dtheta`` (T, ntheta) of the cables'
  deformations at fixed x (the rollout's ``dgammadtheta`` adds ``dL/dx dx/dtheta``).

:class:`PhysicalParameters` is the block of the named physical parameters
(:data:`~.parameters.PARAMETERS`, ``trajopt calibrate``); design parameters
(:mod:`soft_envs.sim.design`) are another. :func:`parameter_block` turns what
``Simulator.rollout(params=...)`` accepts into a block.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ParameterBlock", "PhysicalParameters", "parameter_block"]


class ParameterBlock:
    """Interface of a parameter block (see the module docstring). ``names`` labels the columns."""

    names: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.names)

    def check(self, system) -> "ParameterBlock":
        """This block after checking that it belongs to ``system``'s robot (ValueError if not)."""
        return self

    def force_jacobian(self, system, x, x_prev, u, history) -> np.ndarray:
        """``d(dE/dx)/dtheta`` (3n, ntheta) at fixed x, x_prev, u and history."""
        raise NotImplementedError

    def mass_jacobian(self, system) -> np.ndarray:
        """``dm/dtheta`` per dof (3n, ntheta) of the diagonal mass matrix."""
        return np.zeros((system.n_dof, len(self)))

    def rest_position_jacobian(self, robot) -> np.ndarray | None:
        """``dX/dtheta`` (n, 3, ntheta) of the rest mesh's nodes, where the rest relaxation
        starts (None: the parameters do not move them)."""
        return None

    def history_jacobian(self, system, x, x_prev, history) -> tuple:
        """Per term ``d next_history/dtheta`` (flattened history, ntheta), None: no dependence."""
        return (None,) * len(system.terms)

    def deformation_jacobian(self, system, x) -> np.ndarray:
        """``dGamma/dtheta`` (T, ntheta) of the cables' deformations ``L(x) - alpha(u)`` at fixed
        x (zero: the physical parameters move neither the cables' points nor their lengths)."""
        return np.zeros((system.cables.n_tendons, len(self)))


class PhysicalParameters(ParameterBlock):
    """The block of named physical parameters (already checked against the system)."""

    def __init__(self, names):
        self.names = tuple(names)

    def force_jacobian(self, system, x, x_prev, u, history) -> np.ndarray:
        return system.parameter_jacobian(x, x_prev, u, self.names, history)

    def mass_jacobian(self, system) -> np.ndarray:
        return system.mass_jacobian(self.names)

    def history_jacobian(self, system, x, x_prev, history) -> tuple:
        return system.history_parameter_jacobian(x, x_prev, history, self.names)


def parameter_block(params) -> ParameterBlock:
    """``params`` as a block: a :class:`ParameterBlock` as it is, a sequence of physical
    parameter names as :class:`PhysicalParameters`."""
    return params if isinstance(params, ParameterBlock) else PhysicalParameters(params)
