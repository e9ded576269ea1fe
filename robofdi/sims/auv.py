"""MuJoCo AUV with explicit hydrodynamics, thruster motors and navigation/telemetry sensors (the truth).

MuJoCo's fluid models are off (``density = viscosity = 0``; they apply no buoyancy and an incomplete added mass —
checked against the analytic sphere). What MuJoCo integrates, exactly for a sphere:

* rigid body + translational added mass (a point mass welded at the centre of buoyancy, whose rigid-body Coriolis
  term equals Fossen's C_A(ν)ν for isotropic translational added mass);
* weight at the CG and buoyancy at the CB (``gravcomp = 1 + B/(m_A g)`` on the added-mass point);

and what this module adds every physics step (``xfrc_applied`` on the added-mass point, i.e. at the CB):

* damping −(D_l + D_q|ν_r|)ν_r on the velocity relative to a constant, irrotational ocean current ν_c (eq. (3)
  with ν_r = ν − R^T ν_c);
* thrusters: a voltage-driven DC motor per thruster (:class:`~robofdi.models.auv.ThrusterParameters`) with the
  propeller speed Ω as state, thrust c|Ω|Ω reduced by the axial inflow (a loss the belief does not model), a
  supply with internal resistance (terminal voltage drops with current), current limit; the driver maps the
  commanded thrust to a voltage with the vendor's steady-state map.

The command u is the thrust demand per thruster [N], saturated to ±``thrust_limit``. Component faults (labels in
the core vocabulary): ``component_thruster_blocking`` (a solid body stalls the rotor: Ω = 0, stall current) and
``component_thruster_flooding`` (electrical dispersion: motor drive × (1 + κ), leakage current κ V / R_leak).
A rotor failure by voltage zeroing (ODIN) is the actuator kind ``actuator_float`` on the thruster.

Sensors (white noise from ``stream(run_seed, "sensor", channel)``, one stream per channel): acoustic-baseline
position x, y; pressure depth; sonar altitude over a flat sea floor at ``floor_depth``; IMU/compass roll, pitch,
yaw; DVL body velocity u, v, w; gyro rates p, q, r; per thruster telemetry: propeller speed, motor current and
(Hall sensor) terminal voltage.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robofdi.checks import check_fields, is_number, is_positive
from robofdi.config import part
from robofdi.errors import RobofdiError, all_finite
from robofdi.models.auv import (
    ODIN_LIKE, ODIN_THRUSTER, AuvModel, AuvModelMismatch, FossenParameters, ThrusterParameters, clip,
    euler_from_rotation, thruster_layout,
)
from robofdi.mjcf import resolve_asset
from robofdi.seeding import stream
from robofdi.sims.noise import ChannelNoise

__all__ = ["AuvSensors", "AuvSimulator", "AuvPlant", "NAVIGATION_CHANNELS", "telemetry_channels"]

#: Navigation channels, in measurement order (then the thruster telemetry).
NAVIGATION_CHANNELS = ("x", "y", "depth", "altitude", "roll", "pitch", "yaw", "u", "v", "w", "p", "q", "r")
_NAV_UNITS = ("m", "m", "m", "m", "rad", "rad", "rad", "m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s")
_TELEMETRY = (("speed", "rad/s"), ("current", "A"), ("voltage", "V"))


def telemetry_channels(thrusters) -> list[str]:
    """``<thruster>_speed`` for every thruster, then ``_current``, then ``_voltage``."""
    return [f"{t}_{kind}" for kind, _ in _TELEMETRY for t in thrusters]


@dataclass(frozen=True)
class AuvSensors:
    """Standard deviations of the white measurement noise (navigation in channel order, then telemetry).

    Typical orders: acoustic baseline cm, pressure depth 1 cm, sonar a few cm, AHRS 0.2° roll/pitch and 0.5°
    heading, DVL 5 mm/s, gyros 2 mrad/s; telemetry 1 rad/s, 0.1 A, 0.05 V.
    """

    position: float = 0.02
    depth: float = 0.01
    altitude: float = 0.03
    roll_pitch: float = 0.0035
    yaw: float = 0.0087
    velocity: float = 0.005
    rate: float = 0.002
    speed: float = 1.0
    current: float = 0.1
    voltage: float = 0.05

    def __post_init__(self):
        for k, v in self.__dict__.items():
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise RobofdiError(f"AuvSensors: field {k!r} must be a finite standard deviation >= 0, got {v!r}")

    def sigma(self, n_thrusters: int) -> np.ndarray:
        nav = [self.position, self.position, self.depth, self.altitude, self.roll_pitch, self.roll_pitch, self.yaw,
               *[self.velocity] * 3, *[self.rate] * 3]
        return np.array(nav + [self.speed] * n_thrusters + [self.current] * n_thrusters + [self.voltage] * n_thrusters)

    @classmethod
    def ideal(cls) -> AuvSensors:
        return cls(*(0.0,) * 10)


def _vector(name: str, v, n: int) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise RobofdiError(f"AuvSimulator: field {name!r} must hold {n} finite values, got {v!r}")
    return a


@dataclass(eq=False)
class AuvSimulator:
    """A thruster-driven AUV in MuJoCo (the truth); ``step(u)`` holds the thrust demand u [N] for ``control_dt``.

    hydro / thruster: the plant's parameters (added mass, damping and buoyancy are written into the MuJoCo model
    from ``hydro``; the rigid body is the file's). current [m/s]: world-frame ocean current. supply_resistance [Ω]:
    internal resistance of the thruster supply. inflow_loss [N·s²/(rad·m)]: thrust loss k |Ω| v_axial.
    floor_depth [m]: depth of the flat sea floor (sonar altitude). thrust_limit [N]: driver limit.
    """

    mjcf: str | Path = "auv.xml"
    control_dt: float = 0.02
    hydro: FossenParameters = ODIN_LIKE
    thruster: ThrusterParameters = ODIN_THRUSTER
    current: tuple = (0.10, 0.05, 0.0)
    sensors: AuvSensors = field(default_factory=AuvSensors)
    supply_resistance: float = 0.02
    inflow_loss: float = 0.03
    leak_resistance: float = 1.5
    floor_depth: float = 20.0
    thrust_limit: float = 40.0
    seed: int = 0

    def __post_init__(self):
        if not isinstance(self.hydro, FossenParameters):
            raise RobofdiError(f"AuvSimulator: field 'hydro' must be a FossenParameters, got {self.hydro!r}")
        if not isinstance(self.thruster, ThrusterParameters):
            raise RobofdiError(f"AuvSimulator: field 'thruster' must be a ThrusterParameters, got {self.thruster!r}")
        if not isinstance(self.sensors, AuvSensors):
            raise RobofdiError(f"AuvSimulator: field 'sensors' must be an AuvSensors, got {self.sensors!r}")
        self._current = _vector("current", self.current, 3)
        for name in ("supply_resistance", "inflow_loss", "leak_resistance", "floor_depth", "thrust_limit"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise RobofdiError(f"AuvSimulator: field {name!r} must be a finite number >= 0, got {v!r}")
        if not 0 < self.thrust_limit <= 1.05 * self.thruster.max_thrust():
            raise RobofdiError(f"AuvSimulator: field 'thrust_limit' must be in (0, {self.thruster.max_thrust():.1f}] N "
                               f"(what the thrusters can deliver), got {self.thrust_limit!r}")
        self.path = resolve_asset(self.mjcf)
        m = self.model = mujoco.MjModel.from_xml_path(str(self.path))
        self.system = self.path.stem
        self._hull = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "hull")
        self._am = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "added_mass")
        if self._hull < 0 or self._am < 0 or m.body_jntnum[self._hull] != 1 or m.jnt_type[m.body_jntadr[self._hull]] != 0:
            raise RobofdiError(f"mjcf: {self.path.name} needs a free-floating body 'hull' with a child body 'added_mass'")
        if m.opt.density != 0 or m.opt.viscosity != 0:
            raise RobofdiError(f"mjcf: {self.path.name} must switch MuJoCo's fluid model off (density=0 viscosity=0); "
                               "this simulator applies the hydrodynamics itself")
        names, P, D = thruster_layout(m)
        self.thrusters, self._pos, self._dir = names, P, D
        self._act = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in names])
        # the plant's hydrostatics and added mass from ``hydro`` (one source of truth for the hydrodynamics)
        m_a = float(self.hydro.added_mass[0])
        if not np.allclose(self.hydro.added_mass[:3], m_a) or any(self.hydro.added_mass[3:]):
            raise RobofdiError("AuvSimulator: field 'hydro.added_mass' must be isotropic translational and zero "
                               "rotational (the point-mass emulation is exact only for that)")
        m.body_mass[self._am] = m_a
        m.body_gravcomp[self._am] = 1.0 + self.hydro.buoyancy / (m_a * -m.opt.gravity[2])
        self._lin = np.asarray(self.hydro.linear_damping, dtype=float)
        self._quad = np.asarray(self.hydro.quadratic_damping, dtype=float)
        self.physics_dt = float(m.opt.timestep)
        ratio = self.control_dt / self.physics_dt
        if not (np.isfinite(ratio) and round(ratio) >= 1 and abs(ratio - round(ratio)) < 1e-9):
            raise RobofdiError(f"AuvSimulator: field 'control_dt' must be a positive multiple of the physics step "
                               f"{self.physics_dt} s, got {self.control_dt!r}")
        self.substeps = int(round(ratio))
        self.data = mujoco.MjData(m)
        n = len(names)
        self.actuators = list(names)
        self.sensor_channels = list(NAVIGATION_CHANNELS) + telemetry_channels(names)
        self.state_names = (["x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz"]
                            + [f"{t}_speed" for t in names])
        self.units = {"state": ["m"] * 3 + ["1"] * 4 + ["m/s"] * 3 + ["rad/s"] * 3 + ["rad/s"] * n,
                      "u": ["N"] * n,
                      "y": list(_NAV_UNITS) + [u for _, u in _TELEMETRY for _ in names]}
        self.component_kinds = {"component_thruster_blocking": list(names), "component_thruster_flooding": list(names)}
        self.components = list(names)
        self._sigma = self.sensors.sigma(n)
        self._noisy = bool(np.any(self._sigma))
        self.reset()

    # ------------------------------------------------------------------------------------------------ protocol
    def nominal_model(self, mismatch: AuvModelMismatch | None = None) -> AuvModel:
        """The belief: thruster geometry from the file, parameters with identification errors (never this plant's)."""
        return AuvModel.from_mjcf(self.path, mismatch)

    def reset(self, initial_state=None, seed=None) -> np.ndarray:
        """At rest at ``initial_state`` = [x, y, depth, roll, pitch, yaw] (m, rad; None: the file's pose), rotors
        stopped, component faults cleared; ``seed`` drives this run's sensor noise. Returns the first measurement."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        if initial_state is not None:
            x = np.asarray(initial_state, dtype=float)
            if x.shape != (6,) or not np.all(np.isfinite(x)):
                raise RobofdiError(f"reset: field 'initial_state' must be [x, y, depth, roll, pitch, yaw] (6 finite "
                                   f"values, m and rad), got {initial_state!r}")
            d.qpos[:3] = [x[0], x[1], -x[2]]
            q = np.empty(4)
            mujoco.mju_euler2Quat(q, x[3:], "XYZ")    # extrinsic x, y, z rotations: R = Rz(ψ) Ry(θ) Rx(φ)
            d.qpos[3:7] = q
        mujoco.mj_forward(m, d)
        n = len(self.thrusters)
        self.speed = np.zeros(n)
        self.motor_current = np.zeros(n)
        self.terminal_voltage = np.zeros(n)
        self.thrust = np.zeros(n)
        self.u_applied = np.zeros(n)
        self._blocked = np.zeros(n, dtype=bool)
        self._flood = np.zeros(n)
        self._noise = ChannelNoise(stream(seed), self.sensor_channels) if self._noisy else None
        return self.measure()

    def saturate(self, u: np.ndarray) -> np.ndarray:
        """What the drivers accept of the thrust demand: clipped to ±thrust_limit [N]."""
        return clip(u, -self.thrust_limit, self.thrust_limit)

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        """``component_thruster_blocking``: rotor stalled while value > 0; ``component_thruster_flooding``: κ = value."""
        if target not in self.thrusters:
            raise RobofdiError(f"apply_component_fault: unknown thruster {target!r}; expected one of {self.thrusters}")
        i = self.thrusters.index(target)
        if kind == "component_thruster_blocking":
            self._blocked[i] = value > 0
            if value > 0:
                self.speed[i] = 0.0
        elif kind == "component_thruster_flooding":
            self._flood[i] = max(0.0, float(value))
        else:
            raise RobofdiError(f"apply_component_fault: kind {kind!r} does not apply to the AUV; expected one of "
                               f"{sorted(self.component_kinds)}")

    def step(self, u: np.ndarray) -> np.ndarray:
        """Hold the thrust demand u [N] for one control period; returns the measurement."""
        u = np.asarray(u, dtype=float)
        if u.shape != (len(self.thrusters),) or not all_finite(u):
            raise RobofdiError(f"step: field 'u' must hold {len(self.thrusters)} finite thrust demands [N] for "
                               f"{self.thrusters}, got {u!r}")
        self.u_applied = self.saturate(u)
        v_drive = self.thruster.voltage_for_thrust(self.u_applied)
        m, d, dt = self.model, self.data, self.physics_dt
        th = self.thruster
        for _ in range(self.substeps):
            R = d.xmat[self._hull].reshape(3, 3)
            v_body = R.T @ d.qvel[:3]
            w_body = d.qvel[3:6]
            nu_r = np.concatenate([v_body - R.T @ self._current, w_body])
            f = -(self._lin + self._quad * np.abs(nu_r)) * nu_r
            d.xfrc_applied[self._am, :3] = R @ f[:3]
            d.xfrc_applied[self._am, 3:] = R @ f[3:]
            self._thrusters(v_drive, v_body - R.T @ self._current, w_body, th, dt)
            d.ctrl[self._act] = self.thrust
            mujoco.mj_step(m, d)
        if not all_finite(d.qvel):
            raise RobofdiError(f"step: the simulation diverged at t = {d.time:.3f} s (non-finite velocity)")
        return self.measure()

    def _thrusters(self, v_drive, v_rel, w_body, th: ThrusterParameters, dt: float) -> None:
        """One explicit step of every motor: terminal voltage after the supply drop, current, speed, thrust."""
        # the supply drop uses the last current (the driver's regulation is slower than this step)
        v_term = v_drive - self.supply_resistance * self.motor_current
        v_motor = v_term * (1.0 + self._flood)
        i = clip((v_motor - th.motor_constant * self.speed) / th.resistance, -th.max_current, th.max_current)
        blocked = self._blocked.any()                 # (the masks below change nothing when no rotor is blocked)
        if blocked:
            i = np.where(self._blocked, clip(v_term / th.resistance, -th.max_current, th.max_current), i)
        w = self.speed + dt * (th.motor_constant * i - th.torque_coefficient * np.abs(self.speed) * self.speed) / th.inertia
        self.speed = np.where(self._blocked, 0.0, w) if blocked else w
        w0, w1, w2 = w_body.tolist()
        P0, P1, P2 = self._pos.T                      # ω × r per thruster, written out as np.cross computes it
        swirl = np.empty_like(self._pos)
        swirl[:, 0], swirl[:, 1], swirl[:, 2] = w1 * P2 - w2 * P1, w2 * P0 - w0 * P2, w0 * P1 - w1 * P0
        axial = np.einsum("ij,ij->i", self._dir, v_rel + swirl)
        self.thrust = th.thrust(self.speed) - self.inflow_loss * np.abs(self.speed) * axial
        leak = np.where(self._flood > 0, self._flood * v_term / self.leak_resistance, 0.0)
        self.motor_current, self.terminal_voltage = i + leak, v_term

    # ------------------------------------------------------------------------------------------------ truth
    @property
    def state(self) -> np.ndarray:
        """[x, y, z (world, z up), quaternion, world linear velocity, body angular velocity, propeller speeds]."""
        return np.concatenate([self.data.qpos[:7], self.data.qvel[:6], self.speed])

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def true_output(self) -> np.ndarray:
        d = self.data
        R = d.xmat[self._hull].reshape(3, 3)
        depth = -d.qpos[2]
        nav = np.concatenate([d.qpos[:2], [depth, self.floor_depth - depth], euler_from_rotation(R),
                              R.T @ d.qvel[:3], d.qvel[3:6]])
        return np.concatenate([nav, self.speed, self.motor_current, self.terminal_voltage])

    def measure(self) -> np.ndarray:
        y = self.true_output
        if self._noise is not None:
            y = y + self._sigma * self._noise.draw()
            y[6] = (y[6] + np.pi) % (2 * np.pi) - np.pi
        return y


@dataclass(frozen=True)
class AuvPlant:
    """The AUV simulator's configuration (the truth) as the AUV's configurations hold it (:mod:`robofdi.config`):
    mjcf, control_dt [s], current [m/s], sensors, thrust_limit [N], floor_depth [m], with :class:`AuvSimulator`'s
    defaults (declared there). :meth:`simulator` builds the plant; it validates every field."""

    mjcf: str = AuvSimulator.mjcf
    control_dt: float = AuvSimulator.control_dt
    current: tuple = AuvSimulator.current
    sensors: AuvSensors = part(AuvSensors)
    thrust_limit: float = AuvSimulator.thrust_limit
    floor_depth: float = AuvSimulator.floor_depth

    def __post_init__(self):
        if not isinstance(self.current, str):
            object.__setattr__(self, "current", tuple(self.current))
        check_fields("AuvPlant", self, [
            ("mjcf", isinstance(self.mjcf, (str, Path)) and str(self.mjcf).strip(), "an MJCF file name or path"),
            ("control_dt", is_positive(self.control_dt, 1.0), "a period in (0, 1] s"),
            ("current", isinstance(self.current, tuple) and len(self.current) == 3
             and all(is_number(c) for c in self.current), "three finite velocities [m/s] (world x, y, z)"),
            ("sensors", isinstance(self.sensors, AuvSensors), "an AuvSensors"),
            ("thrust_limit", is_positive(self.thrust_limit), "a force > 0 N"),
            ("floor_depth", is_positive(self.floor_depth), "a depth > 0 m"),
        ])

    def simulator(self, seed: int = 0) -> AuvSimulator:
        return AuvSimulator(self.mjcf, self.control_dt, current=self.current, sensors=self.sensors,
                            thrust_limit=self.thrust_limit, floor_depth=self.floor_depth, seed=seed)
