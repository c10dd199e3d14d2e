"""Physics of cable-driven soft robots (no Gymnasium import here).

Public names: :class:`Robot`, :func:`load_robot`, :class:`Simulator`, :class:`Trajectory`,
:class:`SimulationError`, :class:`TetMesh`, :func:`load_mesh`, :func:`incline_gravity`.
"""
from .contact import incline_gravity
from .integrator import NewtonOptions, SimulationError
from .mesh import TetMesh, load_mesh
from .robot import ContactParams, Motor, Robot, Tendon
from .simulator import Simulator, Trajectory

__all__ = ["Robot", "Tendon", "Motor", "ContactParams", "Simulator", "Trajectory", "SimulationError",
           "NewtonOptions", "TetMesh", "load_mesh", "incline_gravity", "load_robot"]


def load_robot(name_or_path, **overrides):
    """Load a shipped robot by name (``"tripod"``, ``"puppy"``) or a ``robot.toml`` path."""
    from .robot_file import load_robot as _load
    return _load(name_or_path, **overrides)
