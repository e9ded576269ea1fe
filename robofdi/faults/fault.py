"""The :class:`Fault` description: what fails, how, when and how much."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any
from collections.abc import Mapping

from robofdi import RobofdiError
from robofdi.faults.profiles import Profile, Step, profile_from_dict

__all__ = ["Fault", "FaultKind", "FAULT_KINDS", "MAGNITUDE_FREE", "check_sampling", "check_size"]


@dataclass(frozen=True)
class _ParamSpec:
    """One kind-specific parameter: its check, description and whether it must be given."""

    check: Any
    expected: str
    required: bool = False


_LIMIT = _ParamSpec(lambda v: True, "a finite number", required=True)
_DELAY = _ParamSpec(lambda v: 0 < v <= 60, "a delay in (0, 60] s", required=True)
_PROBABILITY = _ParamSpec(lambda v: 0 < v <= 1, "a finite number in (0, 1]", required=True)
_NON_NEGATIVE = _ParamSpec(lambda v: v >= 0, ">= 0")


@dataclass(frozen=True)
class FaultKind:
    """What a fault kind accepts and how it can be emulated.

    profiles: "any" profile; "unit" — only profiles with p(s) in [0, 1] (the kind blends the nominal value into
    the faulty one, out = (1 − p)·x + p·x_fault); "step" — only Step (the kind has its own time law).
    offline: the effect on an actuator command is invertible, so a fault-free run can emulate it exactly
    (the diagnosers are told ū with faulty(ū) = u).
    unit: unit of ``magnitude`` ("target" = the unit of the target channel).
    """

    params: Mapping[str, _ParamSpec] = field(default_factory=dict)
    profiles: str = "any"
    offline: bool = False
    unit: str = "target"
    description: str = ""
    values: _ParamSpec | None = None     # what the effect m·p may be (component kinds: what the plant can take)


#: Fault kind -> its :class:`FaultKind`. The prefix before "_" is the family: actuator, sensor or component.
FAULT_KINDS: dict[str, FaultKind] = {
    "actuator_additive": FaultKind(offline=True, description="u + m·p (bias; intermittent with an Intermittent profile)"),
    "actuator_drift": FaultKind(profiles="step", offline=True, unit="target/s", description="u + m·(t − onset)"),
    "actuator_loss_of_effectiveness": FaultKind(profiles="unit", offline=True, unit="1",
                                                description="u·(1 − m·p), m in [0, 1]"),
    "actuator_scale": FaultKind(unit="1", offline=True, description="u·(1 + m·p), actuator gain change (either sign)"),
    "actuator_lock_in_place": FaultKind(profiles="unit", description="held at its value at onset"),
    "actuator_float": FaultKind(profiles="unit", description="zero output (1 − p)·u"),
    "actuator_hard_over": FaultKind({"limit": _LIMIT}, profiles="unit",
                                    description="u₀ + p·(limit − u₀); a Ramp profile rate-limits it"),
    "sensor_bias": FaultKind(description="y + m·p"),
    "sensor_drift": FaultKind(profiles="step", unit="target/s", description="y + m·(t − onset)"),
    "sensor_freeze": FaultKind(profiles="unit", description="held at its value at onset"),
    "sensor_dropout": FaultKind(profiles="unit", description="reads zero (1 − p)·y"),
    "sensor_scale": FaultKind(unit="1", description="y·(1 + m·p)"),
    "sensor_noise": FaultKind(description="y + N(0, (m·p)²), loss of accuracy"),
    "sensor_delay": FaultKind({"delay": _DELAY}, profiles="unit", description="y(t − delay·p)"),
    "sensor_outliers": FaultKind({"probability": _PROBABILITY}, description="y ± m·p with the given probability per sample"),
    "component_friction": FaultKind(unit="1", description="joint friction × (1 + m·p) (friction rise)",
                                    values=_ParamSpec(lambda v: v > -1, "> -1 (friction cannot become negative)")),
    "component_mass": FaultKind(unit="kg", description="m·p kg added to a body (damage, payload change)",
                                values=_NON_NEGATIVE),
    "component_thruster_blocking": FaultKind(profiles="unit", unit="1", values=_NON_NEGATIVE,
                                             description="rotor stalled while m·p > 0 (solid body in the blades)"),
    "component_thruster_flooding": FaultKind(unit="1", values=_NON_NEGATIVE,
                                             description="flooded thruster: motor drive × (1 + m·p), leakage current"),
    "component_open_winding": FaultKind(profiles="unit", unit="1", values=_ParamSpec(lambda v: 0 <= v <= 1, "in [0, 1]"),
                                        description="servovalve coil current × (1 − m·p); m = 1 an open circuit"),
    "component_valve_sticking": FaultKind(unit="1", values=_NON_NEGATIVE,
                                          description="spool stick–slip with a stiction band of m·p (stroke)"),
    "component_leak": FaultKind(unit="mm^2", values=_NON_NEGATIVE,
                                description="orifice of m·p mm² from a motor line to tank (ruptured line)"),
    "component_wing_damage": FaultKind(profiles="unit", unit="1", values=_ParamSpec(lambda v: 0 <= v <= 1, "in [0, 1]"),
                                       description="structural damage ρ = m·p in [0, 1] of a wing (A(ρ), B(ρ))"),
}


#: Kinds whose effect does not depend on ``magnitude`` (it is ignored: 0 by convention); every other kind scales
#: with it, so a zero magnitude is a fault that never acts and is refused.
MAGNITUDE_FREE = ("actuator_lock_in_place", "actuator_float", "actuator_hard_over", "sensor_freeze", "sensor_dropout",
                  "sensor_delay")


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass(frozen=True)
class Fault:
    """One fault on one actuator, sensor channel or plant component, active on [onset, end).

    ``magnitude`` m and ``profile`` p(t - onset) set the size; ``params`` holds kind-specific
    settings (see :data:`FAULT_KINDS`); ``seed`` fixes its randomness (None: derived from the run's seed).
    Every kind honours its profile or rejects, at construction, a profile it cannot use.
    """

    name: str
    kind: str
    target: str
    onset: float
    end: float | None = None
    magnitude: float = 0.0
    profile: Profile = Step()
    params: Mapping[str, float] = field(default_factory=dict)
    seed: int | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise RobofdiError(f"Fault: field 'name' must be a non-empty string, got {self.name!r}")
        who = f"Fault {self.name!r}"
        if self.kind not in FAULT_KINDS:
            raise RobofdiError(f"{who}: unknown kind {self.kind!r}; expected one of {', '.join(FAULT_KINDS)}")
        if not isinstance(self.target, str) or not self.target:
            raise RobofdiError(f"{who}: field 'target' must be a non-empty string, got {self.target!r}")
        if not _finite(self.onset) or self.onset < 0:
            raise RobofdiError(f"{who}: field 'onset' must be a finite number >= 0, got {self.onset!r}")
        if self.end is not None and (not _finite(self.end) or self.end <= self.onset):
            raise RobofdiError(
                f"{who}: field 'end' must be None or a finite number > onset ({self.onset}), got {self.end!r}"
            )
        if not _finite(self.magnitude):
            raise RobofdiError(f"{who}: field 'magnitude' must be a finite number, got {self.magnitude!r}")
        if self.kind == "actuator_loss_of_effectiveness" and not 0 <= self.magnitude <= 1:
            raise RobofdiError(f"{who}: field 'magnitude' must be in [0, 1] for {self.kind}, got {self.magnitude!r}")
        if self.kind == "component_wing_damage" and not 0 <= self.magnitude <= 1:
            raise RobofdiError(f"{who}: field 'magnitude' must be in [0, 1] for {self.kind} (damage fraction ρ), "
                               f"got {self.magnitude!r}")
        if self.kind == "sensor_noise" and self.magnitude < 0:
            raise RobofdiError(
                f"{who}: field 'magnitude' must be >= 0 for {self.kind} (standard deviation), got {self.magnitude!r}"
            )
        if not isinstance(self.profile, Profile):
            raise RobofdiError(f"{who}: field 'profile' must be a Profile, got {self.profile!r}")
        accepts = FAULT_KINDS[self.kind].profiles
        if accepts == "step" and not isinstance(self.profile, Step):
            raise RobofdiError(
                f"{who}: field 'profile' must be step for {self.kind} (it grows linearly by itself); "
                f"for another shape use {self.family}_{'additive' if self.family == 'actuator' else 'bias'} with that profile"
            )
        if accepts == "unit" and not self.profile.unit_range:
            raise RobofdiError(
                f"{who}: field 'profile' must stay in [0, 1] for {self.kind} (step, exponential_rise, ramp or "
                f"intermittent), got {self.profile.type_name}"
            )
        values = FAULT_KINDS[self.kind].values
        if values is not None:
            for p in self.profile.bounds:
                if not values.check(self.magnitude * p):
                    raise RobofdiError(f"{who}: field 'magnitude': the effect magnitude·p(t) reaches "
                                       f"{self.magnitude * p:g} with profile {self.profile.type_name}; {self.kind} "
                                       f"expects it {values.expected}")
        if self.seed is not None and (not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0):
            raise RobofdiError(f"{who}: field 'seed' must be None or an integer >= 0, got {self.seed!r}")
        self._check_params(who)
        # private copy with float values, so later edits of the caller's dict cannot change the fault
        object.__setattr__(self, "params", {k: float(v) for k, v in self.params.items()})
        object.__setattr__(self, "onset", float(self.onset))
        object.__setattr__(self, "magnitude", float(self.magnitude))
        if self.end is not None:
            object.__setattr__(self, "end", float(self.end))

    def _check_params(self, who: str) -> None:
        if not isinstance(self.params, Mapping):
            raise RobofdiError(f"{who}: field 'params' must be a mapping, got {self.params!r}")
        specs = FAULT_KINDS[self.kind].params
        unknown = sorted(set(self.params) - set(specs))
        if unknown:
            raise RobofdiError(
                f"{who}: unknown params {', '.join(map(repr, unknown))} for kind {self.kind!r}; "
                f"expected {', '.join(specs) or 'no params'}"
            )
        for key, spec in specs.items():
            if key not in self.params:
                if spec.required:
                    raise RobofdiError(f"{who}: kind {self.kind!r} requires params[{key!r}] ({spec.expected})")
                continue
            value = self.params[key]
            if not _finite(value) or not spec.check(value):
                raise RobofdiError(f"{who}: field 'params[{key!r}]' must be {spec.expected}, got {value!r}")

    def __hash__(self):
        return hash((self.name, self.kind, self.target, self.onset, self.end, self.magnitude,
                     self.profile, tuple(sorted(self.params.items())), self.seed))

    @property
    def family(self) -> str:
        """"actuator", "sensor" or "component"."""
        return self.kind.split("_", 1)[0]

    def active(self, t: float) -> bool:
        """True on the window onset <= t < end (end None: forever)."""
        return self.onset <= t and (self.end is None or t < self.end)

    def to_dict(self) -> dict:
        """Plain JSON-serialisable dict, inverse of :meth:`from_dict`."""
        return {
            "name": self.name,
            "kind": self.kind,
            "target": self.target,
            "onset": self.onset,
            "end": self.end,
            "magnitude": self.magnitude,
            "profile": self.profile.to_dict(),
            "params": dict(self.params),
            "seed": self.seed,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Fault:
        """Build from a plain dict (e.g. parsed JSON); ``profile`` may be a dict with a ``type`` key."""
        if not isinstance(d, Mapping):
            raise RobofdiError(f"Fault: expected a mapping, got {type(d).__name__}")
        who = f"Fault {d.get('name', '<unnamed>')!r}"
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise RobofdiError(f"{who}: unknown key(s) {', '.join(map(repr, unknown))}; expected {', '.join(names)}")
        missing = [k for k in ("name", "kind", "target", "onset") if k not in d]
        if missing:
            raise RobofdiError(f"{who}: missing required key(s) {', '.join(map(repr, missing))}")
        kwargs = dict(d)
        if kwargs.get("profile") is None:
            kwargs.pop("profile", None)
        else:
            try:
                kwargs["profile"] = profile_from_dict(kwargs["profile"])
            except RobofdiError as exc:
                raise RobofdiError(f"{who}: field 'profile': {exc}") from None
        if kwargs.get("params") is None:
            kwargs.pop("params", None)
        return cls(**kwargs)


def check_sampling(faults, control_hz: float) -> None:
    """Refuse faults the control-rate sampling cannot represent, and faults that contradict each other
    (part of :func:`robofdi.faults.check_faults`).

    * A sinusoidal profile at or above the Nyquist frequency control_hz/2 aliases (sin(2πf·k/f_s) can be 0 at
      every sample: the label and the effect vanish), Shannon's sampling theorem.
    * An intermittent profile whose on or off phase is shorter than one control sample is not that pattern once
      sampled (a 1 µs period is on most of the time at 1 kHz).
    * A zero magnitude for a kind that scales with it (:func:`check_size`).
    * Two faults of one kind that each set the target's value (lock, float, hard-over, freeze, dropout, delay) on
      the same target at overlapping times cannot both be true.
    """
    from robofdi.faults.profiles import Intermittent, Oscillation, Sinusoid

    dt = 1.0 / control_hz
    for f in faults:
        p, who = f.profile, f"Fault {f.name!r}"
        check_size(f)
        if isinstance(p, (Sinusoid, Oscillation)) and p.frequency >= 0.5 * control_hz:
            raise RobofdiError(f"{who}: field 'profile': frequency {p.frequency:g} Hz is at or above the Nyquist "
                               f"frequency {0.5 * control_hz:g} Hz of the {control_hz:g} Hz control loop (it aliases); "
                               f"expected < {0.5 * control_hz:g} Hz")
        if isinstance(p, Intermittent):
            on, off = p.duty * p.period, (1.0 - p.duty) * p.period
            if on < dt * (1 - 1e-9) or (p.duty < 1 and off < dt * (1 - 1e-9)):
                raise RobofdiError(f"{who}: field 'profile': intermittent on {on:g} s / off {off:g} s, shorter than one "
                                   f"control sample ({dt:g} s at {control_hz:g} Hz); expected on and off phases >= {dt:g} s")
    setting = [f for f in faults if f.kind in MAGNITUDE_FREE]
    for i, a in enumerate(setting):
        for b in setting[i + 1:]:
            if a.kind == b.kind and a.target == b.target and _overlap(a, b):
                raise RobofdiError(f"Fault {b.name!r}: contradicts fault {a.name!r}: two {a.kind} faults on "
                                   f"{a.target!r} at overlapping times; expected at most one at a time")


def _overlap(a: Fault, b: Fault) -> bool:
    a_end = math.inf if a.end is None else a.end
    b_end = math.inf if b.end is None else b.end
    return a.onset < b_end and b.onset < a_end


def check_size(fault: Fault) -> None:
    """Refuse a fault of size zero of a kind whose effect scales with ``magnitude`` (not :data:`MAGNITUDE_FREE`): it
    never acts, and a diagnoser would be scored as missing it; and a non-zero magnitude for a kind that ignores it
    (lock, freeze, …): the user meant something the fault will not do."""
    if fault.magnitude == 0 and fault.kind not in MAGNITUDE_FREE:
        raise RobofdiError(f"Fault {fault.name!r}: field 'magnitude' must not be 0 for {fault.kind} (a fault of size "
                           "zero never acts, and would be scored as a missed detection)")
    if fault.magnitude != 0 and fault.kind in MAGNITUDE_FREE:
        raise RobofdiError(f"Fault {fault.name!r}: field 'magnitude' must be 0 for {fault.kind}: the kind ignores it "
                           f"(its effect is set by the profile{' and params' if FAULT_KINDS[fault.kind].params else ''}), "
                           f"got {fault.magnitude:g}")
