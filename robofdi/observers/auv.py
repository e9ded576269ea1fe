"""AUV diagnosers of Antonelli's survey (Sec. 4), built from the nominal model, the thrust demands and measurements.

* :class:`VoltageResidual` — ODIN's Hall-effect scheme [48]: measured vs commanded motor voltage per thruster.
* :class:`CurrentMap` — Romeo's current vs propeller-rate characteristic [9, 11]: the nominal characteristic is
  identified from fault-free data (:func:`identify_current_characteristic`); the region of the mismatch separates
  rotor failure, blocking and flooding (:func:`current_map_region`).
* :class:`ForceObserver` — a generalised-momentum observer on the whole vehicle (eq. (3) of the survey, in the
  discrete form of De Luca & Mattone eq. (10)): the generalised force deficit τ_actual − τ_demand, and the
  per-thruster thrust change from the propeller-speed telemetry.
* :class:`DepthVote` — ODIN's pressure / sonar / ARX virtual-sensor vote with the 1 s switch [48], and
  :class:`DepthSwitchingControl`, which hands the accepted depth to the controller.

Every diagnoser takes y with the channels of :class:`robofdi.sims.auv.AuvSimulator` (navigation, then propeller
speeds, motor currents and voltages) and u = ū(k−1), the thrust demands [N] held over the last interval.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.decision import Signature
from robofdi.errors import RobofdiError
from robofdi.models.auv import AXES, AuvModel, clip, rotation_from_euler
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["VoltageResidual", "CurrentMap", "ForceObserver", "DepthVote", "DepthSwitchingControl",
           "identify_current_characteristic", "identify_depth_arx", "identify_supply_resistance", "vertical_force",
           "CurrentFeatures",
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
        return y, clip(u, -self.thrust_limit, self.thrust_limit)

    def commanded_voltage(self, u: np.ndarray) -> np.ndarray:
        """The driver's voltage [V] for the thrust demands u [N] (the nominal steady-state map)."""
        return self.model.thruster.voltage_for_thrust(clip(u, -self.thrust_limit, self.thrust_limit))


class VoltageResidual(_Telemetry):
    """Hall-effect voltage residual, ODIN [48]: r_j = mean over ``window`` s of (V_hall,j − V_exp,j) [V], with
    V_exp,j = V_cmd,j − R̂_s i_j the drive voltage after the supply's drop at the measured motor current i_j
    (``supply_resistance`` R̂_s [Ω], identified on fault-free telemetry by :func:`identify_supply_resistance`; 0:
    the bare ODIN residual V_hall − V_cmd). Without the drop term, a hard manoeuvre that draws tens of amperes sags
    every terminal voltage by R_s i and looks like a drive fault.

    A zeroed drive gives r_j → −V_cmd,j: the fault is invisible while |V_cmd,j| stays under the threshold
    (detectability depends on the command; :meth:`detectable`)."""

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, window: float = 0.2,
                 thrust_limit: float = 40.0, supply_resistance: float = 0.0):
        super().__init__(model, measurements, sample_time, thrust_limit)
        if not (np.isfinite(window) and window >= sample_time):
            raise RobofdiError(f"VoltageResidual: field 'window' must be >= the sample time {sample_time} s, got {window!r}")
        if not (np.isfinite(supply_resistance) and supply_resistance >= 0):
            raise RobofdiError(f"VoltageResidual: field 'supply_resistance' must be >= 0 Ω, got {supply_resistance!r}")
        self.supply_resistance = float(supply_resistance)
        self.samples = int(round(window / sample_time))
        self.components = list(self.thrusters)
        self.estimate_components = list(self.thrusters)
        self.estimate_modes = ["level"] * len(self.thrusters)
        self.units = {"residual": ["V"] * len(self.thrusters), "estimate": ["N"] * len(self.thrusters)}
        self.reset()

    def reset(self) -> None:
        self._buffer = np.zeros((self.samples, 2, len(self.thrusters)))
        self._k = 0

    def update(self, y, u) -> Residual:
        """Residual [V]; estimate: the thrust change [N] the measured voltage stands for, T(V_hall) − u (window mean)."""
        y, u = self._inputs(y, u)
        th = self.model.thruster
        v = y[self._voltage]
        expected = self.commanded_voltage(u) - self.supply_resistance * y[self._current]
        self._buffer[self._k % self.samples] = (v - expected, th.thrust(th.steady_speed(v)) - u)
        self._k += 1
        r, estimate = self._buffer[: min(self._k, self.samples)].mean(axis=0)
        return Residual(r, estimate)

    def detectable(self, u: np.ndarray, threshold: np.ndarray) -> np.ndarray:
        """Per thruster: would zeroing its drive raise the residual above ``threshold`` at the demand u?"""
        return np.abs(self.commanded_voltage(np.asarray(u, dtype=float))) > np.asarray(threshold)

    def signatures(self):
        return [Signature(t, frozenset([t])) for t in self.thrusters]


def identify_supply_resistance(residual: VoltageResidual, runs) -> float:
    """R̂_s [Ω] of the supply (shared by every thruster) by least squares on fault-free telemetry:
    V_hall − V_cmd = −R_s i over every thruster and sample of ``runs`` = [(y, u), ...] (the pairs a diagnoser
    receives, :func:`robofdi.loop.diagnoser_inputs`); clipped at 0."""
    num = den = 0.0
    for y, u in runs:
        y, u = np.asarray(y, dtype=float), np.clip(np.asarray(u, dtype=float), -residual.thrust_limit, residual.thrust_limit)
        drop = y[:, residual._voltage] - residual.commanded_voltage(u)
        i = y[:, residual._current]
        num, den = num - float(np.sum(drop * i)), den + float(np.sum(i * i))
    if den <= 0:
        raise RobofdiError("identify_supply_resistance: the telemetry carries no motor current")
    return max(0.0, num / den)


class CurrentFeatures:
    """Filtered regressors of the current characteristic ``i = θ·φ, φ = [|Ω|Ω, Ω̇, Ω]`` (propeller load, rotor
    inertia, viscous motor friction). The motor law ``K_t i = J Ω̇ + K_q |Ω|Ω`` is linear in φ, so every term is
    filtered by the same first-order low-pass (α = T/(τ + T)) *before* the product with θ: Ω̇ is the difference of
    the filtered Ω, and the nonlinear term is filtered as ``|Ω|Ω`` (not formed from a filtered Ω), which keeps the
    filtered law exact and the noise out of the derivative. ``update`` → (φ_f (p, 3), i_f (p,))."""

    def __init__(self, sample_time: float, tau: float):
        if not (np.isfinite(tau) and tau >= 0):
            raise RobofdiError(f"CurrentFeatures: field 'tau' must be a time constant >= 0 s, got {tau!r}")
        self.T, self.alpha = float(sample_time), sample_time / (tau + sample_time)
        self.reset()

    def reset(self) -> None:
        self._x = None                       # filtered [|Ω|Ω, Ω, i], (3, p)

    def update(self, speed: np.ndarray, current: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.stack([np.abs(speed) * speed, speed, current])
        if self._x is None:
            prev_w, self._x = speed, x
        else:
            prev_w = self._x[1].copy()
            self._x = self._x + self.alpha * (x - self._x)
        w2, w, i = self._x
        return np.stack([w2, (w - prev_w) / self.T, w], axis=-1), i


def identify_current_characteristic(speed: np.ndarray, current: np.ndarray, sample_time: float, tau: float = 0.5) -> np.ndarray:
    """θ (3,) of :class:`CurrentFeatures` by least squares over fault-free telemetry — Romeo's experimentally
    identified nominal characteristic [9]. ``speed``/``current``: (N, p) propeller speeds [rad/s] and motor currents
    [A] of one run (every thruster shares the characteristic), filtered exactly as :class:`CurrentMap` filters them."""
    speed, current = np.asarray(speed, dtype=float), np.asarray(current, dtype=float)
    if speed.ndim != 2 or speed.shape != current.shape or speed.shape[0] < 10:
        raise RobofdiError(f"identify_current_characteristic: speed and current must be equal (N >= 10, p) arrays, "
                           f"got {speed.shape} and {current.shape}")
    f = CurrentFeatures(sample_time, tau)
    rows = [f.update(w, i) for w, i in zip(speed, current)][1:]
    Phi = np.concatenate([phi for phi, _ in rows])
    theta, *_ = np.linalg.lstsq(Phi, np.concatenate([i for _, i in rows]), rcond=None)
    return theta


class _Filter:
    """First-order low-pass y ← y + α (x − y) with α = T/(τ + T)."""

    def __init__(self, sample_time: float, tau: float):
        self.alpha = sample_time / (tau + sample_time)

    def __call__(self, prev, x):
        return x.copy() if prev is None else prev + self.alpha * (x - prev)


class CurrentMap(_Telemetry):
    """Current vs propeller-rate characteristic, Romeo [9, 11]; per thruster two residual components:

    * ``<t>_current``: s (i_f − θ·φ(Ω_f, Ω̇_f)) [A], the measured current against the identified characteristic
      (filtered, time constant ``tau``);
    * ``<t>_speed``: s (Ω_f − Ω̂_f)/(|Ω̂_f| + Ω_0) [1], the propeller speed against the nominal motor driven by the
      commanded voltage (Ω_0 = ``speed_floor`` × rated speed keeps it finite near zero);

    with s = tanh(Ω̂_f / Ω_0), the rotation the command asks for: positive = more current / faster than expected;
    near zero speed, where the characteristic says little and the command chatters through zero, s fades out.

    A thruster is isolated by its speed component (a rotor failure is consistent with the characteristic while
    it decelerates, so only the speed shows it); the signs of the two components give the region
    (:func:`current_map_region`). The estimate is the thrust change ĉ Ω|Ω| − u [N] from the speed telemetry.
    """

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, characteristic,
                 tau: float = 0.5, thrust_limit: float = 40.0, substeps: int = 4, speed_floor: float = 0.2):
        super().__init__(model, measurements, sample_time, thrust_limit)
        self.theta = np.asarray(characteristic, dtype=float)
        if self.theta.shape != (3,) or not np.all(np.isfinite(self.theta)):
            raise RobofdiError(f"CurrentMap: field 'characteristic' must be 3 finite coefficients, got {characteristic!r}")
        self.tau, self.substeps, self.speed_floor = float(tau), int(substeps), float(speed_floor)
        self._filter = _Filter(sample_time, tau)
        self.rated_speed = float(model.thruster.steady_speed(model.thruster.max_voltage))
        p = len(self.thrusters)
        self.components = [f"{t}_current" for t in self.thrusters] + [f"{t}_speed" for t in self.thrusters]
        self.estimate_components = list(self.thrusters)
        self.estimate_modes = ["level"] * p
        self.units = {"residual": ["A"] * p + ["1"] * p, "estimate": ["N"] * p}
        self.reset()

    def reset(self) -> None:
        self._features = CurrentFeatures(self.T, self.tau)
        self._w_model_f = None
        self._w_model = np.zeros(len(self.thrusters))

    def update(self, y, u) -> Residual:
        y, u = self._inputs(y, u)
        th, h = self.model.thruster, self.T / self.substeps
        v_cmd = self.commanded_voltage(u)
        for _ in range(self.substeps):                  # the nominal motor, driven by the commanded voltage
            self._w_model = self._w_model + h * th.speed_rate(self._w_model, v_cmd)
        phi, current = self._features.update(y[self._speed], y[self._current])
        w = phi[:, 2]
        self._w_model_f = self._filter(self._w_model_f, self._w_model)
        floor = self.speed_floor * self.rated_speed
        direction = np.tanh(self._w_model_f / floor)      # the rotation the command asks for, faded out near zero
        r_current = direction * (current - phi @ self.theta)
        r_speed = direction * (w - self._w_model_f) / (np.abs(self._w_model_f) + floor)
        return Residual(np.concatenate([r_current, r_speed]), th.thrust(y[self._speed]) - u)

    def signatures(self):
        return [Signature(t, frozenset([f"{t}_speed"]), frozenset([f"{t}_current"])) for t in self.thrusters]


def current_map_region(r_current: float, r_speed: float, current_threshold: float, speed_threshold: float) -> str:
    """Romeo's region map (digest §3.2, [RECON]) from one thruster's two (signed) :class:`CurrentMap` components:

    * over-speed without a current deficit → flooding (electrical dispersion drives the blades faster than
      commanded; the leakage adds current);
    * under-speed with extra current → blocking (a stalled rotor drawing current);
    * under-speed without extra current → rotor failure (the blades stop, no current).
    """
    extra_current, less_current = r_current > current_threshold, r_current < -current_threshold
    fast, slow = r_speed > speed_threshold, r_speed < -speed_threshold
    if fast and not less_current:
        return "flooding"
    if slow:
        return "blocking" if extra_current else "rotor_failure"
    if not (extra_current or less_current):
        return "nominal"
    return "unknown"


class ForceObserver(_Telemetry):
    """Generalised-momentum observer of the vehicle — eq. (3) in De Luca & Mattone's discrete form (eq. (10)):

        r(k) = K_O ( M̂ ν_k − M̂ ν_0 − Σ_{j<k} T (B u_j − n̂(R_j, ν_j) + r_j) )

    r ≈ τ_actual − B u, the generalised force deficit [N, N·m] (components X, Y, Z, K, M, N), with ν from the
    DVL and gyros and R from the attitude. The estimate is the per-thruster thrust change from the propeller-speed
    telemetry, ĉ Ω|Ω| − u [N]. From motion alone, the 8 effectivenesses are
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
        self.units = {"residual": ["N"] * 3 + ["N·m"] * 3, "estimate": ["N"] * len(self.thrusters)}
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
        return Residual(self._r.copy(), m.thruster.thrust(y[self._speed]) - u)

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


def vertical_force(model: AuvModel, euler: np.ndarray, u: np.ndarray) -> float:
    """World-frame vertical (z up) component of the thrusters' force B u [N] at attitude ``euler``."""
    return float(rotation_from_euler(euler)[2] @ (model.B[:3] @ u))


def identify_depth_arx(depth: np.ndarray, force: np.ndarray) -> np.ndarray:
    """θ = (a1, a2, b1, b2, c0) of the ARX depth model z(k) = a1 z(k−1) + a2 z(k−2) + b1 F(k−1) + b2 F(k−2) + c0 by
    least squares (digest §6.7, the ODIN virtual sensor [48]); ``depth`` [m] at the ARX samples k and ``force`` [N]
    the mean downward force over the interval ending at sample k (force[k] = F(k−1)); c0 absorbs the net buoyancy."""
    z, F = np.asarray(depth, dtype=float), np.asarray(force, dtype=float)
    if z.ndim != 1 or z.shape != F.shape or z.size < 10:
        raise RobofdiError(f"identify_depth_arx: depth and force must be equal 1-D series of >= 10 samples, got "
                           f"{z.shape} and {F.shape}")
    Phi = np.column_stack([z[1:-1], z[:-2], F[2:], F[1:-1], np.ones(z.size - 2)])
    theta, *_ = np.linalg.lstsq(Phi, z[2:], rcond=None)
    return theta


class DepthVote(_Telemetry):
    """Three depth sources and their residuals, ODIN [48] (Yang, Yuh & Choi; survey Fig. 7, digest §6.7):

    pressure depth z_p, sonar depth z_s = H − altitude over a sea floor of known depth H, and a virtual sensor z_ARX:
    the ARX model (:func:`identify_depth_arx`) run at ``arx_period`` on the commanded vertical force, re-anchored
    to the accepted depth every ``reanchor`` s while that depth is trustworthy (pressure and sonar agree within
    ``switch_threshold``, or only one of them is left). Residuals [m]:
    R1 = z_p − z_s, R2 = z_p − z_ARX, R3 = z_s − z_ARX (isolation: pressure {R1, R2}, sonar {R1, R3}).

    The switch (ODIN's "programmed time"): when a sensor's two residuals stay above ``switch_threshold`` for
    ``switch_delay`` s, it is disconnected for the rest of the run and :attr:`accepted_depth` comes from the other.
    """

    SOURCES = ("depth", "altitude")

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, arx, floor_depth: float,
                 arx_period: float = 0.1, reanchor: float = 2.0, switch_threshold: float = 0.2,
                 switch_delay: float = 1.0, thrust_limit: float = 40.0):
        super().__init__(model, measurements, sample_time, thrust_limit)
        self.arx = np.asarray(arx, dtype=float)
        if self.arx.shape != (5,) or not np.all(np.isfinite(self.arx)):
            raise RobofdiError(f"DepthVote: field 'arx' must be 5 finite coefficients (a1 a2 b1 b2 c0), got {arx!r}")
        for name, v in (("floor_depth", floor_depth), ("switch_threshold", switch_threshold),
                        ("switch_delay", switch_delay), ("reanchor", reanchor)):
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"DepthVote: field {name!r} must be > 0, got {v!r}")
        ratio = arx_period / sample_time
        if not (round(ratio) >= 1 and abs(ratio - round(ratio)) < 1e-9):
            raise RobofdiError(f"DepthVote: field 'arx_period' must be a multiple of the sample time {sample_time} s, "
                               f"got {arx_period!r}")
        self.decimation, self.floor_depth = int(round(ratio)), float(floor_depth)
        self.reanchor_samples = int(round(reanchor / sample_time))
        self.switch_threshold, self.switch_samples = float(switch_threshold), int(round(switch_delay / sample_time))
        try:
            self._z, self._alt, self._att = (self.measurements.index(c) for c in ("depth", "altitude", "roll"))
        except ValueError:
            raise RobofdiError("DepthVote: measurements must include 'depth', 'altitude' and 'roll', 'pitch', 'yaw'") from None
        self.components = ["R1_pressure_sonar", "R2_pressure_arx", "R3_sonar_arx"]
        self.estimate_components = list(self.SOURCES)
        self.estimate_modes = ["level", "level"]
        self.units = {"residual": ["m"] * 3, "estimate": ["m", "m"]}
        self.reset()

    def reset(self) -> None:
        self._k = 0
        self._hist = None                     # [z(k−1), z(k−2), F(k−2)] of the ARX (F(k−1): the interval just ended)
        self._z_arx = None
        self._force = []
        self._over = np.zeros(2, dtype=int)   # consecutive samples over the switch threshold: pressure, sonar
        self.disconnected: list[str] = []
        self.switch_time: float | None = None
        self.accepted_depth = np.nan

    def update(self, y, u) -> Residual:
        y, u = self._inputs(y, u)
        zp, zs = y[self._z], self.floor_depth - y[self._alt]
        self._force.append(-vertical_force(self.model, y[self._att:self._att + 3], u))    # downward force [N]
        accepted = zs if "depth" in self.disconnected else zp
        if self._hist is None:
            self._hist = [accepted, accepted, self._force[-1]]
            self._z_arx = accepted
        if self._k and self._k % self.decimation == 0:
            F_last = float(np.mean(self._force))
            self._force = []
            z1, z2, F2 = self._hist
            self._z_arx = float(self.arx @ [z1, z2, F_last, F2, 1.0])
            self._hist = [self._z_arx, z1, F_last]
        r = np.array([zp - zs, zp - self._z_arx, zs - self._z_arx])
        # re-anchor while the accepted depth is trustworthy: both physical sensors agree, or only one is left
        trusted = bool(self.disconnected) or abs(r[0]) < self.switch_threshold
        if trusted and self._k % self.reanchor_samples == 0:
            self._hist[0] = self._hist[1] = self._z_arx = accepted
        over = np.abs(r) > self.switch_threshold
        for j, (name, pair) in enumerate((("depth", (0, 1)), ("altitude", (0, 2)))):
            self._over[j] = self._over[j] + 1 if over[list(pair)].all() else 0
            if self._over[j] >= self.switch_samples and name not in self.disconnected and len(self.disconnected) == 0:
                self.disconnected.append(name)
                self.switch_time = self._k * self.T
        self._k += 1
        self.accepted_depth = zs if "depth" in self.disconnected else zp
        voted = self.accepted_depth
        return Residual(r, np.array([zp - voted, zs - voted]))

    def signatures(self):
        return [Signature("depth", frozenset(["R1_pressure_sonar", "R2_pressure_arx"])),
                Signature("altitude", frozenset(["R1_pressure_sonar", "R3_sonar_arx"]))]


class DepthSwitchingControl:
    """A controller whose depth measurement comes from a :class:`DepthVote` (ODIN's sensor fault tolerance): the
    vote is stepped with each measurement and the controller's previous demand, and the depth channel handed to
    ``controller`` is the vote's accepted depth."""

    def __init__(self, controller, vote: DepthVote):
        self.controller, self.vote = controller, vote
        self.reset()

    def reset(self) -> None:
        if hasattr(self.controller, "reset"):
            self.controller.reset()
        self.vote.reset()
        self._u = np.zeros(len(self.vote.thrusters))

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        self.vote.update(y, self._u)
        y = np.array(y, dtype=float)
        y[self.vote._z] = self.vote.accepted_depth
        self._u = self.controller.update(y, reference)
        return self._u
