"""AUV diagnosers of Antonelli's survey (Sec. 4), built from the nominal model, the thrust demands and measurements.

* :class:`VoltageResidual` — ODIN's Hall-effect scheme [48]: measured vs commanded motor voltage per thruster.
* :class:`CurrentMap` — Romeo's current vs propeller-rate characteristic [9, 11]: the nominal characteristic is
  identified from fault-free data (:func:`identify_current_characteristic`); the region of the mismatch separates
  rotor failure, blocking and flooding (:func:`current_map_region`).
* :class:`ForceObserver` — a generalised-momentum observer on the whole vehicle (eq. (3) of the survey, in the
  discrete form of De Luca & Mattone eq. (10)): the generalised force deficit τ_demand − τ_actual, and the
  per-thruster effectiveness from the propeller-speed telemetry.

Every diagnoser takes y with the channels of :class:`robofdi.sims.auv.AuvSimulator` (navigation, then propeller
speeds, motor currents and voltages) and u = ū(k−1), the thrust demands [N] held over the last interval.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.decision import Signature
from robofdi.errors import RobofdiError
from robofdi.models.auv import AXES, AuvModel, rotation_from_euler
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["VoltageResidual", "CurrentMap", "ForceObserver", "identify_current_characteristic", "current_features",
           "current_map_region", "effectiveness_identifiability", "REGIONS"]

#: What :func:`current_map_region` can answer.
REGIONS = ("nominal", "rotor_failure", "blocking", "flooding", "unknown")


class _Telemetry:
    """Shared plumbing: channel indices, the driver's voltage for a thrust demand, input checks."""

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, thrust_limit: float):
        if not (np.isfinite(sample_time) and sample_time > 0):
            raise RobofdiError(f"{type(self).__name__}: field 'sample_time' must be > 0 s, got {sample_time!r}")
        if not (np.isfinite(thrust_limit) and thrust_limit > 0):
            raise RobofdiError(f"{type(self).__name__}: field 'thrust_limit' must be > 0 N, got {thrust_limit!r}")
        self.model, self.T, self.thrust_limit = model, float(sample_time), float(thrust_limit)
        self.thrusters = list(model.thrusters)
        self.inputs = list(self.thrusters)
        self.measurements = list(measurements)

        def index(kind):
            try:
                return np.array([self.measurements.index(f"{t}_{kind}") for t in self.thrusters])
            except ValueError:
                raise RobofdiError(f"{type(self).__name__}: measurements must include '<thruster>_{kind}' for every "
                                   f"thruster {self.thrusters}") from None

        self._speed, self._current, self._voltage = index("speed"), index("current"), index("voltage")

    def _inputs(self, y, u):
        y = check_measurement(y, len(self.measurements), "y")
        u = check_measurement(u, len(self.thrusters), "u")
        return y, np.clip(u, -self.thrust_limit, self.thrust_limit)

    def commanded_voltage(self, u: np.ndarray) -> np.ndarray:
        """The driver's voltage [V] for the thrust demands u [N] (the nominal steady-state map)."""
        return self.model.thruster.voltage_for_thrust(np.clip(u, -self.thrust_limit, self.thrust_limit))


class VoltageResidual(_Telemetry):
    """Hall-effect voltage residual, ODIN [48]: r_j = mean over ``window`` s of (V_hall,j − V_cmd,j) [V].

    A zeroed drive gives r_j → −V_cmd,j: the fault is invisible while |V_cmd,j| stays under the threshold
    (detectability depends on the command; :meth:`detectable`)."""

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, window: float = 0.2,
                 thrust_limit: float = 40.0):
        super().__init__(model, measurements, sample_time, thrust_limit)
        if not (np.isfinite(window) and window >= sample_time):
            raise RobofdiError(f"VoltageResidual: field 'window' must be >= the sample time {sample_time} s, got {window!r}")
        self.samples = int(round(window / sample_time))
        self.components = list(self.thrusters)
        self.estimate_components = list(self.thrusters)
        self.estimate_modes = ["level"] * len(self.thrusters)
        self.units = {"residual": ["V"] * len(self.thrusters), "estimate": ["V"] * len(self.thrusters)}
        self.reset()

    def reset(self) -> None:
        self._buffer = np.zeros((self.samples, len(self.thrusters)))
        self._k = 0

    def update(self, y, u) -> Residual:
        y, u = self._inputs(y, u)
        raw = y[self._voltage] - self.commanded_voltage(u)
        self._buffer[self._k % self.samples] = raw
        self._k += 1
        r = self._buffer[: min(self._k, self.samples)].mean(axis=0)
        return Residual(r, r.copy())

    def detectable(self, u: np.ndarray, threshold: np.ndarray) -> np.ndarray:
        """Per thruster: would zeroing its drive raise the residual above ``threshold`` at the demand u?"""
        return np.abs(self.commanded_voltage(np.asarray(u, dtype=float))) > np.asarray(threshold)

    def signatures(self):
        return [Signature(t, frozenset([t])) for t in self.thrusters]


def current_features(speed: np.ndarray, acceleration: np.ndarray) -> np.ndarray:
    """Regressors of the current characteristic i = θ·φ: φ = [|Ω|Ω, Ω̇, Ω] (propeller load, rotor inertia,
    viscous motor friction), stacked on the last axis."""
    return np.stack([np.abs(speed) * speed, acceleration, speed], axis=-1)


class _Filter:
    """First-order low-pass y ← y + α (x − y) with α = T/(τ + T) (shared by the characteristic's regressors)."""

    def __init__(self, sample_time: float, tau: float):
        self.alpha = sample_time / (tau + sample_time)

    def __call__(self, prev, x):
        return x.copy() if prev is None else prev + self.alpha * (x - prev)


def identify_current_characteristic(speed: np.ndarray, current: np.ndarray, sample_time: float, tau: float = 0.1) -> np.ndarray:
    """θ (3,) of :func:`current_features` by least squares over fault-free telemetry — Romeo's experimentally
    identified nominal characteristic [9]. ``speed``/``current``: (N, p) propeller speeds [rad/s] and motor currents
    [A] (every thruster shares the characteristic), filtered exactly as :class:`CurrentMap` filters them."""
    speed, current = np.asarray(speed, dtype=float), np.asarray(current, dtype=float)
    if speed.ndim != 2 or speed.shape != current.shape or speed.shape[0] < 10:
        raise RobofdiError(f"identify_current_characteristic: speed and current must be equal (N >= 10, p) arrays, "
                           f"got {speed.shape} and {current.shape}")
    f = _Filter(sample_time, tau)
    ws, cs = [], []
    w = c = None
    for k in range(len(speed)):
        w, c = f(w, speed[k]), f(c, current[k])
        ws.append(w)
        cs.append(c)
    ws, cs = np.array(ws), np.array(cs)
    acc = np.vstack([np.zeros((1, ws.shape[1])), np.diff(ws, axis=0) / sample_time])
    Phi = current_features(ws, acc)[1:].reshape(-1, 3)
    theta, *_ = np.linalg.lstsq(Phi, cs[1:].ravel(), rcond=None)
    return theta


class CurrentMap(_Telemetry):
    """Current vs propeller-rate characteristic, Romeo [9, 11]; per thruster two residual components:

    * ``<t>_current``: i_f − θ·φ(Ω_f, Ω̇_f) [A], the measured current against the identified characteristic
      (filtered, time constant ``tau``);
    * ``<t>_speed``: (Ω_f − Ω̂_f)/(|Ω̂_f| + Ω_0) [1], the propeller speed against the nominal motor driven by the
      commanded voltage (Ω_0 = 5 % of the rated speed keeps it finite near zero).

    A thruster is isolated by its speed component (a rotor failure is consistent with the characteristic while
    it decelerates, so only the speed shows it); the signs of the two components give the region
    (:func:`current_map_region`). The estimate is the effectiveness loss 1 − c Ω|Ω| / u from the telemetry.
    """

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, characteristic,
                 tau: float = 0.1, thrust_limit: float = 40.0, substeps: int = 4):
        super().__init__(model, measurements, sample_time, thrust_limit)
        self.theta = np.asarray(characteristic, dtype=float)
        if self.theta.shape != (3,) or not np.all(np.isfinite(self.theta)):
            raise RobofdiError(f"CurrentMap: field 'characteristic' must be 3 finite coefficients, got {characteristic!r}")
        self.tau, self.substeps = float(tau), int(substeps)
        self._filter = _Filter(sample_time, tau)
        self.rated_speed = float(model.thruster.steady_speed(model.thruster.max_voltage))
        p = len(self.thrusters)
        self.components = [f"{t}_current" for t in self.thrusters] + [f"{t}_speed" for t in self.thrusters]
        self.estimate_components = list(self.thrusters)
        self.estimate_modes = ["level"] * p
        self.units = {"residual": ["A"] * p + ["1"] * p, "estimate": ["1"] * p}
        self.reset()

    def reset(self) -> None:
        self._w = self._c = self._w_model_f = None
        self._w_model = np.zeros(len(self.thrusters))

    def update(self, y, u) -> Residual:
        y, u = self._inputs(y, u)
        th, h = self.model.thruster, self.T / self.substeps
        v_cmd = self.commanded_voltage(u)
        for _ in range(self.substeps):                  # the nominal motor, driven by the commanded voltage
            self._w_model = self._w_model + h * th.speed_rate(self._w_model, v_cmd)
        w_prev = self._w
        self._w = self._filter(self._w, y[self._speed])
        self._c = self._filter(self._c, y[self._current])
        self._w_model_f = self._filter(self._w_model_f, self._w_model)
        acc = np.zeros_like(self._w) if w_prev is None else (self._w - w_prev) / self.T
        r_current = self._c - current_features(self._w, acc) @ self.theta
        r_speed = (self._w - self._w_model_f) / (np.abs(self._w_model_f) + 0.05 * self.rated_speed)
        thrust = th.thrust(y[self._speed])
        loss = np.where(np.abs(u) > 2.0, 1.0 - thrust / np.where(np.abs(u) > 2.0, u, 1.0), 0.0)
        return Residual(np.concatenate([r_current, r_speed]), loss)

    def signatures(self):
        return [Signature(t, frozenset([f"{t}_speed"]), frozenset([f"{t}_current"])) for t in self.thrusters]


def current_map_region(r_current: float, r_speed: float, current_threshold: float, speed_threshold: float,
                       direction: float) -> str:
    """Romeo's region map (digest §3.2, [RECON]) from one thruster's two :class:`CurrentMap` components and the
    sign of its command ``direction``: over-speed with extra current → flooding; under-speed with extra current →
    blocking (stalled rotor drawing current); under-speed without extra current → rotor failure."""
    s = 1.0 if direction >= 0 else -1.0
    extra_current = s * r_current > current_threshold
    fast, slow = s * r_speed > speed_threshold, s * r_speed < -speed_threshold
    if fast and extra_current:
        return "flooding"
    if slow:
        return "blocking" if extra_current else "rotor_failure"
    if abs(r_current) <= current_threshold and abs(r_speed) <= speed_threshold:
        return "nominal"
    return "unknown"


class ForceObserver(_Telemetry):
    """Generalised-momentum observer of the vehicle — eq. (3) in De Luca & Mattone's discrete form (eq. (10)):

        r(k) = K_O ( M̂ ν_k − M̂ ν_0 − Σ_{j<k} T (B u_j − n̂(R_j, ν_j) + r_j) )

    r ≈ τ_actual − B u, the generalised force deficit [N, N·m] (components X, Y, Z, K, M, N), with ν from the
    DVL and gyros and R from the attitude. The estimate is the per-thruster effectiveness loss from the
    propeller-speed telemetry, 1 − ĉ Ω|Ω| / u (0 while |u| < 2 N). From motion alone, the 8 effectivenesses are
    not identifiable at one instant (6 equations); :func:`effectiveness_identifiability` checks a window.
    """

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, gain: float = 2.0,
                 thrust_limit: float = 40.0):
        super().__init__(model, measurements, sample_time, thrust_limit)
        if not (np.isfinite(gain) and 0 < gain * sample_time < 1):
            raise RobofdiError(f"ForceObserver: field 'gain' must be in (0, 1/T) = (0, {1 / sample_time:g}), got {gain!r}")
        self.gain = float(gain)
        self.components = [f"force_{a}" for a in AXES]
        self.estimate_components = list(self.thrusters)
        self.estimate_modes = ["level"] * len(self.thrusters)
        self.units = {"residual": ["N"] * 3 + ["N·m"] * 3, "estimate": ["1"] * len(self.thrusters)}
        self.reset()

    def reset(self) -> None:
        self._prev = None

    def update(self, y, u) -> Residual:
        y, u = self._inputs(y, u)
        R = rotation_from_euler(y[4:7])
        nu = y[7:13]
        m = self.model
        p = m.M @ nu
        if self._prev is None:
            self._p0, self._integral, self._r = p, np.zeros(6), np.zeros(6)
        else:
            Rp, nup = self._prev
            self._integral = self._integral + self.T * (m.B @ u - m.bias(Rp, nup) + self._r)
            self._r = self.gain * (p - self._p0 - self._integral)
        self._prev = (R, nu)
        thrust = m.thruster.thrust(y[self._speed])
        loss = np.where(np.abs(u) > 2.0, 1.0 - thrust / np.where(np.abs(u) > 2.0, u, 1.0), 0.0)
        return Residual(self._r.copy(), loss)

    def signatures(self):
        return [Signature(c, frozenset([c])) for c in self.components]


def effectiveness_identifiability(B: np.ndarray, demands: np.ndarray) -> tuple[int, float]:
    """(rank, smallest singular value) of the stacked regressor [B diag(u_k)]_k of τ_deficit = B diag(u)(e − 1)
    over a window of thrust demands (N, p): the p effectivenesses are identifiable from motion alone only when
    the rank is p."""
    U = np.asarray(demands, dtype=float)
    Phi = np.vstack([B * u for u in U])
    sv = np.linalg.svd(Phi, compute_uv=False)
    return int(np.sum(sv > 1e-9 * max(1.0, sv[0]))), float(sv[-1] if len(sv) >= B.shape[1] else 0.0)
