"""Speed control of the wheel actuator: the 5 RPM ramp and a PI(D) controller with flow feedforward."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["SpeedRamp", "SpeedPID"]

RPM = 2 * np.pi / 60


@dataclass(frozen=True)
class SpeedRamp:
    """ω_ref(t): 0 → ``target_rpm`` linearly over ``ramp_time`` s, then held (Leuschen et al., Sec. 5: ramp to 5 RPM)."""

    target_rpm: float = 5.0
    ramp_time: float = 2.0

    def __post_init__(self):
        if not (np.isfinite(self.target_rpm) and 0 < self.target_rpm <= 185):
            raise RobofdiError(f"SpeedRamp: field 'target_rpm' must be in (0, 185] rpm, got {self.target_rpm!r}")
        if not (np.isfinite(self.ramp_time) and self.ramp_time > 0):
            raise RobofdiError(f"SpeedRamp: field 'ramp_time' must be > 0 s, got {self.ramp_time!r}")

    def __call__(self, t: float) -> np.ndarray:
        return np.array([self.target_rpm * RPM * min(max(t, 0.0) / self.ramp_time, 1.0)])


class SpeedPID:
    """u = u_ff + K_p e + K_i ∫e + K_d ė, clipped to ±1, anti-windup by clamping — spec digest §6.2.

    u_ff = d_m ω_ref / (K_f sqrt(2 p_s/ρ)) from the *catalogue* parameters (belief); e = ω_ref − measured speed.
    """

    def __init__(self, dt: float, kp: float = 0.005, ki: float = 0.5, kd: float = 0.0, feedforward: float = 0.0):
        for k, v in (("dt", dt), ("kp", kp), ("ki", ki), ("kd", kd), ("feedforward", feedforward)):
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0) or (k == "dt" and v == 0):
                raise RobofdiError(f"SpeedPID: field {k!r} must be a finite number >= 0 (dt > 0), got {v!r}")
        self.dt, self.kp, self.ki, self.kd, self.feedforward = dt, kp, ki, kd, feedforward
        self.reset()

    def reset(self) -> None:
        self.integral = 0.0
        self.previous = None

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        ref = float(np.asarray(reference).ravel()[0])
        e = ref - float(y[0])
        de = 0.0 if self.previous is None else (e - self.previous) / self.dt
        self.previous = e
        base = self.feedforward * ref + self.kp * e + self.kd * de
        self.integral = float(np.clip(self.integral + self.ki * e * self.dt, -1.0 - base, 1.0 - base))
        return np.array([float(np.clip(base + self.integral, -1.0, 1.0))])
