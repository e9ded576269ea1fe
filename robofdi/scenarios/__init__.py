"""Scenario assembly: a validated configuration turned into a calibrated closed loop, per system."""
