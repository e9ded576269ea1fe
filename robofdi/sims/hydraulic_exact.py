"""The exact-model wheel actuator: eqs. (5)–(6) of Leuschen, Walker & Cavallaro integrated as they stand (RK4,
0.1 ms), for the chapter's numbers that assume plant == model.

This is *not* the rig (:class:`robofdi.sims.hydraulic.HydraulicRig`, MuJoCo mechanics with mismatch and noise).
It is the plant the chapter's exact-model statements are about — R1 = T_l/J_t without load compensation, the
residuals ≈ 0 at steady state, the fault/baseline ratios, the PLAR saw-tooth on a *simulated* servovalve
(Fig. 11) — with the harness choices a simulation needs: the symmetric 4-way valve law
Q = K_f x_v sqrt(2(p_s − sgn(x_v) p_l)/ρ), a first-order spool (τ_v), a throttled load pump
p_L = ½ρ(d_m θ̇/A_th)² sgn θ̇ (T_l = d_m p_L), a leak orifice to tank Q_leak = A_leak sqrt(2|p_l|/ρ) sgn p_l, the PI
speed controller with flow feedforward, and a runaway limiter (valve command 0 above ``overspeed_factor`` × the
target). No sensor noise. Table-1 faults are emulated as the chapter's harness does (digest of Sec. 5):
open winding — the spool goes to null (plant input 0, the diagnoser still sees the command); sticking — plant
input 0 for ``stick_hold`` s every ``stick_period`` s inside ``stick_window``; tachometer — the speed reads 0
(for the controller and the diagnoser); leak — the orifice opens.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from robofdi.checks import check_fields, is_number, is_positive
from robofdi.control.speed import RPM, SpeedPID, SpeedRamp
from robofdi.errors import RobofdiError
from robofdi.models.hydraulic import CATALOGUE, HydraulicParameters

__all__ = ["ExactRun", "EXACT_FAULTS", "exact_model_run", "leak_area_for_share"]

EXACT_FAULTS = ("none", "open_winding", "sticking_valve", "tachometer_loss", "leak")


@dataclass(frozen=True)
class ExactRun:
    """Settings of one exact-model run: parameters (the plant's, default the catalogue = the model's), target
    speed [rpm], ramp [s], duration [s], load throttle area [m²] (None: no load), fault (one of
    :data:`EXACT_FAULTS`) with its onset [s], leak orifice [m²], spool lag [s], sticking timing [s], PI gains."""

    params: HydraulicParameters = CATALOGUE
    target_rpm: float = 5.0
    ramp_time: float = 2.0
    duration: float = 8.0
    throttle_area: float | None = 1.2e-6
    fault: str = "none"
    onset: float = 5.0
    leak_area: float = 2.4e-8
    valve_tau: float = 0.010
    stick_window: tuple = (0.5, 4.1)
    stick_period: float = 0.6
    stick_hold: float = 0.2
    overspeed_factor: float = 4.0
    kp: float = 0.005
    ki: float = 0.5
    dt: float = 1e-4
    sample_dt: float = 1e-3
    controller_params: HydraulicParameters = field(default=CATALOGUE)

    def __post_init__(self):
        if self.fault not in EXACT_FAULTS:
            raise RobofdiError(f"ExactRun: field 'fault' must be one of {EXACT_FAULTS}, got {self.fault!r}")
        check_fields("ExactRun", self, [
            ("target_rpm", is_positive(self.target_rpm), "a speed > 0 rpm"),
            ("ramp_time", is_positive(self.ramp_time), "a time > 0 s"),
            ("duration", is_positive(self.duration), "a time > 0 s"),
            ("throttle_area", self.throttle_area is None or is_positive(self.throttle_area), "None or an area > 0 m²"),
            ("onset", self.fault in ("none", "sticking_valve") or (is_number(self.onset) and 0 <= self.onset < self.duration),
             "a time inside the run"),
            ("leak_area", is_positive(self.leak_area), "an area > 0 m²"),
            ("valve_tau", is_positive(self.valve_tau), "a time constant > 0 s"),
            ("dt", is_positive(self.dt) and self.dt <= self.sample_dt, "a step > 0 s, <= sample_dt"),
        ])
        ratio = self.sample_dt / self.dt
        if abs(ratio - round(ratio)) > 1e-9:
            raise RobofdiError(f"ExactRun: field 'sample_dt' must be a multiple of dt ({self.dt} s), got {self.sample_dt}")


def leak_area_for_share(share: float, p_l: float, rpm: float = 5.0, params: HydraulicParameters = CATALOGUE) -> float:
    """The orifice [m²] whose flow at load pressure ``p_l`` [Pa] is ``share`` of the motor flow d_m θ̇ at ``rpm``."""
    return float(share * params.d_m * rpm * RPM / np.sqrt(2 * abs(p_l) / params.rho))


def _pump_pressure(w: float, area: float | None, rho: float, d_m: float) -> float:
    if area is None:
        return 0.0
    return 0.5 * rho * (d_m * w / area) ** 2 * np.sign(w)


def exact_model_run(run: ExactRun) -> dict:
    """Integrate the exact model (module docstring); returns 1 kHz arrays: ``time`` [s], ``shaft_speed`` (what the
    controller and a diagnoser read, rad/s), ``true_speed`` [rad/s], ``load_pressure`` [Pa], ``pump_pressure`` [Pa],
    ``servovalve`` (the command, 1), ``spool`` (1) and ``active`` (the fault is acting)."""
    P = run.params
    C = run.controller_params
    pid = SpeedPID(run.sample_dt, kp=run.kp, ki=run.ki, feedforward=C.d_m / (C.K_f * np.sqrt(2 * C.p_s / C.rho)))
    ref = SpeedRamp(run.target_rpm, run.ramp_time)
    overspeed = run.overspeed_factor * run.target_rpm * RPM
    leak = run.leak_area if run.fault == "leak" else 0.0

    d_m, J, B, beta, v_t, K_f, rho, p_s, C_tm = P.d_m, P.J_t, P.B_m, P.beta_e, P.v_t, P.K_f, P.rho, P.p_s, P.C_tm
    k_p, tau, area = 4 * beta / v_t, run.valve_tau, run.throttle_area

    def deriv(w, p, xv, u_plant, leak_on):                      # plain floats: ~10x faster than small arrays
        pL = 0.0 if area is None else 0.5 * rho * (d_m * w / area) ** 2 * (1.0 if w > 0 else -1.0 if w < 0 else 0.0)
        s = 1.0 if xv >= 0 else -1.0
        q = K_f * xv * math.sqrt(2 * max(p_s - s * p, 0.0) / rho)
        q_leak = leak_on * math.copysign(math.sqrt(2 * abs(p) / rho), p)
        return ((d_m * p - B * w - d_m * pL) / J, k_p * (q - d_m * w - C_tm * p - q_leak), (u_plant - xv) / tau)

    n = int(round(run.duration / run.sample_dt)) + 1
    sub = int(round(run.sample_dt / run.dt))
    out = {k: np.zeros(n) for k in ("time", "shaft_speed", "true_speed", "load_pressure", "pump_pressure",
                                    "servovalve", "spool", "active")}
    w, p, xv = 0.0, 0.0, 0.0
    for i in range(n):
        t = i * run.sample_dt
        active = t >= run.onset if run.fault in ("open_winding", "tachometer_loss", "leak") else False
        if run.fault == "sticking_valve":
            lo, hi = run.stick_window
            active = lo <= t < hi and (t - lo) % run.stick_period < run.stick_hold - 1e-12
        w_read = 0.0 if run.fault == "tachometer_loss" and active else w
        u_cmd = float(pid.update(np.array([w_read]), ref(t))[0])
        if w > overspeed:                                    # the rig's limiter
            u_cmd = 0.0
        u_plant = 0.0 if run.fault in ("open_winding", "sticking_valve") and active else u_cmd
        for k, v in (("time", t), ("shaft_speed", w_read), ("true_speed", w), ("load_pressure", p),
                     ("pump_pressure", _pump_pressure(w, run.throttle_area, P.rho, P.d_m)), ("servovalve", u_cmd),
                     ("spool", xv), ("active", float(active))):
            out[k][i] = v
        leak_on = leak if (run.fault == "leak" and active) else 0.0
        h = run.dt
        for _ in range(sub):
            a1, b1, c1 = deriv(w, p, xv, u_plant, leak_on)
            a2, b2, c2 = deriv(w + 0.5 * h * a1, p + 0.5 * h * b1, xv + 0.5 * h * c1, u_plant, leak_on)
            a3, b3, c3 = deriv(w + 0.5 * h * a2, p + 0.5 * h * b2, xv + 0.5 * h * c2, u_plant, leak_on)
            a4, b4, c4 = deriv(w + h * a3, p + h * b3, xv + h * c3, u_plant, leak_on)
            w += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            p += h / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
            xv += h / 6 * (c1 + 2 * c2 + 2 * c3 + c4)
    out["active"] = out["active"].astype(bool)
    return out
