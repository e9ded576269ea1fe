"""Residual evaluation: fixed thresholds calibrated on fault-free runs, and isolation by fault signatures."""
from robofdi.decision.thresholds import calibrate_thresholds
from robofdi.decision.identification import Identification
from robofdi.decision.isolation import Alarms, Signature, ThresholdDecision

__all__ = ["Identification", "calibrate_thresholds", "Signature", "Alarms", "ThresholdDecision"]
