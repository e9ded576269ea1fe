"""A linear state-space plant (the truth) with process noise, sensor noise and input saturation.

One ``step(u)`` advances one control period T = ``control_dt`` (u held, zero-order hold)::

    u_a(k)   = clip(u(k), u_min, u_max)                        (u_applied)
    x(k+1)   = A x(k) + B u_a(k) + E d(k) + G w(k),   w(k) ~ N(0, Q)
    y(k+1)   = C x(k+1) + D u_a(k) + v(k+1),          v ~ N(0, R)

The measurement returned by ``step`` is taken at the end of the period, on the new state x(k+1) — the sample the
loop reads next — with the feedthrough D acting on the input held until that sample. ``reset`` returns
y(0) = C x(0) + v(0) (no input applied yet). Q and R are per-sample (discrete) covariances, not spectral densities.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.models.linear import (
    DT_RTOL, LinearMismatch, LinearModel, covariance_factor, discretize, perturbed, vector_field,
)
from robofdi.seeding import stream

__all__ = ["LinearPlant"]


@dataclass(eq=False)
class LinearPlant:
    """Simulator protocol (:class:`robofdi.protocols.Simulator`) for a :class:`LinearModel` truth.

    model: the truth; a continuous model is discretised exactly (ZOH) at ``control_dt``, a discrete one must have
    dt == control_dt. process_noise: Q, covariance of w (n×n or n variances; with ``noise_input`` G (n×g): g×g).
    measurement_noise: R (p×p or p variances). u_min / u_max: actuator limits per input (default ∓inf).
    x0: default initial state (zeros). disturbance: d(t) → (q,) unknown input through E, held over each period.
    A linear plant has no components to degrade: its faults are actuator and sensor faults.
    """

    model: LinearModel
    control_dt: float
    process_noise: Any = None
    measurement_noise: Any = None
    noise_input: Any = None
    u_min: Any = None
    u_max: Any = None
    x0: Any = None
    system: str = "linear"
    disturbance: Callable[[float], np.ndarray] | None = None
    components: list[str] = field(default_factory=list, init=False)
    component_kinds: dict[str, list[str]] = field(default_factory=dict, init=False)

    def __post_init__(self):
        if not isinstance(self.model, LinearModel):
            raise RobofdiError(f"LinearPlant: field 'model' must be a LinearModel, got {type(self.model).__name__}")
        dt = self.control_dt
        if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating, np.integer)) or not (np.isfinite(dt) and dt > 0):
            raise RobofdiError(f"LinearPlant: field 'control_dt' must be a period > 0 s, got {dt!r}")
        self.control_dt = float(dt)
        if self.model.discrete and abs(self.model.dt - self.control_dt) > DT_RTOL * self.control_dt:
            raise RobofdiError(
                f"LinearPlant: field 'control_dt' must equal the discrete model's dt={self.model.dt} s, got {self.control_dt}"
            )
        if not isinstance(self.system, str) or not self.system:
            raise RobofdiError(f"LinearPlant: field 'system' must be a non-empty name, got {self.system!r}")
        md = discretize(self.model, self.control_dt)
        self.discrete_model = md
        n, m, p = md.n, md.m, md.p
        if self.noise_input is None:
            self._G = np.eye(n)
        else:
            G = np.array(self.noise_input, dtype=float)
            if G.ndim != 2 or G.shape[0] != n or not np.all(np.isfinite(G)):
                raise RobofdiError(f"LinearPlant: field 'noise_input' must be a finite {n}xg matrix, got shape {G.shape}")
            self._G = G
        g = self._G.shape[1]
        self._Q, self._FQ = covariance_factor(np.zeros(g) if self.process_noise is None else self.process_noise, g,
                                              "process_noise")
        self._R, self._FR = covariance_factor(np.zeros(p) if self.measurement_noise is None else self.measurement_noise, p,
                                              "measurement_noise")
        self._u_min = vector_field(self.u_min, m, "u_min", "LinearPlant", -np.inf, allow_inf=True)
        self._u_max = vector_field(self.u_max, m, "u_max", "LinearPlant", np.inf, allow_inf=True)
        if np.any(self._u_min > self._u_max):
            j = int(np.flatnonzero(self._u_min > self._u_max)[0])
            raise RobofdiError(f"LinearPlant: field 'u_min' must be <= u_max for input {md.input_names[j]!r}, "
                               f"got {self._u_min[j]} > {self._u_max[j]}")
        self._x0 = vector_field(self.x0, n, "x0", "LinearPlant", 0.0)
        if self.disturbance is not None and not callable(self.disturbance):
            raise RobofdiError("LinearPlant: field 'disturbance' must be None or a function d(t) -> array of q values")
        if self.disturbance is not None and md.q == 0:
            raise RobofdiError("LinearPlant: field 'disturbance' needs an unknown-input matrix E in the model (q = 0)")
        self.actuators = list(md.input_names)
        self.sensor_channels = list(md.output_names)
        self.state_names = list(md.state_names)
        self.units = {k: list(v) for k, v in md.units.items()}
        self.reset()

    @property
    def physics_dt(self) -> float:
        """[s]: the plant is exact at the control period (ZOH), so there is no finer physics step."""
        return self.control_dt

    @property
    def state(self) -> np.ndarray:
        return self._x.copy()

    @property
    def time(self) -> float:
        return self._k * self.control_dt

    @property
    def true_output(self) -> np.ndarray:
        """C x + D u_applied: what the sensors would read without noise."""
        md = self.discrete_model
        return md.C @ self._x + md.D @ self.u_applied

    def reset(self, initial_state: Any = None, seed: np.random.SeedSequence | int | None = None) -> np.ndarray:
        """Start a run from ``initial_state`` (None: x0). ``seed`` (int, SeedSequence; None = fresh entropy) drives
        this run's noise: w from ``stream(seed, "process")``, sensor j from ``stream(seed, "sensor", name_j)``."""
        md = self.discrete_model
        x = self._x0 if initial_state is None else initial_state
        expected = f"LinearPlant.reset: field 'initial_state' must be a finite vector of {md.n} values"
        try:
            x = np.array(x, dtype=float)
        except (TypeError, ValueError):
            raise RobofdiError(f"{expected}, got {initial_state!r}") from None
        if x.shape != (md.n,) or not np.all(np.isfinite(x)):
            raise RobofdiError(f"{expected}, got {initial_state!r}")
        root = stream(seed)  # validates the seed; None -> fresh entropy, fixed for this run
        self._process = np.random.default_rng(stream(root, "process"))
        self._sensors = [np.random.default_rng(stream(root, "sensor", name)) for name in md.output_names]
        self._x = x
        self._k = 0
        self.u_applied = np.zeros(md.m)
        return self._measure(self.u_applied)

    def saturate(self, u: np.ndarray) -> np.ndarray:
        """clip(u, u_min, u_max), per input."""
        return np.clip(self._input(u), self._u_min, self._u_max)

    def step(self, u: np.ndarray) -> np.ndarray:
        """Apply saturate(u) over one period; returns y at the end of it (see the module docstring)."""
        md = self.discrete_model
        ua = self.saturate(u)
        x = md.A @ self._x + md.B @ ua
        if self.disturbance is not None:
            d = np.asarray(self.disturbance(self.time), dtype=float)
            if d.shape != (md.q,) or not np.all(np.isfinite(d)):
                raise RobofdiError(f"LinearPlant: field 'disturbance' must return {md.q} finite values, got {d!r}")
            x = x + md.E @ d
        if self._FQ.any():
            x = x + self._G @ (self._FQ @ self._process.standard_normal(self._FQ.shape[1]))
        self._x, self._k, self.u_applied = x, self._k + 1, ua
        return self._measure(ua)

    def _measure(self, ua: np.ndarray) -> np.ndarray:
        md = self.discrete_model
        y = md.C @ self._x + md.D @ ua
        if self._FR.any():
            z = np.array([g.standard_normal() for g in self._sensors])
            y = y + self._FR @ z
        return y

    def _input(self, u) -> np.ndarray:
        m = self.discrete_model.m
        a = np.array(u, dtype=float)
        if a.shape != (m,):
            raise RobofdiError(f"LinearPlant: input 'u' must be a vector of {m} values {self.actuators}, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            j = int(np.flatnonzero(~np.isfinite(a))[0])
            raise RobofdiError(f"LinearPlant: input 'u' must be finite, got {a[j]} for {self.actuators[j]!r}")
        return a

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        """A linear plant has no components; only value 0 (restore) is accepted."""
        if value != 0:
            raise RobofdiError(f"linear plant has no components (got kind {kind!r} on target {target!r}); "
                               "use actuator or sensor faults")

    def nominal_model(self, mismatch: LinearMismatch | float | None = None) -> LinearModel:
        """The belief: the model as given (continuous stays continuous), with :func:`perturbed` errors when
        ``mismatch`` is a :class:`LinearMismatch` or a relative error (then seed 0). Discretise it at the
        diagnoser's own rate with :func:`robofdi.models.linear.discretize`."""
        if mismatch is None:
            return self.model
        return perturbed(self.model, mismatch if isinstance(mismatch, LinearMismatch) else LinearMismatch(mismatch, 0))
