"""Per-kind fault effects: how one active fault turns a channel's value into a faulty one.

Each effect sees the value its fault receives (the nominal value, or the output of an earlier
fault on the same channel) and returns the faulty value; it keeps its own state (held values,
histories, random generator) until :meth:`Effect.reset`.
"""
from __future__ import annotations

import math

import numpy as np

from robofdi.faults.fault import Fault

__all__ = ["Effect", "make_effect"]


class Effect:
    """Base: stateless effect of one fault; subclasses override :meth:`apply`."""

    def __init__(self, fault: Fault, seed: np.random.SeedSequence):
        self.fault = fault
        self._seed = seed
        self.reset()

    def reset(self) -> None:
        """Forget all state; random generators restart from their seed."""
        self.rng = np.random.default_rng(self._seed)

    def observe(self, t: float, x: float) -> None:
        """Called at every step, active or not, with the value reaching this fault."""

    def apply(self, t: float, x: float) -> float:
        """Faulty value at time t (only called while the fault is active)."""
        raise NotImplementedError

    def p(self, t: float) -> float:
        return self.fault.profile(t - self.fault.onset)


class Additive(Effect):
    """x + m*p (actuator_additive, sensor_bias)."""

    def apply(self, t, x):
        return x + self.fault.magnitude * self.p(t)


class Drift(Effect):
    """x + m*(t - onset) (actuator_drift, sensor_drift)."""

    def apply(self, t, x):
        return x + self.fault.magnitude * (t - self.fault.onset)


class Gain(Effect):
    """x*(1 + sign*m*p): loss of effectiveness (sign -1) or sensor scale (sign +1)."""

    def __init__(self, fault, seed, sign: float):
        self.sign = sign
        super().__init__(fault, seed)

    def apply(self, t, x):
        return x * (1.0 + self.sign * self.fault.magnitude * self.p(t))


class Hold(Effect):
    """Held at the value of the first active step (actuator_lock_in_place, sensor_freeze)."""

    def reset(self):
        super().reset()
        self.held: float | None = None

    def apply(self, t, x):
        if self.held is None:
            self.held = x
        return self.held


class Zero(Effect):
    """Output 0 (actuator_float, sensor_dropout)."""

    def apply(self, t, x):
        return 0.0


class HardOver(Effect):
    """Slews from the value at the first active step toward params['limit'] at params['rate'] units/s."""

    def reset(self):
        super().reset()
        self.value: float | None = None
        self.t_last = self.fault.onset

    def apply(self, t, x):
        limit = self.fault.params["limit"]
        rate = self.fault.params.get("rate", math.inf)
        if self.value is None:
            self.value = x
        dt = max(t - self.t_last, 0.0)
        self.t_last = max(t, self.t_last)
        if math.isinf(rate):
            self.value = limit
        else:
            step = rate * dt
            gap = limit - self.value
            self.value = limit if abs(gap) <= step else self.value + math.copysign(step, gap)
        return self.value


class IntermittentAdd(Effect):
    """x + m while on. Periodic pattern from params period/duty, or seeded random episodes if the fault has a seed."""

    def reset(self):
        super().reset()
        self.period = self.fault.params.get("period", 0.5)
        self.duty = self.fault.params.get("duty", 0.5)
        self.random = self.fault.seed is not None
        self.on = True
        self.next_switch = self.fault.onset + self._draw(True) if self.random else math.inf

    def _draw(self, on: bool) -> float:
        mean = self.period * (self.duty if on else 1.0 - self.duty)
        return float(self.rng.exponential(mean)) if mean > 0 else 0.0

    def is_on(self, t: float) -> bool:
        if not self.random:
            return math.fmod(t - self.fault.onset, self.period) < self.duty * self.period
        while t >= self.next_switch:
            self.on = not self.on
            self.next_switch += self._draw(self.on)
        return self.on

    def apply(self, t, x):
        return x + self.fault.magnitude if self.is_on(t) else x


class Noise(Effect):
    """x + N(0, (m*p)^2), seeded (sensor_noise, loss of accuracy)."""

    def apply(self, t, x):
        return x + abs(self.fault.magnitude * self.p(t)) * float(self.rng.standard_normal())


class Outliers(Effect):
    """With probability params['probability'] per step, x ± m (random sign), seeded."""

    def apply(self, t, x):
        hit = self.rng.random() < self.fault.params["probability"]
        sign = 1.0 if self.rng.random() < 0.5 else -1.0  # drawn every step: stream independent of hits
        return x + sign * self.fault.magnitude if hit else x


class Delay(Effect):
    """x(t - params['delay']), linearly interpolated in the recorded history; oldest sample before enough history."""

    def reset(self):
        super().reset()
        self.times: list[float] = []
        self.values: list[float] = []

    def observe(self, t, x):
        if self.times and t <= self.times[-1]:  # repeated/backward time: replace the newer samples
            while self.times and t <= self.times[-1]:
                self.times.pop()
                self.values.pop()
        self.times.append(t)
        self.values.append(x)
        # drop samples no longer needed: keep the last one at or before t - delay
        horizon = t - self.fault.params["delay"]
        k = 0
        while k + 1 < len(self.times) and self.times[k + 1] <= horizon:
            k += 1
        if k:
            del self.times[:k], self.values[:k]

    def apply(self, t, x):
        return float(np.interp(t - self.fault.params["delay"], self.times, self.values))


_EFFECTS = {
    "actuator_additive": Additive,
    "actuator_drift": Drift,
    "actuator_loss_of_effectiveness": lambda f, s: Gain(f, s, -1.0),
    "actuator_lock_in_place": Hold,
    "actuator_float": Zero,
    "actuator_hard_over": HardOver,
    "actuator_intermittent": IntermittentAdd,
    "sensor_bias": Additive,
    "sensor_drift": Drift,
    "sensor_freeze": Hold,
    "sensor_dropout": Zero,
    "sensor_scale": lambda f, s: Gain(f, s, +1.0),
    "sensor_noise": Noise,
    "sensor_delay": Delay,
    "sensor_outliers": Outliers,
}


def make_effect(fault: Fault, seed: np.random.SeedSequence) -> Effect:
    """The effect object for ``fault.kind``."""
    return _EFFECTS[fault.kind](fault, seed)
