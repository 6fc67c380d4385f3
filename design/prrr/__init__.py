"""The 3-PRRR of seed 002: parameters, kinematics, CAD and MJCF."""

from hapticopt.design.prrr.params import PrrrDesign

__all__ = ["PrrrDesign"]
