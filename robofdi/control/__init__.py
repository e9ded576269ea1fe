"""Reference trajectories, motion design and nominal controllers."""
from robofdi.control.computed_torque import ComputedTorque
from robofdi.control.motions import (
    SPEEDS,
    MotionLimits,
    calibration_motions,
    fit_duration,
    joint_ranges,
    random_point_to_point,
)
from robofdi.control.trajectory import Quintic, Sequence
from robofdi.control.linear import StateFeedback as StateFeedback, lqr_gain as lqr_gain

__all__ = [
    "ComputedTorque",
    "Quintic",
    "Sequence",
    "MotionLimits",
    "SPEEDS",
    "joint_ranges",
    "fit_duration",
    "random_point_to_point",
    "calibration_motions",
]
