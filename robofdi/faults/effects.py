"""Per-kind fault effects: how one active fault turns a channel's value into a faulty one.

Each effect sees the value its fault receives (the nominal value, or the output of an earlier
fault on the same channel) and returns the faulty value; it keeps its own state (held values,
histories, random generator) until :meth:`Effect.reset`.
"""
from __future__ import annotations

import numpy as np

from robofdi.errors import RobofdiError
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

    def inverse(self, t: float, y: float) -> float:
        """The value x with apply(t, x) = y (offline emulation; only invertible kinds define it)."""
        raise RobofdiError(f"Fault {self.fault.name!r}: kind {self.fault.kind!r} cannot be emulated offline")

    def p(self, t: float) -> float:
        return self.fault.profile(t - self.fault.onset)


class Additive(Effect):
    """x + m*p (actuator_additive, sensor_bias)."""

    def apply(self, t, x):
        return x + self.fault.magnitude * self.p(t)


    def inverse(self, t, y):
        return y - self.fault.magnitude * self.p(t)


class Drift(Effect):
    """x + m*(t - onset) (actuator_drift, sensor_drift; Step profile only)."""

    def apply(self, t, x):
        return x + self.fault.magnitude * (t - self.fault.onset)

    def inverse(self, t, y):
        return y - self.fault.magnitude * (t - self.fault.onset)


class Gain(Effect):
    """x*(1 + sign*m*p): loss of effectiveness (sign -1), actuator or sensor scale (sign +1)."""

    def __init__(self, fault, seed, sign: float):
        self.sign = sign
        super().__init__(fault, seed)

    def apply(self, t, x):
        return x * (1.0 + self.sign * self.fault.magnitude * self.p(t))

    def inverse(self, t, y):
        gain = 1.0 + self.sign * self.fault.magnitude * self.p(t)
        if gain <= 0.0:
            raise RobofdiError(f"Fault {self.fault.name!r}: a total loss of effectiveness cannot be emulated offline")
        return y / gain


class Hold(Effect):
    """Blends toward the value of the first active step: (1 − p)·x + p·x(onset) (actuator_lock_in_place, sensor_freeze)."""

    def reset(self):
        super().reset()
        self.held: float | None = None

    def apply(self, t, x):
        if self.held is None:
            self.held = x
        p = self.p(t)
        return x + p * (self.held - x)


class Zero(Effect):
    """Output (1 − p)·x, zero for a step (actuator_float, sensor_dropout)."""

    def apply(self, t, x):
        return (1.0 - self.p(t)) * x


class HardOver(Effect):
    """From the value at the first active step x₀ toward params['limit']: x₀ + p·(limit − x₀); a Ramp profile
    gives the rate-limited slew of a real hard-over, a Step the jump."""

    def reset(self):
        super().reset()
        self.start: float | None = None

    def apply(self, t, x):
        if self.start is None:
            self.start = x
        return self.start + self.p(t) * (self.fault.params["limit"] - self.start)


class Noise(Effect):
    """x + N(0, (m*p)^2), seeded (sensor_noise, loss of accuracy)."""

    def apply(self, t, x):
        return x + abs(self.fault.magnitude * self.p(t)) * float(self.rng.standard_normal())


class Outliers(Effect):
    """With probability params['probability'] per step, x ± m·p (random sign), seeded."""

    def apply(self, t, x):
        hit = self.rng.random() < self.fault.params["probability"]
        sign = 1.0 if self.rng.random() < 0.5 else -1.0  # drawn every step: stream independent of hits
        return x + sign * self.fault.magnitude * self.p(t) if hit else x


class Delay(Effect):
    """x(t − delay·p), linearly interpolated in the recorded history; oldest sample before enough history."""

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
        # drop samples no longer needed: keep the last one at or before t - delay (the longest delay)
        horizon = t - self.fault.params["delay"]
        k = 0
        while k + 1 < len(self.times) and self.times[k + 1] <= horizon:
            k += 1
        if k:
            del self.times[:k], self.values[:k]

    def apply(self, t, x):
        return float(np.interp(t - self.fault.params["delay"] * self.p(t), self.times, self.values))


class Level(Effect):
    """The component's change from nominal, m·p (component faults; the simulator applies it)."""

    def apply(self, t, x):
        return x + self.fault.magnitude * self.p(t)


_EFFECTS = {
    "actuator_additive": Additive,
    "actuator_drift": Drift,
    "actuator_loss_of_effectiveness": lambda f, s: Gain(f, s, -1.0),
    "actuator_scale": lambda f, s: Gain(f, s, +1.0),
    "actuator_lock_in_place": Hold,
    "actuator_float": Zero,
    "actuator_hard_over": HardOver,
    "sensor_bias": Additive,
    "sensor_drift": Drift,
    "sensor_freeze": Hold,
    "sensor_dropout": Zero,
    "sensor_scale": lambda f, s: Gain(f, s, +1.0),
    "sensor_noise": Noise,
    "sensor_delay": Delay,
    "sensor_outliers": Outliers,
    "component_friction": Level,
    "component_mass": Level,
    "component_thruster_blocking": Level,
    "component_thruster_flooding": Level,
    "component_open_winding": Level,
    "component_valve_sticking": Level,
    "component_leak": Level,
    "component_wing_damage": Level,
}


def make_effect(fault: Fault, seed: np.random.SeedSequence) -> Effect:
    """The effect object for ``fault.kind``."""
    return _EFFECTS[fault.kind](fault, seed)
