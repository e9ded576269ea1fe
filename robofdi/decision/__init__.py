"""Residual evaluation: thresholds from fault-free runs (fixed, or for a false-alarm rate per hour),
operating-point bounds, and isolation by fault signatures."""
from robofdi.decision.identification import Identification
from robofdi.decision.isolation import STARTUP_BLANKING, Alarms, Signature, ThresholdDecision, startup_samples
from robofdi.decision.thresholds import calibrate_thresholds, extreme_value_thresholds

__all__ = ["Identification", "calibrate_thresholds", "extreme_value_thresholds", "Signature", "Alarms",
           "ThresholdDecision", "STARTUP_BLANKING", "startup_samples"]
