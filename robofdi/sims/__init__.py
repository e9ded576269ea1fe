"""Simulated plants (the truth): MuJoCo systems with the effects their nominal models lack, and linear plants."""
from robofdi.sims.arm import ArmSettings, ArmSimulator, SensorModel, StribeckFriction, TorqueRipple
from robofdi.sims.linear import LinearPlant

__all__ = ["ArmSimulator", "ArmSettings", "SensorModel", "StribeckFriction", "TorqueRipple", "LinearPlant"]
