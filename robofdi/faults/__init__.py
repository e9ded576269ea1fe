"""Fault models: time profiles, fault descriptions and the injector that applies them to u, y and plant components."""
from robofdi.faults.fault import FAULT_KINDS, MAGNITUDE_FREE, Fault, FaultKind, check_sampling, check_size
from robofdi.faults.injector import FaultInjector, check_faults
from robofdi.faults.spec import SPEC_FORMAT, parse_fault_spec, parse_fault_specs
from robofdi.faults.profiles import (
    PROFILE_TYPES,
    ExponentialGrowth,
    ExponentialRise,
    Intermittent,
    Oscillation,
    Profile,
    Ramp,
    Sinusoid,
    Step,
    profile_from_dict,
)

__all__ = [
    "Profile",
    "Step",
    "ExponentialRise",
    "ExponentialGrowth",
    "Ramp",
    "Sinusoid",
    "Intermittent",
    "Oscillation",
    "PROFILE_TYPES",
    "profile_from_dict",
    "Fault",
    "FAULT_KINDS",
    "FaultKind",
    "MAGNITUDE_FREE",
    "check_sampling",
    "check_size",
    "FaultInjector",
    "check_faults",
    "SPEC_FORMAT",
    "parse_fault_spec",
    "parse_fault_specs",
]
