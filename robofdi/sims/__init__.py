"""Simulated plants (the truth): MuJoCo systems with the effects their nominal models lack."""
from robofdi.sims.arm import ArmSettings, ArmSimulator, SensorModel, StribeckFriction, TorqueRipple

__all__ = ["ArmSimulator", "ArmSettings", "SensorModel", "StribeckFriction", "TorqueRipple"]
