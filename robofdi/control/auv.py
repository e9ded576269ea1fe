"""Task-space AUV control (the survey's eq. (8)) and seeded 6-DOF missions.

Eq. (8), u = E⁺[(η̈_d − β) + K_v η̇ + K_p η̃], with the digest's [ERRATUM] (velocity *error* K_v(η̇_d − η̇)) and
E = J(η) M⁻¹ B, β = J̇ν − J M⁻¹ n(ν, R) ([DERIVED]). Written as its two factors: the task-space acceleration
command a = η̈_d + K_v(η̇_d − η̇) + K_p η̃ is mapped to the body acceleration ν̇ = J⁻¹(a − J̇ν), the nominal model
gives the wrench τ = M ν̇ + n, and the thrust demand is u = B⁺ τ (minimum norm; the accommodation may re-allocate
τ = B u with the diagnosed health). Only measurements and the nominal model are used.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robofdi.control.trajectory import Sequence
from robofdi.errors import RobofdiError, all_finite
from robofdi.models.auv import AuvModel, T_euler_from_body, cross, rotation_from_euler
from robofdi.seeding import rng

__all__ = ["TaskSpaceAuvControl", "navigation_pose", "random_mission", "MissionLimits", "POSE_NAMES", "wrap"]

#: Task-space coordinates η: world position (z up) and ZYX Euler angles.
POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")


def wrap(angle):
    """Angle(s) wrapped to [−π, π)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def navigation_pose(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(η (6,), ν (6,)) from the navigation channels of :data:`robofdi.sims.auv.NAVIGATION_CHANNELS`:
    η = [x, y, −depth, roll, pitch, yaw], ν = [DVL u, v, w, gyro p, q, r]."""
    return np.array([y[0], y[1], -y[2], y[4], y[5], y[6]]), y[7:13]


@dataclass
class TaskSpaceAuvControl:
    """Eq. (8) of the survey (module docstring) with diagonal gains K_p [1/s²], K_v [1/s] (spec §6.8: 1 and 2)."""

    model: AuvModel
    kp: float | tuple = 1.0
    kv: float | tuple = 2.0

    def __post_init__(self):
        self.Kp = np.broadcast_to(np.asarray(self.kp, dtype=float), (6,)).copy()
        self.Kv = np.broadcast_to(np.asarray(self.kv, dtype=float), (6,)).copy()
        if not (np.all(np.isfinite(self.Kp)) and np.all(self.Kp > 0) and np.all(np.isfinite(self.Kv)) and np.all(self.Kv > 0)):
            raise RobofdiError(f"TaskSpaceAuvControl: fields 'kp' and 'kv' must be > 0, got {self.kp!r}, {self.kv!r}")
        self.B_pinv = np.linalg.pinv(self.model.B)
        self.tau = np.zeros(6)

    def reset(self) -> None:
        self.tau = np.zeros(6)

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        eta_d, deta_d, ddeta_d = reference
        if not all_finite(np.asarray(y[:13], dtype=float)):
            raise RobofdiError("TaskSpaceAuvControl: non-finite navigation measurement (NaN sensor reading)")
        eta, nu = navigation_pose(y)
        R = rotation_from_euler(eta[3:])
        T = T_euler_from_body(eta[3:])
        deta = np.concatenate([R @ nu[:3], T @ nu[3:]])
        err = eta_d - eta
        err[3:] = wrap(err[3:])
        a = ddeta_d + self.Kv * (deta_d - deta) + self.Kp * err
        # J̇ν: linear part R S(ω) ν1; angular part Ṫ ν2 by a directional difference of T along η̇2
        h = 1e-6
        T_dot_nu = (T_euler_from_body(eta[3:] + h * deta[3:]) - T) @ nu[3:] / h
        nu_dot = np.concatenate([R.T @ a[:3] - cross(nu[3:], nu[:3]), np.linalg.solve(T, a[3:] - T_dot_nu)])
        self.tau = self.model.wrench(R, nu, nu_dot)
        return self.B_pinv @ self.tau


@dataclass(frozen=True)
class MissionLimits:
    """Ranges of a random mission: horizontal box half-width [m], depth range [m], yaw range [rad], peak speed [m/s]."""

    half_width: float = 2.0
    depth: tuple = (3.0, 8.0)
    yaw: float = np.pi / 6
    speed: float = 0.2
    dwell: float = 4.0

    def __post_init__(self):
        lo, hi = self.depth
        if not (0 < lo < hi and np.isfinite(hi)):
            raise RobofdiError(f"MissionLimits: field 'depth' must be (min, max) with 0 < min < max, got {self.depth!r}")
        for name in ("half_width", "yaw", "speed", "dwell"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"MissionLimits: field {name!r} must be > 0, got {v!r}")


def random_mission(seed: int, duration: float, limits: MissionLimits = MissionLimits(), start_depth: float = 5.0,
                   name: str = "mission") -> Sequence:
    """A seeded waypoint mission of ``duration`` s: station keeping, then quintic segments between random
    (x, y, depth, yaw) waypoints (roll = pitch = 0) timed for a peak speed ``limits.speed``, each followed by a
    dwell. The reference is (η_d, η̇_d, η̈_d) with z = −depth."""
    if not (np.isfinite(duration) and duration > 0):
        raise RobofdiError(f"random_mission: field 'duration' must be > 0 s, got {duration!r}")
    g = rng(seed, "mission", name)
    wp = [np.array([0.0, 0.0, -start_depth, 0.0, 0.0, 0.0])]
    durations, t = [], 0.0
    while t < duration:
        nxt = np.array([*g.uniform(-limits.half_width, limits.half_width, 2), -g.uniform(*limits.depth), 0.0, 0.0,
                        g.uniform(-limits.yaw, limits.yaw)])
        dist = np.linalg.norm(nxt[:3] - wp[-1][:3])
        d = max(4.0, 1.875 * dist / limits.speed)          # quintic peak speed = 1.875 × mean speed
        wp += [nxt, nxt]
        durations += [d, limits.dwell]
        t += d + limits.dwell
    return Sequence.through(wp, durations)
