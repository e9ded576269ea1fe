"""Nominal manipulator model (the diagnoser's belief), built with Pinocchio from an MJCF file.

The file is compiled by MuJoCo's own compiler (:func:`robofdi.mjcf.compile_arm`, through ``mujoco.MjSpec``; a URDF
is first turned into MJCF by :func:`robofdi.mjcf.urdf_to_mjcf`, the same file the simulator reads), so everything
MJCF allows — ``<include>``, ``<default>`` classes, ``compiler angle="degree"``, meshes, inertia from geoms —
is read exactly as the plant reads it. The Pinocchio model is then assembled directly from the compiled
kinematic tree and inertias (:func:`pinocchio_model`): one joint per arm joint; every other joint (a gripper)
is locked at its reference position and its bodies, like welded bodies, are lumped into the arm link that
carries them. The compiled model is fresh for every nominal model, so nothing a simulator changes at run time
(payload, component faults) leaks into the belief.

Parameters are perturbed on purpose (:class:`ModelMismatch`) so that diagnosers face real model error.
Pinocchio's ``crba``/``aba``/``rnea`` include the joint armature; ``nonLinearEffects`` does not include damping,
so the nominal bias is n̂ = nle(q, q̇) + D̂ q̇ (viscous friction, eq. (2) of Caccavale & Villani). Coulomb and
Stribeck friction, torque ripple, joint springs and the plant's payload are deliberately left out of the belief;
a load the user declares (``payload``) is a point mass at the file's payload point (:func:`payload_inertia`).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from robofdi import RobofdiError
from robofdi.checks import is_number
from robofdi.jit import kernel
from robofdi.mjcf import _JOINT_KINDS, VELOCITY_LIMIT, _name, compile_arm, gear_ratio, payload_point
from robofdi.seeding import rng

__all__ = ["ModelMismatch", "ManipulatorModel", "pinocchio_model", "payload_inertia", "sensor_channel_names",
           "mirror_upper"]


def sensor_channel_names(joints: Sequence[str]) -> list[str]:
    """Names of the measurement entries of an arm: every joint's position, then every joint's velocity."""
    return [f"{j}_pos" for j in joints] + [f"{j}_vel" for j in joints]


# ---------------------------------------------------------------------------------------------------------------
# The Pinocchio model
# ---------------------------------------------------------------------------------------------------------------
def _se3(quat: np.ndarray, pos: np.ndarray) -> pin.SE3:
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, dtype=float))
    return pin.SE3(R.reshape(3, 3), np.asarray(pos, dtype=float).copy())


def _joint_model(kind: str, axis: np.ndarray):
    aligned = {(1.0, 0.0, 0.0): "X", (0.0, 1.0, 0.0): "Y", (0.0, 0.0, 1.0): "Z"}.get(tuple(np.round(axis, 15)))
    if kind == "hinge":
        return getattr(pin, f"JointModelR{aligned}")() if aligned else pin.JointModelRevoluteUnaligned(axis.copy())
    return getattr(pin, f"JointModelP{aligned}")() if aligned else pin.JointModelPrismaticUnaligned(axis.copy())


def pinocchio_model(m: mujoco.MjModel, arm_joints: Sequence[int]) -> pin.Model:
    """The rigid-body model of the arm joints ``arm_joints`` (MuJoCo joint ids, in tree order) of the compiled
    model ``m``: joint placements from body_pos/body_quat/jnt_pos/jnt_axis (q = 0 in Pinocchio is q = ref in
    MuJoCo), inertias from body_mass/body_ipos/body_iquat/body_inertia, armature and damping from
    dof_armature/dof_damping, gravity from opt.gravity. Other joints are locked at their reference position:
    their bodies, like welded bodies, are lumped into the arm joint that carries them."""
    arm = {int(j): k for k, j in enumerate(arm_joints)}
    model = pin.Model()
    model.gravity = pin.Motion(np.r_[m.opt.gravity, 0.0, 0.0, 0.0])
    frame_of = {0: (0, pin.SE3.Identity(), 0)}   # body -> (Pinocchio joint, body placement in it, frame id)
    armature, damping = np.zeros(len(arm)), np.zeros(len(arm))
    for b in range(1, m.nbody):
        joint, X, frame = frame_of[int(m.body_parentid[b])]
        X = X * _se3(m.body_quat[b], m.body_pos[b])
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            if j not in arm:
                continue                          # locked at its reference: the body frame is the compiled one
            kind = _JOINT_KINDS[int(m.jnt_type[j])]
            placement = X * pin.SE3(np.eye(3), m.jnt_pos[j].copy())      # the body frame at q = ref, moved to the joint
            joint = model.addJoint(joint, _joint_model(kind, m.jnt_axis[j].copy()), placement,
                                   _name(m, mujoco.mjtObj.mjOBJ_JOINT, j))
            frame = model.addJointFrame(joint, frame)
            armature[arm[j]], damping[arm[j]] = m.dof_armature[m.jnt_dofadr[j]], m.dof_damping[m.jnt_dofadr[j]]
            X = pin.SE3(np.eye(3), -m.jnt_pos[j])
        if m.body_mass[b] > 0:
            R = _se3(m.body_iquat[b], np.zeros(3)).rotation
            inertia = pin.Inertia(float(m.body_mass[b]), m.body_ipos[b].copy(), R @ np.diag(m.body_inertia[b]) @ R.T)
            model.appendBodyToJoint(joint, inertia, X)
        frame = model.addBodyFrame(_name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}", joint, X, frame)
        frame_of[b] = (joint, X, frame)
    if model.nv != len(arm):
        raise RobofdiError(f"nominal model: built {model.nv} joints, expected {len(arm)}")
    model.armature, model.damping = armature, damping
    return model


# ---------------------------------------------------------------------------------------------------------------
# Mismatch and the model
# ---------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ModelMismatch:
    """Deliberate errors of the nominal parameters, as relative 1-sigma errors drawn from the stream
    ``robofdi.seeding.stream(seed, "belief", "mismatch")`` (normal draws truncated at ±2σ, so with σ < 0.5 every
    parameter keeps its sign).

    mass: link masses (and the rotational inertias scale with them); inertia: extra error on the
    rotational inertias; damping: viscous friction coefficients; armature: rotor inertias (all dimensionless).
    """

    mass: float = 0.0
    inertia: float = 0.0
    damping: float = 0.0
    armature: float = 0.0
    seed: int = 0

    def __post_init__(self):
        for name in ("mass", "inertia", "damping", "armature"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 <= v < 0.5):
                raise RobofdiError(f"ModelMismatch: field {name!r} must be a relative error in [0, 0.5), got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise RobofdiError(f"ModelMismatch: field 'seed' must be an integer >= 0, got {self.seed!r}")


def _velocity_limit(m: mujoco.MjModel, n: int, path: Path) -> np.ndarray:
    """The arm joints' velocity limits [rad/s or m/s] from ``<numeric name="robofdi_velocity_limit">`` (one per
    arm joint, 0 = none; written by :func:`robofdi.mjcf.urdf_to_mjcf`); inf where none is given."""
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, VELOCITY_LIMIT)
    if i < 0:
        return np.full(n, np.inf)
    data = np.array(m.numeric_data[m.numeric_adr[i]: m.numeric_adr[i] + m.numeric_size[i]], dtype=float)
    if data.shape != (n,) or not np.all(np.isfinite(data) & (data >= 0)):
        raise RobofdiError(f"mjcf: <numeric name='{VELOCITY_LIMIT}'> of {path.name} must hold {n} finite values >= 0 "
                           f"[rad/s or m/s] (one per arm joint, 0 = none), got {data.tolist()}")
    return np.where(data > 0, data, np.inf)


class ManipulatorModel:
    """M̂(q), n̂(q, q̇) of an n-joint arm — the nominal model of eq. (3) (Caccavale & Villani).

    ``joints``, ``torque_motors`` and ``drive_inertia`` read the arm exactly as :class:`robofdi.sims.ArmSimulator` does. q is in
    the file's joint coordinates [rad or m], velocities in rad/s or m/s, torques in N·m or N. ``joint_range``
    (n, 2) [rad or m] is ±inf where a joint is unlimited; ``velocity_limit`` (n,) [rad/s or m/s] is inf where the
    file gives none (a URDF's ``<limit velocity>``, see :func:`robofdi.mjcf.urdf_to_mjcf`); ``gear_ratio`` (n,)
    the drives' datasheet gear ratios (:func:`robofdi.mjcf.gear_ratio`); ``payload_body`` and ``payload_offset``
    (3,) [m] the payload point (:func:`robofdi.mjcf.payload_point`).

    ``payload`` [kg]: a load the user declares (a tool or part the file lacks), added exactly as a point mass at
    the payload point after the mismatch is drawn: the belief carries it, the controller compensates it and the
    motions are planned with it. 0 (default): the file's model as it is.
    """

    def __init__(self, mjcf: str | Path, mismatch: ModelMismatch | None = None,
                 joints: Sequence[str] | None = None, torque_motors: bool = False, drive_inertia: float = 0.0,
                 payload: float = 0.0):
        mismatch = mismatch or ModelMismatch()
        if not isinstance(mismatch, ModelMismatch):
            raise RobofdiError(f"mismatch: expected a ModelMismatch, got {type(mismatch).__name__}")
        if not (is_number(payload) and payload >= 0):
            raise RobofdiError(f"nominal model: field 'payload' must be a finite mass >= 0 kg, got {payload!r}")
        arm = compile_arm(mjcf, joints, torque_motors, drive_inertia)
        m = arm.model
        self.path = arm.path
        self.system = arm.system
        self.mismatch = mismatch
        self.payload_body, self.payload_offset = payload_point(arm)
        self.payload = float(payload)
        model = pinocchio_model(m, [d.joint_id for d in arm.drives])
        model.name = arm.system
        self._perturb(model, mismatch)
        if self.payload:
            joint, load = payload_inertia(model, self.payload_body, self.payload_offset, self.payload)
            model.inertias[joint] = model.inertias[joint] + load
        self.model = model
        self.data = model.createData()
        self.joint_names = arm.joint_names
        self.joint_kinds = tuple(d.kind for d in arm.drives)            # "hinge" [rad, N·m] or "slide" [m, N]
        self.n = model.nv
        self.damping = np.array(model.damping, dtype=float)
        self.torque_limit = arm.torque_limit
        self.torque_range = arm.torque_range
        ids = [d.joint_id for d in arm.drives]
        self.joint_range = np.where(m.jnt_limited[ids, None].astype(bool), m.jnt_range[ids], [-np.inf, np.inf])
        self.velocity_limit = _velocity_limit(m, self.n, arm.path)
        self.gear_ratio = gear_ratio(arm)
        self._ref = np.array([m.qpos0[d.qpos] for d in arm.drives])
        self._has_ref = bool(np.any(self._ref != 0))
        self._lower = np.tril_indices(self.n, -1)

    @property
    def input_names(self) -> list[str]:
        """Names of the entries of u (the arm joints, torques in N·m or N)."""
        return list(self.joint_names)

    @property
    def measurement_names(self) -> list[str]:
        """Names of the entries of y: joint positions, then joint velocities."""
        return sensor_channel_names(self.joint_names)

    @staticmethod
    def _perturb(model: pin.Model, mm: ModelMismatch) -> None:
        draw = rng(mm.seed, "belief", "mismatch")

        def factor(sigma, size=None):
            return 1.0 + sigma * np.clip(draw.standard_normal(size), -2.0, 2.0)

        for i in range(1, model.njoints):
            inert = model.inertias[i]
            ks = factor(mm.mass)
            ki = ks * factor(mm.inertia)
            model.inertias[i] = pin.Inertia(inert.mass * ks, inert.lever.copy(), inert.inertia * ki)
        model.damping = model.damping * factor(mm.damping, model.nv)
        model.armature = model.armature * factor(mm.armature, model.nv)

    def check_joints(self, names: list[str]) -> None:
        """Raise if the simulator's joints differ from the model's (by name and order)."""
        if list(names) != self.joint_names:
            raise RobofdiError(
                f"nominal model joints {self.joint_names} do not match the simulator's joints {list(names)}"
            )

    def _q(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(q, dtype=float) - self._ref if self._has_ref else q

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M̂(q) [kg·m²], symmetric, armature included."""
        return mirror_upper(pin.crba(self.model, self.data, self._q(q)).copy())   # crba fills the upper triangle

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """n̂(q, q̇) = C(q, q̇) q̇ + g(q) + D̂ q̇ [N·m]."""
        return pin.nonLinearEffects(self.model, self.data, self._q(q), v) + self.damping * v

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """τ = M̂(q) q̈ + n̂(q, q̇) (RNEA, armature included, plus viscous friction) [N·m]."""
        return pin.rnea(self.model, self.data, self._q(q), v, a) + self.damping * v

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """g(q) [N·m]."""
        return pin.computeGeneralizedGravity(self.model, self.data, self._q(q))

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """C(q, q̇) with Ṁ = C + Cᵀ (Pinocchio's factorisation)."""
        return pin.computeCoriolisMatrix(self.model, self.data, self._q(q), v)

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q̈ = M̂⁻¹(τ − n̂) (forward dynamics with viscous friction) [rad/s²]."""
        return pin.aba(self.model, self.data, self._q(q), v, tau - self.damping * v)


def payload_inertia(model: pin.Model, body: str, offset: np.ndarray, mass: float) -> tuple[int, pin.Inertia]:
    """(joint index, inertia) of a point mass ``mass`` [kg] at ``offset`` (3,) [m] in ``body``'s frame of the
    Pinocchio ``model`` (no rotational inertia of its own), for the joint that carries the body."""
    if not model.existFrame(body):
        raise RobofdiError(f"payload: the nominal model has no body frame {body!r} for the payload point")
    frame = model.frames[model.getFrameId(body)]
    return frame.parentJoint, pin.Inertia(float(mass), frame.placement.act(np.asarray(offset, float)), np.zeros((3, 3)))


def mirror_upper(M: np.ndarray) -> np.ndarray:
    """Copy the upper triangle of the square ``M`` onto its lower one, in place, and return ``M`` (Pinocchio's crba
    fills the upper triangle only)."""
    _mirror_upper(M)
    return M


@kernel
def _mirror_upper(M):
    """Copy the upper triangle of the square ``M`` onto its lower one (crba fills the upper triangle only)."""
    for i in range(M.shape[0]):
        for j in range(i):
            M[i, j] = M[j, i]
