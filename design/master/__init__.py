"""The surgical master of seed 003: parameters, kinematics, mass model, CAD and MJCF."""

from hapticopt.design.master.params import MasterDesign

__all__ = ["MasterDesign"]
