"""Reference trajectories and nominal controllers."""
from robofdi.control.computed_torque import ComputedTorque
from robofdi.control.trajectory import Quintic, Sequence

__all__ = ["ComputedTorque", "Quintic", "Sequence"]
