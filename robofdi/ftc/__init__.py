"""Accommodation: what stands between the controller and the actuators (allocation, compensation, reconfiguration)."""
from robofdi.ftc.compensation import FaultCompensation

__all__ = ["FaultCompensation"]
