"""Domain randomisation: multiplicative ranges on physical parameters, drawn at reset.

``{"friction": (0.7, 1.3), "youngs_modulus": (0.8, 1.2), "payload_mass": (0.9, 1.1)}`` means:
at every reset draw a factor uniformly from each range (keys in sorted order, from the
environment's ``np_random``) and multiply the nominal robot's parameter by it. Keys:

========================  =====================================================================
``friction``              ground friction: the friction parameter of the robot's contact law
                          (``ContactLaw.friction_parameter``: the paper law's weight
                          ``robot.contact.friction``, the Coulomb law's ``friction_coefficient``;
                          a law without friction draws the factor and ignores it)
``contact_stiffness``     ground penalty stiffness ``robot.contact.stiffness``
``youngs_modulus``        Young's modulus of the foam
``density``               foam density (body mass)
``payload_mass``          mass of the motor assembly on top
========================  =====================================================================

``domain_randomization=True`` draws from :data:`DEFAULT_DOMAIN_RANDOMIZATION`: friction
(0.7, 1.3) and Young's modulus (0.8, 1.2), the two parameters fitted rather than measured
(paper II-A), and foam density and payload mass (0.9, 1.1), weighed ones.

A reset never fails because of a draw (:func:`draw_standing_robot`): a drawn robot that cannot
stand at rest (its rest state does not settle: e.g. a soft, heavy body on soft ground) is
redrawn, up to :data:`MAX_DOMAIN_DRAWS` times from the same ``np_random``, so the factors are
drawn from the ranges given the robot can stand; if no draw stands, the episode uses the
nominal robot (all factors 1) and Gymnasium's logger warns. The reset's ``info`` reports
``domain_parameters`` (the factors used), ``domain_draws`` (draws made) and
``domain_fallback`` (True when the nominal robot was used).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np
from gymnasium import logger

from ..sim import Robot, SimulationError
from ..sim.parameters import scale_parameters

__all__ = ["DOMAIN_KEYS", "DEFAULT_DOMAIN_RANDOMIZATION", "MAX_DOMAIN_DRAWS", "parse_domain_randomization",
           "sample_factors", "randomized_robot", "draw_standing_robot"]

#: Draws per reset before the nominal robot is used (see the module docstring).
MAX_DOMAIN_DRAWS = 8

DOMAIN_KEYS = ("contact_stiffness", "density", "friction", "payload_mass", "youngs_modulus")

#: The ranges of ``domain_randomization=True``.
DEFAULT_DOMAIN_RANDOMIZATION: Mapping[str, tuple[float, float]] = MappingProxyType({
    "friction": (0.7, 1.3), "youngs_modulus": (0.8, 1.2), "density": (0.9, 1.1), "payload_mass": (0.9, 1.1)})


def parse_domain_randomization(spec: Mapping[str, tuple[float, float]] | bool | None
                               ) -> dict[str, tuple[float, float]] | None:
    """Validate a randomisation spec (a dict, True for :data:`DEFAULT_DOMAIN_RANDOMIZATION`,
    False or None for none); returns ``{key: (lo, hi)}`` in sorted key order, or None."""
    if spec is None or spec is False:
        return None
    if spec is True:
        spec = DEFAULT_DOMAIN_RANDOMIZATION
    if not isinstance(spec, Mapping):
        raise TypeError(f"domain_randomization must be a dict, True (the default ranges), False or None, "
                        f"got {type(spec).__name__}")
    out: dict[str, tuple[float, float]] = {}
    for key in sorted(spec):
        if key not in DOMAIN_KEYS:
            raise ValueError(f"domain_randomization: unknown key {key!r}; known keys: {list(DOMAIN_KEYS)}")
        try:
            lo, hi = (float(v) for v in spec[key])
        except (TypeError, ValueError):
            raise ValueError(f"domain_randomization[{key!r}] must be a (low, high) pair of factors, "
                             f"got {spec[key]!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo <= hi):
            raise ValueError(f"domain_randomization[{key!r}] needs 0 < low <= high, got ({lo}, {hi})")
        out[key] = (lo, hi)
    return out or None


def sample_factors(ranges: Mapping[str, tuple[float, float]], rng: np.random.Generator) -> dict[str, float]:
    """One multiplicative factor per key (sorted key order, one uniform draw each)."""
    return {k: float(rng.uniform(*ranges[k])) for k in sorted(ranges)}


def randomized_robot(base: Robot, factors: Mapping[str, float]) -> Robot:
    """``base`` with its parameters multiplied by ``factors`` (``base`` itself if all are 1;
    :func:`soft_envs.sim.parameters.scale_parameters`, ``"friction"`` the contact law's)."""
    return scale_parameters(base, factors)


def draw_standing_robot(ranges: Mapping[str, tuple[float, float]], rng: np.random.Generator,
                        use: Callable[[Mapping[str, float]], None]) -> dict[str, Any]:
    """Draw factors and ``use(factors)`` them (which raises SimulationError when that robot
    cannot stand at rest, changing nothing) until one stands, at most :data:`MAX_DOMAIN_DRAWS`
    times; then the nominal factors. Returns the reset ``info`` entries (module docstring)."""
    failures = []
    for draw in range(1, MAX_DOMAIN_DRAWS + 1):
        factors = sample_factors(ranges, rng)
        try:
            use(factors)
        except SimulationError as err:
            failures.append(f"{ {k: round(v, 3) for k, v in factors.items()} }: {err}")
            continue
        return {"domain_parameters": factors, "domain_draws": draw, "domain_fallback": False}
    nominal = {k: 1.0 for k in sorted(ranges)}
    use(nominal)
    logger.warn(f"domain randomisation: none of {MAX_DOMAIN_DRAWS} draws could stand at rest (last: {failures[-1]}); "
                "this episode uses the nominal robot (all factors 1)")
    return {"domain_parameters": nominal, "domain_draws": MAX_DOMAIN_DRAWS, "domain_fallback": True}
