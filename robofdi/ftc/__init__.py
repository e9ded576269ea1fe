"""Accommodation: what stands between the controller and the actuators (allocation, compensation, reconfiguration)."""
from robofdi.ftc.compensation import FaultCompensation
from robofdi.ftc.effectiveness import EffectivenessCompensation, GainCompensation, reduced_actuator_set

__all__ = ["FaultCompensation", "EffectivenessCompensation", "GainCompensation", "reduced_actuator_set"]
