"""Residual evaluation: thresholds from fault-free runs (fixed, or for a false-alarm rate per hour),
operating-point bounds, isolation by fault signatures, directional and multiple-model decisions, windowed tests,
the sliding-mode residuals' peak (max-hold) and logic-table decisions, Hotelling T²."""
from robofdi.decision.identification import Identification
from robofdi.decision.isolation import STARTUP_BLANKING, Alarms, Signature, ThresholdDecision, startup_samples
from robofdi.decision.thresholds import calibrate_thresholds, extreme_value_thresholds
from robofdi.decision.multiple_model import NisBankDecision, SupervisorStatusDecision, SwitchingIndexDecision
from robofdi.decision.directional import DirectionalDecision
from robofdi.decision.windowed import WindowedTTest
from robofdi.decision.peak import LogicRule, LogicTableDecision, PeakHoldDecision
from robofdi.decision.hotelling import HotellingT2Decision, hotelling_fit

__all__ = ["Identification", "calibrate_thresholds", "extreme_value_thresholds", "Signature", "Alarms",
           "ThresholdDecision", "STARTUP_BLANKING", "startup_samples", "SwitchingIndexDecision", "NisBankDecision",
           "SupervisorStatusDecision", "WindowedTTest", "DirectionalDecision", "PeakHoldDecision", "LogicRule",
           "LogicTableDecision", "HotellingT2Decision", "hotelling_fit"]
