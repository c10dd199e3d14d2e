"""Moved: the Coulomb contact law is :mod:`soft_envs.sim.contact.coulomb` (this module re-exports it)."""
from .contact.coulomb import *  # noqa: F401,F403
from .contact.coulomb import __all__  # noqa: F401
