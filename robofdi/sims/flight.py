"""The over-actuated flight-control surrogate (:mod:`robofdi.models.flight`) as a simulator (the truth).

Effects outside every diagnoser's model class: the surfaces move at most at their rate limits (first-order
servo lag ``servo_tau`` inside the rate limit; the chapter's observers assume unity actuator dynamics) and stop
at their position limits; the sensors are noisy (one seeded stream per channel); outer-left-wing damage
ρ ∈ [0, 1] (component ``left_wing``, kind ``component_wing_damage``) switches the plant to A(ρ), B(ρ).

One ``step(u)`` advances ``control_dt``; inside it ``substeps`` physics steps of the exact ZOH of (A(ρ), B(ρ))
with each surface's position updated by its rate-limited servo.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import expm

from robofdi.checks import is_int
from robofdi.errors import RobofdiError
from robofdi.models.flight import FlightSurrogate, flight_surrogate
from robofdi.seeding import stream

__all__ = ["FlightPlant", "DEFAULT_NOISE", "DAMAGE_KIND"]

DAMAGE_KIND = "component_wing_damage"
#: sensor noise std per state channel: airspeed 0.05 m/s, angles 0.01°, rates 0.01°/s.
DEFAULT_NOISE = (0.05,) + (1.745e-4,) * 4 + (1.745e-4,) * 3


@dataclass(eq=False)
class FlightPlant:
    """Simulator protocol (:class:`robofdi.protocols.Simulator`) for the flight surrogate.

    control_dt [s]; substeps: physics steps per control period; noise: sensor std per channel (None: the
    defaults, 0: noise-free); servo_tau [s]: first-order lag of each surface inside its rate limit (0: none);
    x0: default initial state (zeros: trim)."""

    control_dt: float = 0.01
    substeps: int = 5
    noise: Any = None
    servo_tau: float = 0.01
    x0: Any = None
    surrogate: FlightSurrogate = field(default_factory=flight_surrogate)
    system: str = "flight_surrogate"

    def __post_init__(self):
        if not (isinstance(self.control_dt, (int, float)) and np.isfinite(self.control_dt) and self.control_dt > 0):
            raise RobofdiError(f"FlightPlant: field 'control_dt' must be a period > 0 s, got {self.control_dt!r}")
        if not is_int(self.substeps, 1):
            raise RobofdiError(f"FlightPlant: field 'substeps' must be an integer >= 1, got {self.substeps!r}")
        if not (isinstance(self.servo_tau, (int, float)) and np.isfinite(self.servo_tau) and self.servo_tau >= 0):
            raise RobofdiError(f"FlightPlant: field 'servo_tau' must be a time >= 0 s, got {self.servo_tau!r}")
        s = self.surrogate
        n = s.n
        noise = DEFAULT_NOISE if self.noise is None else self.noise
        noise = np.broadcast_to(np.asarray(noise, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(noise)) or np.any(noise < 0):
            raise RobofdiError(f"FlightPlant: field 'noise' must be {n} standard deviations >= 0, got {self.noise!r}")
        self._noise = noise
        self._x0 = np.zeros(n) if self.x0 is None else np.array(self.x0, dtype=float)
        if self._x0.shape != (n,) or not np.all(np.isfinite(self._x0)):
            raise RobofdiError(f"FlightPlant: field 'x0' must be {n} finite values, got {self.x0!r}")
        self.actuators = list(s.effectors)
        self.sensor_channels = list(s.state_names)
        self.state_names = list(s.state_names)
        self.components = ["left_wing"]
        self.component_kinds = {DAMAGE_KIND: ["left_wing"]}
        self.units = {"state": list(s.units), "u": ["rad"] * s.m, "y": list(s.units)}
        self._h = self.control_dt / self.substeps
        self._disc: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self.reset()

    @property
    def physics_dt(self) -> float:
        return self._h

    @property
    def state(self) -> np.ndarray:
        return self._x.copy()

    @property
    def true_output(self) -> np.ndarray:
        return self._x.copy()

    @property
    def time(self) -> float:
        return self._k * self.control_dt

    @property
    def damage(self) -> float:
        """The true damage ρ now."""
        return self._rho

    def _discrete(self, rho: float):
        if rho not in self._disc:
            s = self.surrogate
            n, m = s.n, s.m
            M = np.zeros((n + m, n + m))
            M[:n, :n], M[:n, n:] = s.A(rho), s.B(rho)
            E = expm(M * self._h)
            self._disc[rho] = (E[:n, :n], E[:n, n:])
        return self._disc[rho]

    def reset(self, initial_state: Any = None, seed=None) -> np.ndarray:
        x = self._x0 if initial_state is None else np.array(initial_state, dtype=float)
        if x.shape != (self.surrogate.n,) or not np.all(np.isfinite(x)):
            raise RobofdiError(f"FlightPlant.reset: field 'initial_state' must be {self.surrogate.n} finite values, "
                               f"got {initial_state!r}")
        root = stream(seed)
        self._sensors = [np.random.default_rng(stream(root, "sensor", c)) for c in self.sensor_channels]
        self._x = x.copy()
        self._k = 0
        self._rho = 0.0
        self._pos = np.zeros(self.surrogate.m)
        self.u_applied = self._pos.copy()
        return self._measure()

    def saturate(self, u: np.ndarray) -> np.ndarray:
        """Position limits (the rate limits act in ``step``)."""
        return np.clip(self._input(u), self.surrogate.u_min, self.surrogate.u_max)

    def step(self, u: np.ndarray) -> np.ndarray:
        s = self.surrogate
        target = self.saturate(u)
        Ad, Bd = self._discrete(self._rho)
        h, rate = self._h, s.rate_limit
        a = 1.0 - np.exp(-h / self.servo_tau) if self.servo_tau > 0 else 1.0
        for _ in range(self.substeps):
            move = np.clip(a * (target - self._pos), -rate * h, rate * h)
            mid = self._pos + 0.5 * move
            self._pos = self._pos + move
            self._x = Ad @ self._x + Bd @ mid
        self._k += 1
        self.u_applied = self._pos.copy()
        return self._measure()

    def _measure(self) -> np.ndarray:
        y = self._x.copy()
        if self._noise.any():
            y = y + self._noise * np.array([g.standard_normal() for g in self._sensors])
        return y

    def _input(self, u) -> np.ndarray:
        m = self.surrogate.m
        a = np.array(u, dtype=float)
        if a.shape != (m,):
            raise RobofdiError(f"FlightPlant: input 'u' must be a vector of {m} values {self.actuators}, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            j = int(np.flatnonzero(~np.isfinite(a))[0])
            raise RobofdiError(f"FlightPlant: input 'u' must be finite, got {a[j]} for {self.actuators[j]!r}")
        return a

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        """``component_wing_damage`` on ``left_wing``: ρ = value ∈ [0, 1] (0 restores the nominal plant)."""
        if kind != DAMAGE_KIND or target != "left_wing":
            raise RobofdiError(f"FlightPlant: component fault must be {DAMAGE_KIND!r} on 'left_wing', got {kind!r} "
                               f"on {target!r}")
        if not (np.isfinite(value) and 0.0 <= value <= 1.0):
            raise RobofdiError(f"FlightPlant: wing damage must be a fraction in [0, 1], got {value!r}")
        self._rho = float(value)

    def nominal_model(self, mismatch: Any = None) -> FlightSurrogate:
        """The belief: the surrogate's matrices (damage polynomials included, ρ unknown). ``mismatch`` (a relative
        error) scales every nominal coefficient by a seeded factor 1 + mismatch·N(0, 1)."""
        s = flight_surrogate()
        if not mismatch:
            return s
        g = np.random.default_rng(stream(0, "flight_mismatch"))
        A = tuple(Ai * (1 + mismatch * g.standard_normal(Ai.shape)) for Ai in s.A_coeffs)
        B = tuple(Bi * (1 + mismatch * g.standard_normal(Bi.shape)) for Bi in s.B_coeffs)
        return FlightSurrogate(A, B, s.u_min, s.u_max, s.rate_limit)
