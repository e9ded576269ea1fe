"""Faults written on one line, as the command line takes them (``robofdi run arm --fault SPEC``)::

    KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE ...]

    actuator_additive:joint2:20@1.0                 20 N·m on joint 2 from t = 1 s (step)
    actuator_additive:joint5:40@3.0~exponential_rise(0.08)   incipient: 40 (1 − e^{−(t−3)/0.08})
    sensor_bias:joint3_pos:0.004@1.5-2.5~ramp(0.5)  ramps to 4 mrad over 0.5 s, gone at 2.5 s
    actuator_loss_of_effectiveness:joint4:0.6@2     60 % loss of effectiveness
    actuator_hard_over:joint1:0@1~ramp(0.2);limit=150
    component_friction:joint3:1.5@1                 joint-3 friction × 2.5

Profiles, by the names a campaign TOML and summary.json use (:data:`robofdi.faults.profiles.PROFILE_TYPES`):
``step``, ``exponential_rise(TAU)``, ``exponential_growth(RATE)``, ``ramp(DURATION)``, ``sinusoid(FREQUENCY[,PHASE])``,
``oscillation(MEAN,AMPLITUDE,FREQUENCY[,PHASE])``, ``intermittent(PERIOD,DUTY)`` (seconds, hertz, radians, 1/s);
``exp(TAU)`` and ``sin(…)`` are accepted as short aliases. The fault's name is TARGET_KIND (``joint2_additive``),
numbered if repeated.
"""
from __future__ import annotations

import re
from collections.abc import Sequence

from robofdi.errors import RobofdiError
from robofdi.faults.fault import FAULT_KINDS, Fault, check_size
from robofdi.faults.profiles import (
    ExponentialGrowth, ExponentialRise, Intermittent, Oscillation, Profile, Ramp, Sinusoid, Step,
)

__all__ = ["parse_fault_spec", "parse_fault_specs", "SPEC_FORMAT", "PROFILE_HELP"]

SPEC_FORMAT = "KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE]"
_SPEC = re.compile(
    r"^(?P<kind>[a-z_]+):(?P<target>[^:@~;]+):(?P<magnitude>[^@]+)@(?P<onset>[0-9.]+(?:[eE][+-]?[0-9]*)?)(?:-(?P<end>[0-9.]+(?:[eE][+-]?[0-9]*)?))?"
    r"(?:~(?P<profile>[a-z_]+(?:\([^)]*\))?))?(?P<params>(?:;[a-z_]+=[^;]+)*)$"
)
#: canonical profile name (the serialised type name) → (class, least and most arguments, argument names)
_PROFILES = {
    Step.type_name: (Step, 0, 0, ""),
    ExponentialRise.type_name: (ExponentialRise, 1, 1, "TAU"),
    ExponentialGrowth.type_name: (ExponentialGrowth, 1, 1, "RATE"),
    Ramp.type_name: (Ramp, 1, 1, "DURATION"),
    Sinusoid.type_name: (Sinusoid, 1, 2, "FREQUENCY[,PHASE]"),
    Oscillation.type_name: (Oscillation, 3, 4, "MEAN,AMPLITUDE,FREQUENCY[,PHASE]"),
    Intermittent.type_name: (Intermittent, 2, 2, "PERIOD,DUTY"),
}
#: short names the command line has always accepted
_ALIASES = {"exp": ExponentialRise.type_name, "sin": Sinusoid.type_name}
#: the profiles as the help text shows them
PROFILE_HELP = ", ".join(f"{name}({args})" if args else name for name, (_, _, _, args) in _PROFILES.items())


def _number(text: str, what: str, spec: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise RobofdiError(f"fault spec {spec!r}: {what} must be a number, got {text!r}") from None


def _profile(text: str, spec: str) -> Profile:
    m = re.fullmatch(r"([a-z_]+)(?:\((.*)\))?", text)
    name, args = m.group(1), m.group(2)          # name: as typed (an alias stays in the messages)
    if _ALIASES.get(name, name) not in _PROFILES:
        raise RobofdiError(f"fault spec {spec!r}: unknown profile {name!r}; expected one of {PROFILE_HELP}")
    cls, lo, hi, _ = _PROFILES[_ALIASES.get(name, name)]
    values = [_number(a.strip(), f"profile {name} argument", spec) for a in args.split(",")] if args else []
    if not lo <= len(values) <= hi:
        raise RobofdiError(f"fault spec {spec!r}: profile {name} takes {lo if lo == hi else f'{lo} to {hi}'} "
                           f"argument(s), got {len(values)}")
    try:
        return cls(*values)
    except RobofdiError as exc:
        raise RobofdiError(f"fault spec {spec!r}: {exc}") from None


def parse_fault_spec(spec: str, name: str | None = None) -> Fault:
    """One :class:`Fault` from ``KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE]`` (module docstring)."""
    if not isinstance(spec, str):
        raise RobofdiError(f"fault spec: expected a string {SPEC_FORMAT}, got {spec!r}")
    text = spec.strip()
    m = _SPEC.match(text)
    if m is None:
        raise RobofdiError(f"fault spec {spec!r}: expected {SPEC_FORMAT}, e.g. actuator_additive:joint2:20@1.0")
    kind = m.group("kind")
    if kind not in FAULT_KINDS:
        raise RobofdiError(f"fault spec {spec!r}: unknown kind {kind!r}; expected one of {', '.join(FAULT_KINDS)}")
    params = {}
    for item in filter(None, m.group("params").split(";")):
        key, value = item.split("=", 1)
        params[key] = _number(value, f"parameter {key}", spec)
    end = m.group("end")
    profile = _profile(m.group("profile"), spec) if m.group("profile") else Step()
    target = m.group("target")
    onset, magnitude = _number(m.group("onset"), "ONSET", spec), _number(m.group("magnitude"), "MAGNITUDE", spec)
    end = None if end is None else _number(end, "END", spec)
    try:
        fault = Fault(name or f"{target}_{kind.split('_', 1)[1]}", kind, target, onset=onset, end=end,
                      magnitude=magnitude, profile=profile, params=params)
        check_size(fault)
        return fault
    except RobofdiError as exc:
        raise RobofdiError(f"fault spec {spec!r}: {exc}") from None


def parse_fault_specs(specs: Sequence[str]) -> tuple[Fault, ...]:
    """Several specs; repeated default names are numbered (``joint2_additive``, ``joint2_additive_2``)."""
    faults, seen = [], {}
    for spec in specs:
        fault = parse_fault_spec(spec)
        count = seen.get(fault.name, 0) + 1
        seen[fault.name] = count
        if count > 1:
            fault = parse_fault_spec(spec, f"{fault.name}_{count}")
        faults.append(fault)
    return tuple(faults)
