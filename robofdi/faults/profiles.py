"""Time profiles of a fault: how its effect grows with the time ``s`` elapsed since onset."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any
from collections.abc import Mapping

from robofdi import RobofdiError

__all__ = [
    "Profile",
    "Step",
    "ExponentialRise",
    "ExponentialGrowth",
    "Ramp",
    "Sinusoid",
    "Intermittent",
    "PROFILE_TYPES",
    "profile_from_dict",
]


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _positive(owner: str, name: str, value: Any) -> None:
    if not _is_number(value) or value <= 0:
        raise RobofdiError(f"{owner}: field '{name}' must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class Profile:
    """Base class: a shape p(s) of the fault over the elapsed time s >= 0 since onset."""

    type_name = ""  # serialised name, set by subclasses (class attribute, not a field)
    unit_range = True  # p(s) stays in [0, 1] (class attribute)

    @property
    def bounds(self) -> tuple[float, float]:
        """The least and the greatest value p(s) takes (a fault's effect is magnitude·p)."""
        return (0.0, 1.0)

    def __call__(self, s: float) -> float:  # pragma: no cover - abstract
        raise NotImplementedError

    def to_dict(self) -> dict:
        """Plain JSON-serialisable description, inverse of :func:`profile_from_dict`."""
        return {"type": self.type_name, **{k: float(v) for k, v in asdict(self).items()}}


@dataclass(frozen=True)
class Step(Profile):
    """Abrupt fault: p(s) = 1."""

    type_name = "step"

    @property
    def bounds(self) -> tuple[float, float]:
        return (1.0, 1.0)

    def __call__(self, s: float) -> float:
        return 1.0


@dataclass(frozen=True)
class ExponentialRise(Profile):
    """Incipient fault with time constant tau: p(s) = 1 - exp(-s/tau)."""

    tau: float
    type_name = "exponential_rise"

    def __post_init__(self):
        _positive("ExponentialRise", "tau", self.tau)

    def __call__(self, s: float) -> float:
        return 1.0 - math.exp(-s / self.tau)


@dataclass(frozen=True)
class ExponentialGrowth(Profile):
    """A bias that jumps to the magnitude at onset and grows exponentially: p(s) = exp(rate·s) — Bošković &
    Mehra's Sim 2 sensor profile d(t) = e^{0.05(t − t_F)} c (rate 0.05 1/s). ``rate`` [1/s] > 0; p is unbounded,
    so only the additive kinds (bias) accept it."""

    rate: float
    type_name = "exponential_growth"
    unit_range = False

    def __post_init__(self):
        _positive("ExponentialGrowth", "rate", self.rate)
        if self.rate > 10.0:
            raise RobofdiError(f"ExponentialGrowth: field 'rate' must be <= 10 1/s (a growth, not a blow-up), "
                               f"got {self.rate!r}")

    def __call__(self, s: float) -> float:
        return math.exp(self.rate * s)


@dataclass(frozen=True)
class Ramp(Profile):
    """Linear growth to full effect over ``duration`` seconds: p(s) = min(s/duration, 1)."""

    duration: float
    type_name = "ramp"

    def __post_init__(self):
        _positive("Ramp", "duration", self.duration)

    def __call__(self, s: float) -> float:
        return min(s / self.duration, 1.0)


@dataclass(frozen=True)
class Sinusoid(Profile):
    """Oscillating fault: p(s) = sin(2*pi*frequency*s + phase)."""

    frequency: float
    phase: float = 0.0
    type_name = "sinusoid"
    unit_range = False

    @property
    def bounds(self) -> tuple[float, float]:
        return (-1.0, 1.0)

    def __post_init__(self):
        _positive("Sinusoid", "frequency", self.frequency)
        if not _is_number(self.phase):
            raise RobofdiError(f"Sinusoid: field 'phase' must be a finite number, got {self.phase!r}")

    def __call__(self, s: float) -> float:
        return math.sin(2.0 * math.pi * self.frequency * s + self.phase)


@dataclass(frozen=True)
class Oscillation(Profile):
    """A fault that oscillates about a mean: p(s) = mean + amplitude·sin(2π·frequency·s + phase).

    Usable by the "unit" kinds (loss of effectiveness) when mean ± |amplitude| stays in [0, 1], e.g. Jiang &
    Chowdhury's r₂(t) = 0.5 + 0.3 sin(πt)."""

    mean: float
    amplitude: float
    frequency: float
    phase: float = 0.0
    type_name = "oscillation"

    def __post_init__(self):
        _positive("Oscillation", "frequency", self.frequency)
        for name in ("mean", "amplitude", "phase"):
            if not _is_number(getattr(self, name)):
                raise RobofdiError(f"Oscillation: field {name!r} must be a finite number, got {getattr(self, name)!r}")

    @property
    def unit_range(self) -> bool:
        return self.mean - abs(self.amplitude) >= 0.0 and self.mean + abs(self.amplitude) <= 1.0

    @property
    def bounds(self) -> tuple[float, float]:
        return (self.mean - abs(self.amplitude), self.mean + abs(self.amplitude))

    def __call__(self, s: float) -> float:
        return self.mean + self.amplitude * math.sin(2.0 * math.pi * self.frequency * s + self.phase)


@dataclass(frozen=True)
class Intermittent(Profile):
    """On/off pattern: p(s) = 1 while (s mod period) < duty*period, else 0."""

    period: float
    duty: float
    type_name = "intermittent"

    def __post_init__(self):
        _positive("Intermittent", "period", self.period)
        if not _is_number(self.duty) or not 0 < self.duty <= 1:
            raise RobofdiError(f"Intermittent: field 'duty' must be a finite number in (0, 1], got {self.duty!r}")

    def __call__(self, s: float) -> float:
        return 1.0 if math.fmod(s, self.period) < self.duty * self.period else 0.0


#: Serialised profile type name -> class.
PROFILE_TYPES: dict[str, type[Profile]] = {
    cls.type_name: cls for cls in (Step, ExponentialRise, ExponentialGrowth, Ramp, Sinusoid, Oscillation, Intermittent)
}


def profile_from_dict(d: Mapping[str, Any]) -> Profile:
    """Build a profile from ``{"type": "exponential_rise", "tau": 0.002}`` (inverse of ``Profile.to_dict``)."""
    if isinstance(d, Profile):
        return d
    if not isinstance(d, Mapping):
        raise RobofdiError(f"profile must be a mapping with a 'type' key, got {d!r}")
    if "type" not in d:
        raise RobofdiError(f"profile: missing field 'type'; expected one of {', '.join(PROFILE_TYPES)}")
    kind = d["type"]
    if kind not in PROFILE_TYPES:
        raise RobofdiError(f"profile: unknown type {kind!r}; expected one of {', '.join(PROFILE_TYPES)}")
    cls = PROFILE_TYPES[kind]
    names = [f.name for f in fields(cls)]
    extra = sorted(set(d) - set(names) - {"type"})
    if extra:
        raise RobofdiError(
            f"profile {kind!r}: unknown field(s) {', '.join(map(repr, extra))}; expected {', '.join(names) or 'none'}"
        )
    try:
        return cls(**{k: v for k, v in d.items() if k != "type"})
    except TypeError as exc:  # missing required field
        raise RobofdiError(f"profile {kind!r}: {exc}; expected fields {', '.join(names)}") from None
