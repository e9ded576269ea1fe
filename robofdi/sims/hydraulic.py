"""The Rosie wheel-actuator rig (truth): MuJoCo mechanics + hydraulics integrated at the physics rate.

Leuschen, Walker & Cavallaro, Sec. 3 and eqs. (5)–(6), with what the catalogue model (eqs. (8)–(10)) lacks::

    spool      ẋ_v = (i − x_v)/τ_v,  i = u·(1 − open_winding); stick–slip when the valve sticks; overspeed trip
    valve      Q = K_f x_v sqrt(2 (p_s − sgn(x_v) p_l)/ρ)                   symmetric 4-way law (digest §3 [ERRATUM] 2)
    supply     p_s = p_s0 − R_s |Q| (sagging supply)
    motor      ṗ_l = 4β_e/v_t (Q − d_m θ̇_m − C_tm p_l − Q_leak),  Q_leak = A_leak sqrt(2 (p_s + p_l)/(2ρ))
    torque     T_g = d_m p_l on the motor shaft; the load pump (own shaft, compliant coupling) T_L = d_m p_L with the
               throttle p_L = ½ρ (d_m θ̇_p / A_th)² sgn θ̇_p; bearing friction under the radial load (MuJoCo)
    sensors    tachometer (shaft speed), load ΔP, pump ΔP, supply pressure: noise + quantisation, seeded streams

One ``step`` = one control period (1 ms) = 10 physics steps of 0.1 ms (the MJCF's timestep).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import mujoco
import numpy as np

from robofdi.errors import RobofdiError
from robofdi.models.hydraulic import PSI, HydraulicParameters, hydraulic_model
from robofdi.seeding import stream

__all__ = ["RigParameters", "RigSensors", "HydraulicRig", "RIG_COMPONENT_KINDS"]

RIG_COMPONENT_KINDS = {"component_open_winding": ["servovalve"], "component_valve_sticking": ["servovalve"],
                       "component_leak": ["motor"]}


@dataclass(frozen=True)
class RigParameters:
    """The rig's true hydraulic parameters (SI). They differ from the catalogue (robofdi.models.hydraulic.CATALOGUE)
    as a real rig does: warmer, aerated oil, worn motor, a supply below its 3000 psi rating that sags with flow."""

    d_m: float = 1.22e-4
    C_tm: float = 1.25e-12
    beta_e: float = 0.85e9
    v_t: float = 2.1e-3
    K_f: float = 4.85e-6
    rho: float = 870.0
    supply_pressure: float = 2900.0 * PSI
    supply_sag: float = 1.5e9                   # Pa per m³/s of valve flow (≈ 28 bar at the HPSS's 114 l/min)
    valve_tau: float = 0.010                    # s
    throttle_area: float = 1.2e-6               # m², the load valve (smaller = more load)
    overspeed: float = 4 * 5 * 2 * np.pi / 60   # rad/s, the rig's limiter: valve current cut above it
    stick_release: float = 0.05                 # a slipping spool sticks again within this share of the band

    def __post_init__(self):
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise RobofdiError(f"RigParameters: field {k!r} must be a finite number > 0, got {v!r}")


@dataclass(frozen=True)
class RigSensors:
    """Noise standard deviation and quantisation step per channel (rad/s, Pa)."""

    speed_noise: float = 0.002
    speed_step: float = 0.0005
    pressure_noise: float = 2.0e3
    pressure_step: float = 316.0                # 16 bit over 3000 psi

    def __post_init__(self):
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise RobofdiError(f"RigSensors: field {k!r} must be a finite number >= 0, got {v!r}")


@dataclass(eq=False)
class HydraulicRig:
    """Simulator protocol for the wheel-actuator rig (``assets/hydraulic_rig.xml``)."""

    params: RigParameters = field(default_factory=RigParameters)
    sensors: RigSensors = field(default_factory=RigSensors)
    mjcf: str = "hydraulic_rig.xml"
    control_dt: float = 0.001

    system = "hydraulic_rig"
    actuators = ["servovalve"]
    sensor_channels = ["shaft_speed", "load_pressure", "pump_pressure", "supply_pressure"]
    components = ["servovalve", "motor"]
    component_kinds = RIG_COMPONENT_KINDS
    state_names = ["shaft_angle", "shaft_speed", "pump_speed", "load_pressure", "spool", "pump_pressure",
                   "supply_pressure", "overspeed_trip"]
    units = {"state": ["rad", "rad/s", "rad/s", "Pa", "1", "Pa", "Pa", "1"], "u": ["1"],
             "y": ["rad/s", "Pa", "Pa", "Pa"]}

    def __post_init__(self):
        from robofdi import ASSETS

        if not isinstance(self.params, RigParameters):
            raise RobofdiError("HydraulicRig: field 'params' must be a RigParameters")
        path = ASSETS / self.mjcf if not str(self.mjcf).startswith("/") else self.mjcf
        self.path = str(path)
        self.model = mujoco.MjModel.from_xml_path(self.path)
        self.data = mujoco.MjData(self.model)
        self.physics_dt = float(self.model.opt.timestep)
        ratio = self.control_dt / self.physics_dt
        if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
            raise RobofdiError(f"HydraulicRig: field 'control_dt' must be a multiple of the physics step "
                               f"{self.physics_dt} s, got {self.control_dt}")
        self._substeps = int(round(ratio))
        self._motor = self.model.joint("motor_shaft").dofadr[0]
        self._pump = self.model.joint("pump_shaft").dofadr[0]
        self._motor_q = self.model.joint("motor_shaft").qposadr[0]
        self.reset()

    # --- Simulator protocol -------------------------------------------------------------------------------------
    def reset(self, initial_state=None, seed=None) -> np.ndarray:
        """At rest, unpressurised (``initial_state`` must be None: the rig always starts at rest)."""
        if initial_state is not None:
            raise RobofdiError("HydraulicRig.reset: field 'initial_state' must be None (the rig starts at rest)")
        mujoco.mj_resetData(self.model, self.data)
        root = stream(seed)
        self._noise = [np.random.default_rng(stream(root, "sensor", c)) for c in self.sensor_channels]
        self.p_l = 0.0
        self.x_v = 0.0
        self.p_L = 0.0
        self.p_s = self.params.supply_pressure
        self.tripped = False
        self.stuck = False
        self.open_winding = 0.0
        self.stiction = 0.0
        self.leak_area = 0.0
        self.u_applied = np.zeros(1)
        mujoco.mj_forward(self.model, self.data)
        return self._measure()

    def saturate(self, u: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(u, dtype=float), -1.0, 1.0)

    def step(self, u: np.ndarray) -> np.ndarray:
        a = np.asarray(u, dtype=float)
        if a.shape != (1,) or not np.isfinite(a[0]):
            raise RobofdiError(f"HydraulicRig: input 'u' must be one finite servovalve command, got {u!r}")
        ua = self.saturate(a)
        self.u_applied = ua
        for _ in range(self._substeps):
            self._physics_step(float(ua[0]))
        return self._measure()

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        """open winding: coil-current loss share (1 = open circuit); valve sticking: stiction band [stroke];
        leak: orifice area to tank [mm²]."""
        if target not in self.component_kinds.get(kind, ()):
            raise RobofdiError(f"HydraulicRig: component fault {kind!r} cannot act on {target!r}; expected "
                               f"{self.component_kinds.get(kind, [])}")
        if kind == "component_open_winding":
            self.open_winding = float(np.clip(value, 0.0, 1.0))
        elif kind == "component_valve_sticking":
            self.stiction = max(float(value), 0.0)
            if self.stiction == 0.0:
                self.stuck = False
        else:
            self.leak_area = max(float(value), 0.0) * 1e-6

    def nominal_model(self, mismatch=None):
        """The catalogue model (eqs. (8)–(10)); ``mismatch`` may be a HydraulicParameters to use instead."""
        params = mismatch if isinstance(mismatch, HydraulicParameters) else HydraulicParameters()
        return hydraulic_model(params)

    # --- truth ----------------------------------------------------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        d = self.data
        return np.array([d.qpos[self._motor_q], d.qvel[self._motor], d.qvel[self._pump], self.p_l, self.x_v, self.p_L,
                         self.p_s, float(self.tripped)])

    @property
    def true_output(self) -> np.ndarray:
        d = self.data
        return np.array([d.qvel[self._motor], self.p_l, self.p_L, self.p_s])

    def leak_flow(self) -> float:
        """[m³/s] to tank through the leak."""
        P = self.params
        return self.leak_area * np.sqrt(max(self.p_s + self.p_l, 0.0) / P.rho)

    def _physics_step(self, u: float) -> None:
        P, d, h = self.params, self.data, self.physics_dt
        omega, omega_p = d.qvel[self._motor], d.qvel[self._pump]
        if omega > P.overspeed:
            self.tripped = True
        elif omega < 0.5 * P.overspeed:
            self.tripped = False
        current = 0.0 if self.tripped else u * (1.0 - self.open_winding)
        target = np.clip(current, -1.0, 1.0)
        if self.stiction > 0.0:
            gap = abs(target - self.x_v)
            if self.stuck and gap > self.stiction:
                self.stuck = False
            elif not self.stuck and gap < P.stick_release * self.stiction:
                self.stuck = True
        if not self.stuck:
            self.x_v += h / P.valve_tau * (target - self.x_v)
        s = 1.0 if self.x_v >= 0 else -1.0
        q_valve = P.K_f * self.x_v * np.sqrt(2.0 * max(self.p_s - s * self.p_l, 0.0) / P.rho)
        self.p_s = P.supply_pressure - P.supply_sag * abs(q_valve)
        flow = q_valve - P.d_m * omega - P.C_tm * self.p_l - self.leak_flow()
        self.p_l += h * 4.0 * P.beta_e / P.v_t * flow
        v_th = P.d_m * omega_p / P.throttle_area
        self.p_L = 0.5 * P.rho * v_th * abs(v_th)
        d.qfrc_applied[self._motor] = P.d_m * self.p_l
        d.qfrc_applied[self._pump] = -P.d_m * self.p_L
        mujoco.mj_step(self.model, self.data)

    def _measure(self) -> np.ndarray:
        S = self.sensors
        y = self.true_output.copy()
        sd = (S.speed_noise, S.pressure_noise, S.pressure_noise, S.pressure_noise)
        q = (S.speed_step, S.pressure_step, S.pressure_step, S.pressure_step)
        for i in range(4):
            v = y[i] + sd[i] * self._noise[i].standard_normal()
            y[i] = np.round(v / q[i]) * q[i] if q[i] > 0 else v
        return y
