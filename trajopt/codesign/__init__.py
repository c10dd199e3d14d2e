"""Co-design: a walking robot's gait and its design optimised together through the
same exact sensitivities (``trajopt codesign``). See docs/codesign.md."""
from .problem import CodesignProblem, CodesignWeights, InfeasibleDesign

__all__ = ["CodesignProblem", "CodesignWeights", "InfeasibleDesign"]
