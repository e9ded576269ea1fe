"""Simulated plants (the truth): MuJoCo systems with the effects their nominal models lack."""
from robofdi.sims.arm import ArmSimulator, SensorModel, TorqueRipple
from robofdi.sims.linear import LinearPlant as LinearPlant

__all__ = ["ArmSimulator", "SensorModel", "TorqueRipple"]
