"""Design parameters of a robot: regional Young's moduli, tendon routing and leg
lengths, declared in robot.toml's ``[design]``, with their derivatives for the sensitivity
recurrence. See docs/codesign.md."""
from .block import MAX_MASS_LOSS, DesignParameters
from .clearance import MIN_CLEARANCE, signed_distance
from .declaration import KINDS, load_design
from .morph import LegMorph, legs_below
from .regions import Region, RegionalModuli, region_from_boxes, region_from_cell_tags
from .routing import TendonRouting, cable_gradient_point_jacobian, embedding_jacobian
from .writer import write_designed_robot

__all__ = ["DesignParameters", "MAX_MASS_LOSS", "MIN_CLEARANCE", "signed_distance", "Region", "RegionalModuli",
           "region_from_boxes", "region_from_cell_tags", "TendonRouting", "cable_gradient_point_jacobian",
           "embedding_jacobian", "LegMorph", "legs_below", "KINDS",
           "load_design", "write_designed_robot"]
