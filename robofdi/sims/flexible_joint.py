"""The single-link flexible-joint arm of Saif & Xiong's Example 2 (book ch. 1; Spong's model) in MuJoCo (truth).

``assets/flexible_joint.xml``: rotor and link are coaxial hinges coupled by a torsional spring (a fixed tendon
θ_l − θ_m of stiffness k), the rotor has viscous damping B, the motor drives it with gain K_r, gravity acts on the
link. Its parameters reproduce the chapter's model exactly (checked in tests/test_sliding_mode.py)::

    θ̇_m = ω_m,  ω̇_m = 48.6(θ_l − θ_m) − 1.25 ω_m + 21.6 u,  θ̇_l = ω_l,  ω̇_l = −19.5(θ_l − θ_m) − 3.33 sin θ_l

Sensor: the motor encoder only (y = θ_m), with optional Gaussian noise and quantisation (both 0 by default, as in
the chapter's simulation). One ``step`` = one control period (1 ms) = 10 RK4 physics steps of 0.1 ms.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from robofdi.errors import RobofdiError
from robofdi.models.linear import LinearModel
from robofdi.seeding import stream

__all__ = ["FlexibleJointArm", "flexible_joint_model", "FLEXIBLE_JOINT"]

#: The chapter's matrices (Example 2): ẋ = A x + Φ(x) + B u, Φ = G·(−3.33 sin x3), y = C x.
FLEXIBLE_JOINT = {
    "A": np.array([[0.0, 1.0, 0.0, 0.0], [-48.6, -1.25, 48.6, 0.0], [0.0, 0.0, 0.0, 1.0], [19.5, 0.0, -19.5, 0.0]]),
    "B": np.array([[0.0], [21.6], [0.0], [0.0]]),
    "C": np.array([[1.0, 0.0, 0.0, 0.0]]),
    "G": np.array([[0.0], [0.0], [0.0], [1.0]]),
    "gravity": 3.33,
}


def flexible_joint_model() -> LinearModel:
    """The belief: the chapter's linear part, the gravity term −3.33 sin θ_l as the unknown input through E = G."""
    F = FLEXIBLE_JOINT
    return LinearModel(F["A"], F["B"], F["C"], E=F["G"], state_names=["theta_m", "omega_m", "theta_l", "omega_l"],
                       input_names=["motor"], output_names=["motor_angle"],
                       units={"state": ["rad", "rad/s", "rad", "rad/s"], "u": ["V"], "y": ["rad"]})


@dataclass(eq=False)
class FlexibleJointArm:
    """Simulator protocol for ``assets/flexible_joint.xml``. x0: the default initial state [θ_m, ω_m, θ_l, ω_l]
    (the chapter's [1, 1, 1, 1]); encoder_noise: std [rad]; encoder_step: quantisation [rad] (0: none)."""

    x0: tuple = (1.0, 1.0, 1.0, 1.0)
    encoder_noise: float = 0.0
    encoder_step: float = 0.0
    control_dt: float = 0.001
    mjcf: str = "flexible_joint.xml"

    system = "flexible_joint"
    actuators = ["motor"]
    sensor_channels = ["motor_angle"]
    components = ()
    component_kinds = {}
    state_names = ["theta_m", "omega_m", "theta_l", "omega_l"]
    units = {"state": ["rad", "rad/s", "rad", "rad/s"], "u": ["V"], "y": ["rad"]}

    def __post_init__(self):
        from robofdi import ASSETS

        x0 = np.array(self.x0, dtype=float)
        if x0.shape != (4,) or not np.all(np.isfinite(x0)):
            raise RobofdiError(f"FlexibleJointArm: field 'x0' must be 4 finite values [θ_m, ω_m, θ_l, ω_l], got {self.x0!r}")
        for name in ("encoder_noise", "encoder_step"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise RobofdiError(f"FlexibleJointArm: field {name!r} must be a number >= 0 rad, got {v!r}")
        self.components, self.component_kinds = [], {}
        self.path = str(ASSETS / self.mjcf)
        self.model = mujoco.MjModel.from_xml_path(self.path)
        self.data = mujoco.MjData(self.model)
        self.physics_dt = float(self.model.opt.timestep)
        ratio = self.control_dt / self.physics_dt
        if ratio < 1 or abs(ratio - round(ratio)) > 1e-9:
            raise RobofdiError(f"FlexibleJointArm: field 'control_dt' must be a multiple of the physics step "
                               f"{self.physics_dt} s, got {self.control_dt}")
        self._substeps = int(round(ratio))
        self._qm, self._ql = self.model.joint("motor_joint").qposadr[0], self.model.joint("link_joint").qposadr[0]
        self._vm, self._vl = self.model.joint("motor_joint").dofadr[0], self.model.joint("link_joint").dofadr[0]
        lo, hi = self.model.actuator_ctrlrange[0]
        self._u_lim = (float(lo), float(hi))
        self.reset()

    def reset(self, initial_state=None, seed=None) -> np.ndarray:
        x = np.array(self.x0 if initial_state is None else initial_state, dtype=float)
        if x.shape != (4,) or not np.all(np.isfinite(x)):
            raise RobofdiError(f"FlexibleJointArm.reset: field 'initial_state' must be 4 finite values, got {initial_state!r}")
        mujoco.mj_resetData(self.model, self.data)
        d = self.data
        d.qpos[self._qm], d.qvel[self._vm], d.qpos[self._ql], d.qvel[self._vl] = x
        mujoco.mj_forward(self.model, d)
        self._noise = np.random.default_rng(stream(seed, "sensor", "motor_angle"))
        self.u_applied = np.zeros(1)
        return self._measure()

    def saturate(self, u) -> np.ndarray:
        return np.clip(np.asarray(u, dtype=float), *self._u_lim)

    def step(self, u) -> np.ndarray:
        a = np.asarray(u, dtype=float)
        if a.shape != (1,) or not np.isfinite(a[0]):
            raise RobofdiError(f"FlexibleJointArm: input 'u' must be one finite motor voltage, got {u!r}")
        self.u_applied = self.saturate(a)
        self.data.ctrl[0] = self.u_applied[0]
        for _ in range(self._substeps):
            mujoco.mj_step(self.model, self.data)
        return self._measure()

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        raise RobofdiError(f"FlexibleJointArm: no component faults (got {kind!r} on {target!r}); its faults are "
                           "actuator and sensor faults")

    def nominal_model(self, mismatch=None) -> LinearModel:
        return flexible_joint_model()

    @property
    def state(self) -> np.ndarray:
        d = self.data
        return np.array([d.qpos[self._qm], d.qvel[self._vm], d.qpos[self._ql], d.qvel[self._vl]])

    @property
    def true_output(self) -> np.ndarray:
        return np.array([self.data.qpos[self._qm]])

    def _measure(self) -> np.ndarray:
        y = self.true_output
        if self.encoder_noise > 0:
            y = y + self.encoder_noise * self._noise.standard_normal(1)
        if self.encoder_step > 0:
            y = np.round(y / self.encoder_step) * self.encoder_step
        return y
