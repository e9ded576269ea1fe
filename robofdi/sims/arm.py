"""MuJoCo industrial arm: the truth the diagnosers never see.

Besides what the MJCF holds (armature, viscous and Coulomb friction), the plant carries a position-dependent
periodic motor torque ripple shaped like eq. (50) of Caccavale & Villani, applied every physics step in
torque units (it enters as δ in eq. (3): M q̈ + n = τ − δ):

    δ_i(q, τ) = c0_i + c1_i sin(N_i q_i + φ1_i) + τ_i c2_i sin(N_i q_i + φ2_i)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robofdi import RobofdiError
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, resolve_asset

__all__ = ["TorqueRipple", "SensorModel", "ArmSimulator"]

# Six ripple cycles per motor revolution: N_i = 6 G_i with the gear ratios of the shipped arm.
_PHYSICAL_FREQ = np.array([900.0, 900.0, 720.0, 480.0, 480.0, 360.0])
_LOW_FREQ = np.array([40.0, 40.0, 40.0, 30.0, 30.0, 30.0])


@dataclass(frozen=True)
class TorqueRipple:
    """Motor torque ripple of the plant. mode: "physical" (N_i = 6 G_i), "low" (slow, well-conditioned) or "off"."""

    mode: str = "physical"
    c1_fraction: float = 0.01   # c1_i = c1_fraction * torque limit_i
    c2: float = 0.02
    seed: int = 0

    def __post_init__(self):
        if self.mode not in ("physical", "low", "off"):
            raise RobofdiError(f"TorqueRipple: field 'mode' must be 'physical', 'low' or 'off', got {self.mode!r}")
        for name in ("c1_fraction", "c2"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise RobofdiError(f"TorqueRipple: field {name!r} must be a finite number >= 0, got {v!r}")

    def coefficients(self, torque_limit: np.ndarray):
        n = len(torque_limit)
        freq = (_PHYSICAL_FREQ if self.mode == "physical" else _LOW_FREQ)[:n]
        if len(freq) < n:
            freq = np.resize(freq, n)
        rng = np.random.default_rng(self.seed)
        phi1, phi2 = rng.uniform(0, 2 * np.pi, (2, n))
        on = 0.0 if self.mode == "off" else 1.0
        return on * self.c1_fraction * torque_limit, on * self.c2, freq, phi1, phi2


@dataclass(frozen=True)
class SensorModel:
    """Joint encoders: optional quantisation step [rad] and white noise (std) on positions and velocities."""

    position_resolution: float = 0.0
    position_noise: float = 0.0
    velocity_noise: float = 0.0
    seed: int = 0

    def __post_init__(self):
        for name in ("position_resolution", "position_noise", "velocity_noise"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise RobofdiError(f"SensorModel: field {name!r} must be a finite number >= 0, got {v!r}")


@dataclass
class ArmSimulator:
    """A torque-controlled arm in MuJoCo; ``step(u)`` holds u for one control period (zero-order hold)."""

    mjcf: str | Path = "arm6.xml"
    control_dt: float = 1e-3
    ripple: TorqueRipple = field(default_factory=TorqueRipple)
    sensors: SensorModel = field(default_factory=SensorModel)
    payload: float = 0.0

    def __post_init__(self):
        self.path = resolve_asset(self.mjcf)
        try:
            self.model = mujoco.MjModel.from_xml_path(str(self.path))
        except Exception as exc:
            raise RobofdiError(f"mjcf: cannot load {str(self.path)!r} in MuJoCo: {exc}") from None
        m = self.model
        if m.nu != m.njnt or m.nq != m.njnt:
            raise RobofdiError(f"mjcf: {self.path.name} must have one hinge joint and one motor per joint")
        self.data = mujoco.MjData(m)
        self.joint_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(m.njnt)]
        self.n = m.njnt
        self.actuators = list(self.joint_names)
        self.sensor_channels = [f"{j}_pos" for j in self.joint_names] + [f"{j}_vel" for j in self.joint_names]
        self.torque_limit = m.actuator_ctrlrange[:, 1].copy()
        self.joint_range = m.jnt_range.copy()
        substeps = self.control_dt / m.opt.timestep
        if not (self.control_dt > 0 and abs(substeps - round(substeps)) < 1e-9 and round(substeps) >= 1):
            raise RobofdiError(
                f"ArmSimulator: field 'control_dt' must be a positive multiple of the physics step "
                f"{m.opt.timestep}, got {self.control_dt}"
            )
        self.substeps = int(round(substeps))
        if not (np.isfinite(self.payload) and 0.0 <= self.payload <= 20.0):
            raise RobofdiError(f"ArmSimulator: field 'payload' must be in [0, 20] kg, got {self.payload}")
        if self.payload > 0:
            last = m.nbody - 1
            m.body_mass[last] += self.payload
            m.body_ipos[last, 2] -= 0.08 * self.payload / m.body_mass[last]
            mujoco.mj_setConst(m, self.data)
        self._c1, self._c2, self._freq, self._phi1, self._phi2 = self.ripple.coefficients(self.torque_limit)
        self._rng = np.random.default_rng(self.sensors.seed)

    @property
    def physics_dt(self) -> float:
        return float(self.model.opt.timestep)

    def reset(self, q0: np.ndarray, seed: int | None = None) -> np.ndarray:
        """Put the arm at rest at q0 and return the first measurement [q; q̇]."""
        q0 = np.asarray(q0, dtype=float)
        if q0.shape != (self.n,) or not np.all(np.isfinite(q0)):
            raise RobofdiError(f"reset: field 'q0' must be {self.n} finite joint angles, got {q0!r}")
        lo, hi = self.joint_range.T
        if np.any(q0 < lo) or np.any(q0 > hi):
            bad = [self.joint_names[i] for i in np.flatnonzero((q0 < lo) | (q0 > hi))]
            raise RobofdiError(f"reset: q0 is outside the joint range of {bad}")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q0
        mujoco.mj_forward(self.model, self.data)
        self._rng = np.random.default_rng(self.sensors.seed if seed is None else seed)
        return self.measure()

    def ripple_torque(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """δ(q, τ) of the module docstring."""
        arg = self._freq * q
        return self._c1 * np.sin(arg + self._phi1) + tau * self._c2 * np.sin(arg + self._phi2)

    def step(self, u: np.ndarray) -> np.ndarray:
        """Apply torques u (clipped to the motor limits) for one control period; return the measurement."""
        m, d = self.model, self.data
        tau = np.clip(u, -self.torque_limit, self.torque_limit)
        d.ctrl[:] = tau
        for _ in range(self.substeps):
            d.qfrc_applied[:] = -self.ripple_torque(d.qpos, tau)
            mujoco.mj_step(m, d)
        if not np.all(np.isfinite(d.qpos)):
            raise RobofdiError("simulation diverged: non-finite joint positions")
        return self.measure()

    @property
    def state(self) -> np.ndarray:
        """True state [q; q̇]."""
        return np.concatenate([self.data.qpos, self.data.qvel])

    @property
    def time(self) -> float:
        return float(self.data.time)

    def measure(self) -> np.ndarray:
        """Encoder reading [q; q̇] with the configured quantisation and noise."""
        s = self.sensors
        q, v = self.data.qpos.copy(), self.data.qvel.copy()
        if s.position_resolution > 0:
            q = np.round(q / s.position_resolution) * s.position_resolution
        if s.position_noise > 0:
            q += s.position_noise * self._rng.standard_normal(self.n)
        if s.velocity_noise > 0:
            v += s.velocity_noise * self._rng.standard_normal(self.n)
        return np.concatenate([q, v])

    def nominal_model(self, mismatch: ModelMismatch | None = None) -> ManipulatorModel:
        """The belief: a Pinocchio model read from the same MJCF file, with deliberate parameter errors."""
        model = ManipulatorModel(self.path, mismatch or ModelMismatch())
        model.check_joints(self.joint_names)
        return model
