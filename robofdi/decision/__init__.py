"""Residual evaluation: fixed thresholds calibrated on fault-free runs, and isolation by fault signatures."""
from robofdi.decision.thresholds import calibrate_thresholds
from robofdi.decision.identification import Identification
from robofdi.decision.isolation import STARTUP_BLANKING, Alarms, Signature, ThresholdDecision, startup_samples
from robofdi.decision.multiple_model import SwitchingIndexDecision
from robofdi.decision.directional import DirectionalDecision
from robofdi.decision.windowed import WindowedTTest

__all__ = ["Identification", "calibrate_thresholds", "Signature", "Alarms", "ThresholdDecision", "STARTUP_BLANKING",
           "startup_samples", "SwitchingIndexDecision", "WindowedTTest",
           "DirectionalDecision"]
