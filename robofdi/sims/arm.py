"""MuJoCo arm (any MJCF arm): the truth the diagnosers never see.

The file is compiled with ``mujoco.MjSpec.from_file`` (``<include>``, ``<default>``, degrees and meshes work);
the physics step is the file's ``<option timestep>``. The arm joints are hinge/slide joints each driven by one
motor-type actuator through a joint transmission, in any file order: u[i] is the torque [N·m] (force [N] for
a slide joint) on arm joint i, written as ``ctrl = u[i] / gear`` to that joint's actuator. Other joints (a
gripper) are simulated but not part of the arm: their actuators hold the ctrl of the keyframe "home" (or 0).

Besides what the MJCF holds (armature, viscous ``damping``, Coulomb ``frictionloss``), the plant carries effects
outside every diagnoser's model class (the nominal model has rigid body + armature + viscous damping only):

* motor torque ripple with harmonics and a transmission term (:class:`TorqueRipple`), richer than the
  three-term model of eq. (50) of Caccavale & Villani that the adaptive scheme assumes;
* a Stribeck breakaway term on top of MuJoCo's Coulomb friction (:class:`StribeckFriction`);
* industrial sensors: 20-bit absolute encoders and a drive's velocity estimate (:class:`SensorModel`).

Both torque terms enter as δ of eq. (3) (M q̈ + n = τ − δ) through ``qfrc_applied = −δ`` every physics step.

Per-robot settings, read from the MJCF's ``<custom>`` section when present::

    <custom>
      <numeric name="robofdi_gear_ratio" data="150 150 120 80 80 60"/>  <!-- one per arm joint; default 100 -->
      <text name="robofdi_payload_body" data="link6"/>          <!-- default: the body of the last arm joint -->
      <numeric name="robofdi_payload_offset" data="0 0 -0.10"/> <!-- payload point in that body's frame [m]; default 0 -->
    </custom>

The gear ratios set the ripple's spatial frequencies; the payload body and offset say where ``payload`` and the
"payload" component fault put their mass.

Randomness: the robot's own (ripple phases) from ``stream(seed, "plant", "ripple")`` with the simulator's
``seed``; each run's sensor noise from ``stream(run_seed, "sensor", channel)``, one stream per channel.
"""
from __future__ import annotations


from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robofdi.checks import check_fields, is_number
from robofdi.config import part
from robofdi.errors import RobofdiError, all_finite
from robofdi.mjcf import CompiledArm, compile_arm, gear_ratio, payload_point
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, sensor_channel_names
from robofdi.protocols import returns_state
from robofdi.seeding import stream
from robofdi.sims import capi, kernels
from robofdi.sims.noise import ChannelNoise

__all__ = ["TorqueRipple", "StribeckFriction", "SensorModel", "ArmSettings", "ArmSimulator", "ArmPlant", "add_point_mass",
           "arm_settings", "full_mass_matrix"]

_RIPPLE_MODES = ("physical", "low", "off")


def _check_fraction(owner: str, name: str, v, upper: float = np.inf) -> None:
    if not (is_number(v) and 0 <= v <= upper):
        raise RobofdiError(f"{owner}: field {name!r} must be a finite number in [0, {upper}], got {v!r}")


# ---------------------------------------------------------------------------------------------------------------
# Plant effects (configuration)
# ---------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TorqueRipple:
    """Motor torque ripple δ_i(q, τ) [N·m] of each arm joint, with G_i the gear ratio and N_i = k G_i the
    fundamental (k = ``cycles_per_revolution`` ripple periods per motor revolution)::

        δ_i = Σ_h a_h τmax_i sin(h N_i q_i + φ_h,i)            h = 1, 2, 3 (fundamental, 2nd, 3rd harmonic)
            + c_load τ_i sin(N_i q_i + ψ_i)                     (load-dependent ripple, τ = applied torque)
            + a_t τmax_i sin(2 G_i q_i + φ_t,i)                  (transmission: 2 cycles per motor revolution)

    Permanent-magnet drives show a ripple of about 1–5 % of rated torque at multiples of 6 per electrical
    period (Jahns & Soong 1996, IEEE TIE 43(2)); strain-wave gears add a torque component at twice the
    wave-generator (motor) frequency (Tuttle & Seering 1996, IEEE TRA 12(2)). The adaptive scheme models only
    c0 + c1 sin(N q + φ1) + τ c2 sin(N q + φ2) per joint, so the harmonics and the transmission term stay outside
    its model class. Amplitudes: fractions of the joint's torque limit τmax (dimensionless).

    mode: "physical" (the frequencies above), "low" (every frequency scaled by ``low_frequency`` / (k max G), so
    the stiffest joint's fundamental is ``low_frequency`` rad⁻¹: slow and well conditioned) or "off".
    Phases come from the simulator's ``seed``.
    """

    mode: str = "physical"
    fundamental: float = 0.01
    harmonics: tuple[float, float] = (0.004, 0.002)
    load: float = 0.02
    transmission: float = 0.005
    cycles_per_revolution: float = 6.0
    low_frequency: float = 40.0

    def __post_init__(self):
        if self.mode not in _RIPPLE_MODES:
            raise RobofdiError(f"TorqueRipple: field 'mode' must be 'physical', 'low' or 'off', got {self.mode!r}")
        for name in ("fundamental", "load", "transmission"):
            _check_fraction("TorqueRipple", name, getattr(self, name), 0.5)
        h = self.harmonics
        if not (isinstance(h, (tuple, list)) and len(h) == 2):
            raise RobofdiError(f"TorqueRipple: field 'harmonics' must be two amplitudes (2nd, 3rd), got {h!r}")
        for v in h:
            _check_fraction("TorqueRipple", "harmonics", v, 0.5)
        for name in ("cycles_per_revolution", "low_frequency"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"TorqueRipple: field {name!r} must be a finite number > 0, got {v!r}")

    def terms(self, torque_limit: np.ndarray, gear_ratio: np.ndarray, seed) -> tuple[np.ndarray, ...]:
        """Pure design computation: (amplitude [N·m], frequency [rad⁻¹], phase [rad]) of the position-dependent
        terms, each (4, n), and (c_load, frequency, phase) of the load-dependent term, each (n,)."""
        G = np.asarray(gear_ratio, dtype=float)
        N = self.cycles_per_revolution * G
        freq = np.stack([N, 2 * N, 3 * N, 2 * G])
        load_freq = N.copy()
        if self.mode == "low":
            scale = self.low_frequency / np.max(N)
            freq, load_freq = freq * scale, load_freq * scale
        phases = np.random.default_rng(stream(seed, "plant", "ripple")).uniform(0.0, 2 * np.pi, (5, len(G)))
        on = 0.0 if self.mode == "off" else 1.0
        fractions = np.array([self.fundamental, *self.harmonics, self.transmission])[:, None]
        amp = on * fractions * np.asarray(torque_limit, dtype=float)
        return amp, freq, phases[:4], np.full(len(G), on * self.load), load_freq, phases[4]


@dataclass(frozen=True)
class StribeckFriction:
    """Breakaway (Stribeck) friction on top of MuJoCo's Coulomb ``frictionloss`` F_c and viscous ``damping``::

        τ_s,i(q̇) = −(F_s − F_c)_i exp(−(q̇_i / v_s)²) tanh(q̇_i / ε_i),    (F_s − F_c)_i = breakaway · F_c,i

    (Armstrong-Hélouvry, Dupont & Canudas de Wit 1994, Automatica 30(7): static friction typically 10–50 % above
    Coulomb friction, Stribeck velocities 1e-3–1e-1 in joint units). ``breakaway`` is dimensionless;
    ``velocity`` v_s [rad/s or m/s]; ``smoothing`` the smallest ε [rad/s or m/s]. Because the term is applied
    explicitly (qfrc_applied, once per physics step), ε_i is raised where needed so that its slope
    (F_s − F_c)/ε stays a quarter of the explicit-Euler limit: ε_i ≥ 4 Δt (F_s − F_c)_i / M_ii(q_ref).
    """

    breakaway: float = 0.3
    velocity: float = 0.05
    smoothing: float = 1e-3

    def __post_init__(self):
        _check_fraction("StribeckFriction", "breakaway", self.breakaway, 10.0)
        for name in ("velocity", "smoothing"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"StribeckFriction: field {name!r} must be a finite number > 0, got {v!r}")

    def smoothing_velocity(self, excess: np.ndarray, inertia: np.ndarray, dt: float) -> np.ndarray:
        """ε_i [rad/s]: ``smoothing``, raised to keep the explicit term stable (pure design computation)."""
        return np.maximum(self.smoothing, 4.0 * dt * np.asarray(excess) / np.asarray(inertia))

    @staticmethod
    def torque(v: np.ndarray, excess: np.ndarray, velocity: float, eps: np.ndarray) -> np.ndarray:
        """τ_s(q̇) of the class docstring [N·m] (opposes the motion)."""
        return -excess * np.exp(-(v / velocity) ** 2) * np.tanh(v / eps)


@dataclass(frozen=True)
class SensorModel:
    """Joint sensors of an industrial drive.

    Positions: an absolute encoder of ``position_resolution`` [rad] (default 2π/2²⁰, a 20-bit single-turn encoder,
    the class of joint-side encoders of current collaborative arms; slide joints: ``linear_resolution`` [m],
    default 1 µm, a common linear-scale resolution), plus optional white noise ``position_noise`` [rad]
    (``linear_position_noise`` [m]).

    Velocities: the drive's estimate, modelled as the true velocity plus white noise ``velocity_noise``
    [rad/s] (``linear_velocity_noise`` [m/s]). The default 1e-3 rad/s is what a drive gets from this encoder:
    a backward difference of a 2π/2²⁰-quantised position at 1 kHz has a quantisation noise of
    std q·√2/(√12·T) ≈ 2.5e-3 rad/s, which the drive's velocity filter roughly halves; the same argument gives
    2e-4 m/s for a 1 µm scale. The noise is white (no filter lag): the diagnosers' sampling is left exact.

    ``SensorModel.ideal()`` is the noise-free, unquantised sensor.
    """

    position_resolution: float = 2 * np.pi / 2**20
    position_noise: float = 0.0
    velocity_noise: float = 1e-3
    linear_resolution: float = 1e-6
    linear_position_noise: float = 0.0
    linear_velocity_noise: float = 2e-4

    def __post_init__(self):
        for name in ("position_resolution", "position_noise", "velocity_noise", "linear_resolution",
                     "linear_position_noise", "linear_velocity_noise"):
            _check_fraction("SensorModel", name, getattr(self, name))

    @classmethod
    def ideal(cls) -> SensorModel:
        """Noise-free, unquantised sensors."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


# ---------------------------------------------------------------------------------------------------------------
# Per-robot settings and the mass function
# ---------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ArmSettings:
    """Per-robot settings from the MJCF's <custom> section (module docstring)."""

    gear_ratio: np.ndarray          # (n,) dimensionless
    payload_body: str
    payload_offset: np.ndarray      # (3,) [m] in the payload body's frame


def arm_settings(arm: CompiledArm) -> ArmSettings:
    """Read robofdi_gear_ratio, robofdi_payload_body, robofdi_payload_offset from ``arm``'s <custom> (defaults:
    gear ratio 100 per joint, the body of the last arm joint, offset 0)."""
    body, offset = payload_point(arm)
    gear = gear_ratio(arm)
    return ArmSettings(gear, body, offset)


def add_point_mass(mass: float, com: np.ndarray, quat: np.ndarray, inertia: np.ndarray, added: float,
                   point: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """A body's inertial parameters after adding a point mass ``added`` [kg] at ``point`` [m] (body frame):
    (mass [kg], centre of mass [m], principal-axes quaternion, principal inertia [kg·m²]) in MuJoCo's convention
    (body_mass, body_ipos, body_iquat, body_inertia). Parallel-axis theorem, re-diagonalised with eigh."""
    com, point = np.asarray(com, dtype=float), np.asarray(point, dtype=float)
    total = mass + added
    if added == 0:
        return float(mass), com.copy(), np.asarray(quat, dtype=float).copy(), np.asarray(inertia, dtype=float).copy()
    new_com = (mass * com + added * point) / total
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, dtype=float))
    R = R.reshape(3, 3)

    def shift(m, r):                               # inertia of a point mass m at offset r
        return m * (r @ r * np.eye(3) - np.outer(r, r))

    I = R @ np.diag(inertia) @ R.T + shift(mass, com - new_com) + shift(added, point - new_com)
    values, vectors = np.linalg.eigh(0.5 * (I + I.T))
    if np.linalg.det(vectors) < 0:
        vectors[:, 0] = -vectors[:, 0]
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, vectors.ravel())
    return float(total), new_com, q, np.maximum(values, 0.0)


def full_mass_matrix(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """MuJoCo's dense joint-space inertia matrix [kg·m²] of the last mj_forward (armature included)."""
    M = np.zeros((m.nv, m.nv))
    try:
        mujoco.mj_fullM(m, d, M)          # MuJoCo >= 4.0
    except TypeError:
        mujoco.mj_fullM(m, M, d.qM)       # older signature (spec ch. 3, §6.3)
    return M


# ---------------------------------------------------------------------------------------------------------------
# The simulator
# ---------------------------------------------------------------------------------------------------------------
def _as_slice(index: np.ndarray):
    """``index`` as a slice when it is a contiguous ascending run (a view, no copy), else the index array."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index


@dataclass(frozen=True)
class ArmPlant:
    """The arm simulator's configuration (the truth), one part of every arm configuration (:mod:`robofdi.config`).

    robot: MJCF file (a shipped asset name or a path); joints / torque_motors / drive_inertia [s²] / payload [kg] /
    sensors: as :class:`ArmSimulator`; ripple_mode: :class:`TorqueRipple`'s mode. :meth:`simulator` builds the
    plant for one robot instance (``seed``: its ripple phases) at a control period."""

    robot: str = "arm6.xml"
    joints: tuple | None = None
    torque_motors: bool = False
    drive_inertia: float = 0.0
    ripple_mode: str = "physical"
    sensors: SensorModel = part(SensorModel)
    payload: float = 0.0

    def __post_init__(self):
        if isinstance(self.robot, Path):
            object.__setattr__(self, "robot", str(self.robot))
        if self.joints is not None and not isinstance(self.joints, str):
            object.__setattr__(self, "joints", tuple(self.joints))
        check_fields("ArmPlant", self, [
            ("robot", isinstance(self.robot, str) and self.robot.strip(), "an MJCF file name or path"),
            ("joints", self.joints is None or (isinstance(self.joints, tuple) and self.joints
                                               and all(isinstance(j, str) for j in self.joints)),
             "a non-empty list of joint names or none"),
            ("torque_motors", isinstance(self.torque_motors, bool), "true or false"),
            ("drive_inertia", is_number(self.drive_inertia) and self.drive_inertia >= 0, "a number >= 0 [s²]"),
            ("ripple_mode", self.ripple_mode in _RIPPLE_MODES, f"one of {list(_RIPPLE_MODES)}"),
            ("sensors", isinstance(self.sensors, SensorModel), "a SensorModel"),
            ("payload", is_number(self.payload) and self.payload >= 0, "a finite mass >= 0 kg"),
        ])

    def simulator(self, seed: int = 0, control_dt: float | None = None) -> ArmSimulator:
        """The plant of robot instance ``seed`` (ripple phases) at ``control_dt`` [s] (None: ≈ 1 ms)."""
        return ArmSimulator(self.robot, control_dt=control_dt, ripple=TorqueRipple(self.ripple_mode),
                            sensors=self.sensors, payload=self.payload, joints=self.joints,
                            torque_motors=self.torque_motors, drive_inertia=self.drive_inertia, seed=seed)


@dataclass(eq=False)
class ArmSimulator:
    """A torque-controlled arm in MuJoCo (the truth); ``step(u)`` holds u for one control period.

    mjcf: a shipped asset name or a path. control_dt [s]: a positive integer multiple of the file's physics
    step; None = the multiple closest to 1 ms. ripple, friction, sensors: the plant effects of the module
    docstring. payload [kg]: a constant point mass at the payload point. joints: the arm joints (None = every
    hinge/slide joint driven by a motor-type actuator; with torque_motors, by any joint actuator, so pass
    ``joints`` to leave a servo-driven gripper out). torque_motors: convert the arm joints' servos into motors
    (torque limit: the servo's forcerange, else the joint's actuatorfrcrange). drive_inertia [s²]: an armature
    floor per unit torque limit for files without rotor inertia (:func:`robofdi.mjcf.compile_arm`; the nominal
    model gets the same). seed: the robot's own
    randomness (ripple phases); each run's sensor noise is seeded in ``reset``.
    """

    mjcf: str | Path = "arm6.xml"
    control_dt: float | None = None
    ripple: TorqueRipple = field(default_factory=TorqueRipple)
    sensors: SensorModel = field(default_factory=SensorModel)
    payload: float = 0.0
    friction: StribeckFriction = field(default_factory=StribeckFriction)
    joints: Sequence[str] | None = None
    torque_motors: bool = False
    drive_inertia: float = 0.0
    seed: int = 0

    def __post_init__(self):
        for name, cls in (("ripple", TorqueRipple), ("sensors", SensorModel), ("friction", StribeckFriction)):
            if not isinstance(getattr(self, name), cls):
                raise RobofdiError(f"ArmSimulator: field {name!r} must be a {cls.__name__}, got {getattr(self, name)!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise RobofdiError(f"ArmSimulator: field 'seed' must be an integer >= 0, got {self.seed!r}")
        if not (is_number(self.payload) and self.payload >= 0):
            raise RobofdiError(f"ArmSimulator: field 'payload' must be a finite mass >= 0 kg, got {self.payload!r}")
        arm = compile_arm(self.mjcf, self.joints, self.torque_motors, self.drive_inertia)
        m = self.model = arm.model
        self.path, self.system, self.drives = arm.path, arm.system, arm.drives
        self.joint_names = arm.joint_names
        self.n = n = len(self.drives)
        self.settings = arm_settings(arm)

        # names and units (the Simulator protocol)
        self.actuators = list(self.joint_names)
        self.sensor_channels = sensor_channel_names(self.joint_names)
        self.state_names = [f"{j}_q" for j in self.joint_names] + [f"{j}_qd" for j in self.joint_names]
        slide = np.array([d.kind == "slide" for d in self.drives], dtype=bool)
        pos_units = ["m" if s else "rad" for s in slide]
        vel_units = ["m/s" if s else "rad/s" for s in slide]
        self.units = {"state": pos_units + vel_units, "u": ["N" if s else "N·m" for s in slide],
                      "y": pos_units + vel_units}

        # drives, ranges, rates
        self._qadr = np.array([d.qpos for d in self.drives])
        self._dofs = np.array([d.dof for d in self.drives])
        self._act = np.array([d.actuator_id for d in self.drives])
        self._gain = np.array([d.gain for d in self.drives])
        # hot-path views: slices where the arm's addresses are contiguous (the usual file), else index arrays
        self._q_at, self._v_at, self._ctrl_at = (_as_slice(a) for a in (self._qadr, self._dofs, self._act))
        self._inv_gain = None if np.all(self._gain == 1.0) else 1.0 / self._gain
        self.torque_range = arm.torque_range
        self._torque_lo, self._torque_hi = self.torque_range[:, 0].copy(), self.torque_range[:, 1].copy()
        self.torque_limit = arm.torque_limit
        ids = [d.joint_id for d in self.drives]
        self.joint_range = np.where(m.jnt_limited[ids, None].astype(bool), m.jnt_range[ids], [-np.inf, np.inf])
        self.physics_dt = float(m.opt.timestep)
        self.control_dt, self.substeps = self._control_period(self.control_dt)

        # home pose, non-arm actuators
        self._home_key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
        arm_acts = set(self._act.tolist())
        self._other_act = np.array([a for a in range(m.nu) if a not in arm_acts], dtype=int)
        self.data = mujoco.MjData(m)
        self._scratch = mujoco.MjData(m)
        # the C step the compiled control period calls (0: step through the bindings, the same C function)
        self._mj_step, self._model_at, self._data_at = capi.MJ_STEP, m._address, self.data._address
        self._sensors_in_tick = type(self).measure is ArmSimulator.measure     # not overridden: read in the kernel
        # the hot path's views of the data (valid as long as self.data lives) and its preallocated buffers
        d = self.data
        self._qpos, self._qvel, self._qfrc, self._ctrl = d.qpos, d.qvel, d.qfrc_applied, d.ctrl
        self._inv_gain_k = np.zeros(0) if self._inv_gain is None else np.ascontiguousarray(self._inv_gain)
        self._empty = np.zeros(0)

        # components: friction per joint, mass per link body and the payload point
        self._frictionloss0 = m.dof_frictionloss[self._dofs].copy()
        self._damping0 = m.dof_damping[self._dofs].copy()
        links = list(dict.fromkeys(d.body for d in self.drives))
        self._mass_points = {b: (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b), None) for b in links}
        payload_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, self.settings.payload_body)
        self._mass_points["payload"] = (payload_id, self.settings.payload_offset)
        self.component_kinds = {"component_friction": list(self.joint_names), "component_mass": links + ["payload"]}
        self.components = list(dict.fromkeys(self.joint_names + links + ["payload"]))
        if self.payload > 0:
            self._set_body(payload_id, [(self.payload, self.settings.payload_offset)])
            mujoco.mj_setConst(m, self._scratch)
        self._body0 = {b: (float(m.body_mass[b]), m.body_ipos[b].copy(), m.body_iquat[b].copy(), m.body_inertia[b].copy(),
                           int(m.body_sameframe[b])) for b, _ in self._mass_points.values()}
        self._faults: dict[tuple[str, str], float] = {}

        # plant effects
        amp, freq, phase, c_load, load_freq, load_phase = self.ripple.terms(
            self.torque_limit, self.settings.gear_ratio, self.seed)
        self._ripple_on = bool(np.any(amp) or np.any(c_load))
        # the terms fused: one sine over every (harmonic, joint), the load-dependent block last; the kernel sums
        # amp[k, i] s[k·n + i] over k, the NumPy form (ripple_torque) takes A s with A[i, k·n + i] = amp[k, i]
        used = np.any(amp != 0.0, axis=1)                 # terms switched off cost nothing
        amp, freq, phase = amp[used], freq[used], phase[used]
        k = amp.shape[0]
        self._r_index = np.tile(np.arange(n), k + 1)
        self._r_F = np.concatenate([freq.ravel(), load_freq])
        self._r_P = np.concatenate([phase.ravel(), load_phase])
        self._r_A = np.zeros((n, k * n))
        self._r_A[np.tile(np.arange(n), k), np.arange(k * n)] = amp.ravel()
        self._r_split = k * n
        ripple = {"amp": amp.ravel(), "freq": self._r_F, "phase": self._r_P, "load": c_load, "sines": np.zeros(self._r_F.size)}
        d = self._scratch
        mujoco.mj_resetData(m, d)
        mujoco.mj_forward(m, d)
        self._inertia_ref = np.diag(full_mass_matrix(m, d))[self._dofs].copy()

        s = self.sensors
        self._resolution = np.where(slide, s.linear_resolution, s.position_resolution)
        self._quantised = bool(np.all(self._resolution > 0))
        self._any_quantised = bool(np.any(self._resolution > 0))
        self._inv_resolution = 1.0 / np.where(self._resolution > 0, self._resolution, 1.0)
        self._pos_noise = np.where(slide, s.linear_position_noise, s.position_noise)
        self._vel_noise = np.where(slide, s.linear_velocity_noise, s.velocity_noise)

        # one control period's parameters packed for the compiled tick; the attributes below are views of them
        self._tick_f, self._tick_fo, f = kernels.pack(kernels.TICK_FLOATS, {
            "lo": self._torque_lo, "hi": self._torque_hi, "inv_gain": self._inv_gain_k, **ripple,
            "excess": np.zeros(n), "inv_eps": np.zeros(n), "inv_v": 1.0 / self.friction.velocity,
            "other_ctrl": np.zeros(self._other_act.size), "resolution": self._resolution,
            "inv_resolution": self._inv_resolution, "pos_noise": self._pos_noise, "vel_noise": self._vel_noise}, float)
        self._tick_i, self._tick_io, i = kernels.pack(kernels.TICK_INTS, {
            "qadr": self._qadr, "dofs": self._dofs, "act": self._act, "index": self._r_index,
            "other_act": self._other_act}, np.int64)
        self._torque_lo, self._torque_hi, self._inv_gain_k = f["lo"], f["hi"], f["inv_gain"]
        self._r_amp, self._r_F, self._r_P, self._r_load, self._r_s = (f[k] for k in ("amp", "freq", "phase", "load", "sines"))
        self._stribeck, self._stribeck_inv_eps, self._other_ctrl = f["excess"], f["inv_eps"], f["other_ctrl"]
        self._resolution, self._inv_resolution, self._pos_noise, self._vel_noise = (
            f[k] for k in ("resolution", "inv_resolution", "pos_noise", "vel_noise"))
        self._qadr, self._dofs, self._act, self._r_index, self._other_act = (
            i[k] for k in ("qadr", "dofs", "act", "index", "other_act"))
        self._set_friction(np.zeros(n))
        self.reset()

    def __reduce_ex__(self, protocol):
        # the compiled control period steps this simulator's MjData through its address and its views: a copy or
        # an unpickled simulator would step another process's (or a freed) model
        raise RobofdiError("ArmSimulator: cannot be copied or pickled (it steps its own MuJoCo data through its "
                           "address); build another one from the same fields, e.g. ArmPlant.simulator(seed)")

    # ----------------------------------------------------------------------------------------- configuration
    def _control_period(self, control_dt) -> tuple[float, int]:
        dt = self.physics_dt
        if control_dt is None:
            k = max(1, int(round(1e-3 / dt)))
            return k * dt, k
        ok = is_number(control_dt) and control_dt > 0
        ratio = control_dt / dt if ok else np.nan
        if not (ok and round(ratio) >= 1 and abs(ratio - round(ratio)) <= 1e-9 * max(1.0, ratio)):
            raise RobofdiError(f"ArmSimulator: field 'control_dt' must be a positive integer multiple of the physics "
                               f"step {dt} s of {self.path.name}, got {control_dt!r}")
        return float(control_dt), int(round(ratio))

    def _set_body(self, body: int, points: list[tuple[float, np.ndarray]]) -> None:
        """Add point masses (mass [kg], point [m] in the body frame) to the body's current parameters."""
        m = self.model
        mass, com, quat, inertia = (float(m.body_mass[body]), m.body_ipos[body].copy(), m.body_iquat[body].copy(),
                                    m.body_inertia[body].copy())
        for added, point in points:
            mass, com, quat, inertia = add_point_mass(mass, com, quat, inertia, added, point)
        m.body_mass[body], m.body_ipos[body], m.body_iquat[body], m.body_inertia[body] = mass, com, quat, inertia
        m.body_sameframe[body] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE    # the compiler's shortcut no longer holds

    def _set_friction(self, rise: np.ndarray) -> None:
        m = self.model
        scale = 1.0 + rise
        m.dof_frictionloss[self._dofs] = np.where(rise == 0, self._frictionloss0, self._frictionloss0 * scale)
        m.dof_damping[self._dofs] = np.where(rise == 0, self._damping0, self._damping0 * scale)
        self._stribeck[:] = self.friction.breakaway * m.dof_frictionloss[self._dofs]     # views of the tick's
        self._stribeck_eps = self.friction.smoothing_velocity(self._stribeck, self._inertia_ref, self.physics_dt)
        self._stribeck_inv_eps[:] = 1.0 / self._stribeck_eps                             # parameters: in place
        self._stribeck_on = bool(np.any(self._stribeck > 0))
        self._stribeck_inv_v = 1.0 / self.friction.velocity

    # ----------------------------------------------------------------------------------------- protocol
    @property
    def state(self) -> np.ndarray:
        """True state [q; q̇] of the arm joints [rad, rad/s (m, m/s for slide joints)]."""
        return np.concatenate((self._qpos[self._q_at], self._qvel[self._v_at]))

    @property
    @returns_state
    def true_output(self) -> np.ndarray:
        """What ideal encoders would read: [q; q̇], the state itself."""
        return self.state

    @property
    def time(self) -> float:
        return float(self.data.time)

    def default_positions(self) -> np.ndarray:
        """Arm joint positions of ``reset(None)``: keyframe "home" if the file has one, else qpos0 clipped into
        the joint ranges."""
        if self._home_key >= 0:
            return self.model.key_qpos[self._home_key][self._qadr].copy()
        lo, hi = self.joint_range.T
        return np.clip(self.model.qpos0[self._qadr], lo, hi)

    def reset(self, initial_state=None, seed: np.random.SeedSequence | int | None = None) -> np.ndarray:
        """Start a run with the arm at rest at ``initial_state`` (n joint positions [rad or m]; or a full state
        [q; q̇] of 2n entries; None = :meth:`default_positions`), component faults cleared. ``seed`` (int,
        SeedSequence, None = fresh entropy) drives this run's sensor noise. Returns the first measurement."""
        n = self.n
        if initial_state is None:
            q, v = self.default_positions(), np.zeros(n)
        else:
            x = np.asarray(initial_state, dtype=float)
            if x.shape not in ((n,), (2 * n,)) or not np.all(np.isfinite(x)):
                raise RobofdiError(f"reset: field 'initial_state' must be {n} finite joint positions (or {2 * n} "
                                   f"entries [q; q̇]) for {self.joint_names}, got shape {x.shape}: {x.tolist()}")
            q, v = (x, np.zeros(n)) if x.shape == (n,) else (x[:n], x[n:])
            lo, hi = self.joint_range.T
            out = (q < lo) | (q > hi)
            if np.any(out):
                bad = {self.joint_names[i]: (float(q[i]), [float(lo[i]), float(hi[i])]) for i in np.flatnonzero(out)}
                raise RobofdiError(f"reset: initial_state is outside the joint range of {bad} (value, [min, max])")
        run = stream(seed)                              # validates the seed; None: fresh entropy for this run
        self._clear_faults()
        m, d = self.model, self.data
        if self._home_key >= 0:
            mujoco.mj_resetDataKeyframe(m, d, self._home_key)
        else:
            mujoco.mj_resetData(m, d)
        d.qpos[self._qadr], d.qvel[self._dofs] = q, v
        d.ctrl[self._act] = 0.0
        if self._home_key < 0:
            d.ctrl[self._other_act] = 0.0
        self._other_ctrl[:] = d.ctrl[self._other_act]
        mujoco.mj_forward(m, d)
        self.u_applied = np.zeros(n)
        self._pos_draws = ChannelNoise(run, self.sensor_channels[:n]) if np.any(self._pos_noise) else None
        self._vel_draws = ChannelNoise(run, self.sensor_channels[n:]) if np.any(self._vel_noise) else None
        return self.measure()

    def saturate(self, u: np.ndarray) -> np.ndarray:
        """What the drives can deliver of u: clipped to each drive's torque range [N·m or N]."""
        return np.minimum(np.maximum(u, self._torque_lo), self._torque_hi)

    def step(self, u: np.ndarray) -> np.ndarray:
        """Apply torques u (n, [N·m or N], saturated) for one control period; return the measurement.

        One compiled kernel (:func:`robofdi.sims.kernels.control_tick`) does the period: the saturation, every
        physics sub-step's ripple and Stribeck torques (:meth:`disturbance`'s effects) and MuJoCo's ``mj_step``
        through its C API, then the sensors (:meth:`measure`'s reading; a subclass that overrides :meth:`measure`
        gets its own reading)."""
        u = np.asarray(u, dtype=float)
        n = self.n
        if u.shape != (n,):
            self._refuse(u)
        tau, y = np.empty(n), np.empty(2 * n)
        sensed = self._sensors_in_tick          # else a subclass's own measure() reads the sensors afterwards
        zq = self._pos_draws.draw() if sensed and self._pos_draws is not None else self._empty
        zv = self._vel_draws.draw() if sensed and self._vel_draws is not None else self._empty
        if self._mj_step:
            status = kernels.control_tick(
                self._mj_step, self._model_at, self._data_at, self.substeps, self._ripple_on, self._stribeck_on, u,
                self._tick_f, self._tick_fo, self._tick_i, self._tick_io, self._qpos, self._qvel, self._qfrc,
                self._ctrl, tau, zq, zv, y)
        else:
            status = self._step_through_bindings(u, tau, zq, zv, y)
        if status == 0:                     # u not finite: the plant is untouched
            self._refuse(u)
        self.u_applied = tau
        if status == 2:
            raise RobofdiError(f"simulation diverged at t={self.data.time:.4f} s: non-finite joint state")
        return y if sensed else self.measure()

    def _refuse(self, u: np.ndarray):
        raise RobofdiError(f"step: u must be {self.n} finite joint torques for {self.joint_names}, got shape "
                           f"{u.shape}: {u.tolist()}")

    def _step_through_bindings(self, u: np.ndarray, tau: np.ndarray, zq: np.ndarray, zv: np.ndarray,
                               y: np.ndarray) -> int:
        """:func:`~robofdi.sims.kernels.control_tick` with ``mujoco.mj_step`` between the kernels, for a ``mujoco``
        whose C library :mod:`robofdi.sims.capi` cannot find: the same C function, the same numbers."""
        if not kernels.apply_torque(u, self._torque_lo, self._torque_hi, self._inv_gain_k, self._act, self._ctrl, tau):
            return 0
        self._ctrl[self._other_act] = self._other_ctrl
        m, d = self.model, self.data
        for _ in range(self.substeps):
            if self._ripple_on or self._stribeck_on:
                kernels.physics_forces(self._qpos, self._qvel, self._qadr, self._dofs, tau, self._r_index, self._r_F,
                                       self._r_P, self._r_amp, self._r_load, self._r_s, self._ripple_on,
                                       self._stribeck, self._stribeck_inv_v, self._stribeck_inv_eps, self._stribeck_on,
                                       self._qfrc)
            mujoco.mj_step(m, d)
        if not (all_finite(self._qpos) and all_finite(self._qvel)):
            return 2
        kernels.measure(self._qpos, self._qvel, self._qadr, self._dofs, self._resolution, self._inv_resolution,
                        self._pos_noise, zq, self._vel_noise, zv, y)
        return 1

    def disturbance(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """δ(q, q̇, τ) [N·m] of eq. (3): torque ripple plus the Stribeck term (the friction torque opposes motion,
        so its δ is minus it)."""
        delta = self.ripple_torque(q, tau) if self._ripple_on else np.zeros(self.n)
        if self._stribeck_on:       # StribeckFriction.torque with the divisions precomputed
            delta = delta + self._stribeck * np.exp(-np.square(v * self._stribeck_inv_v)) * np.tanh(v * self._stribeck_inv_eps)
        return delta

    def ripple_torque(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The ripple δ(q, τ) of :class:`TorqueRipple` [N·m]."""
        s = np.sin(self._r_F * q[self._r_index] + self._r_P)
        k = self._r_split
        return self._r_A @ s[:k] + tau * self._r_load * s[k:]

    def measure(self) -> np.ndarray:
        """Sensor reading [q; q̇] (quantised positions, noisy velocities; :class:`SensorModel`)."""
        zq = self._pos_draws.draw() if self._pos_draws is not None else self._empty
        zv = self._vel_draws.draw() if self._vel_draws is not None else self._empty
        y = np.empty(2 * self.n)
        kernels.measure(self._qpos, self._qvel, self._qadr, self._dofs, self._resolution, self._inv_resolution,
                        self._pos_noise, zq, self._vel_noise, zv, y)
        return y

    # ----------------------------------------------------------------------------------------- components
    @property
    def link_masses(self) -> dict[str, float]:
        """Nominal mass [kg] of every link body a ``component_mass`` fault may change (the payload point excluded)."""
        return {b: float(self._body0[i][0]) for b, (i, _) in self._mass_points.items() if b != "payload"}

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        """Set component ``target`` to ``value`` away from nominal (0 restores it exactly).

        component_friction (target: an arm joint; value: relative rise, dimensionless, > −1): Coulomb
        frictionloss, viscous damping and the Stribeck term become nominal · (1 + value).
        component_mass (target: an arm link body or "payload"; value: added mass [kg], >= 0): a point mass at
        the body's centre of mass (or at the payload point).
        """
        key = (kind, target)
        if key in self._faults and self._faults[key] == value:       # called every control tick: cheap when unchanged
            return
        if kind not in self.component_kinds:
            raise RobofdiError(f"apply_component_fault: kind {kind!r} is not one of {list(self.component_kinds)}")
        if target not in self.component_kinds[kind]:
            raise RobofdiError(f"apply_component_fault: {kind} target {target!r} is not one of "
                               f"{list(self.component_kinds[kind])}")
        v = float(value)
        if kind == "component_friction" and not (np.isfinite(v) and v > -1.0):
            raise RobofdiError(f"apply_component_fault: component_friction on {target!r} must be a relative rise > -1, "
                               f"got {value!r}")
        if kind == "component_mass" and not (np.isfinite(v) and v >= 0.0):
            raise RobofdiError(f"apply_component_fault: component_mass on {target!r} must be an added mass >= 0 kg, "
                               f"got {value!r}")
        if v == 0.0:
            if key not in self._faults:
                return
            del self._faults[key]
        else:
            self._faults[key] = v
        if kind == "component_friction":
            self._apply_friction()
        else:
            self._apply_mass(self._mass_points[target][0])

    def _apply_friction(self) -> None:
        rise = np.array([self._faults.get(("component_friction", j), 0.0) for j in self.joint_names])
        self._set_friction(rise)

    def _apply_mass(self, body: int) -> None:
        m = self.model
        (m.body_mass[body], m.body_ipos[body], m.body_iquat[body], m.body_inertia[body],
         m.body_sameframe[body]) = self._body0[body]
        nominal_com = self._body0[body][1]
        points = [(v, nominal_com if self._mass_points[t][1] is None else self._mass_points[t][1])
                  for (kind, t), v in self._faults.items() if kind == "component_mass" and self._mass_points[t][0] == body]
        if points:
            self._set_body(body, points)
        mujoco.mj_setConst(m, self._scratch)

    def _clear_faults(self) -> None:
        if not self._faults:
            return
        bodies = {self._mass_points[t][0] for (kind, t) in self._faults if kind == "component_mass"}
        self._faults.clear()
        self._apply_friction()
        for b in bodies:
            self._apply_mass(b)

    # ----------------------------------------------------------------------------------------- belief
    def nominal_model(self, mismatch: ModelMismatch | None = None, payload: float = 0.0) -> ManipulatorModel:
        """The belief: a Pinocchio model compiled afresh from the same file (never from this simulator's model,
        so no payload or component fault leaks in), with deliberate parameter errors ``mismatch`` and the load
        ``payload`` [kg] the user declares at the payload point (:class:`ManipulatorModel`)."""
        model = ManipulatorModel(self.path, mismatch or ModelMismatch(), self.joint_names, self.torque_motors,
                                 self.drive_inertia, payload)
        model.check_joints(self.joint_names)
        return model

