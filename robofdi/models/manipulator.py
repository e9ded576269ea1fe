"""Nominal manipulator model (the diagnoser's belief), built with Pinocchio from an MJCF file.

The file is compiled by MuJoCo's own compiler (:func:`compile_arm`, through ``mujoco.MjSpec``), so everything
MJCF allows — ``<include>``, ``<default>`` classes, ``compiler angle="degree"``, meshes, inertia from geoms —
is read exactly as the plant reads it. The Pinocchio model is then assembled directly from the compiled
kinematic tree and inertias (:func:`pinocchio_model`): one joint per arm joint; every other joint (a gripper)
is locked at its reference position and its bodies, like welded bodies, are lumped into the arm link that
carries them. The compiled model is fresh for every nominal model, so nothing a simulator changes at run time
(payload, component faults) leaks into the belief.

Parameters are perturbed on purpose (:class:`ModelMismatch`) so that diagnosers face real model error.
Pinocchio's ``crba``/``aba``/``rnea`` include the joint armature; ``nonLinearEffects`` does not include damping,
so the nominal bias is n̂ = nle(q, q̇) + D̂ q̇ (viscous friction, eq. (2) of Caccavale & Villani). Coulomb and
Stribeck friction, torque ripple, joint springs and any payload are deliberately left out of the belief.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from robofdi import ASSETS, RobofdiError
from robofdi.seeding import rng

__all__ = [
    "ModelMismatch", "ManipulatorModel", "Drive", "CompiledArm", "compile_arm", "pinocchio_model",
    "sensor_channel_names", "resolve_asset", "is_torque_motor", "actuator_kind",
]

_JOINT_KINDS = {int(mujoco.mjtJoint.mjJNT_HINGE): "hinge", int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
                int(mujoco.mjtJoint.mjJNT_BALL): "ball", int(mujoco.mjtJoint.mjJNT_FREE): "free"}
_JOINT_TRANSMISSIONS = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
_DEFAULT_MODEL_NAME = "MuJoCo Model"      # what MuJoCo calls a model whose <mujoco> has no name


def resolve_asset(path: str | Path) -> Path:
    """A file name of the shipped assets or a path; raises RobofdiError naming the file if it does not exist."""
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = ASSETS / p
    if not p.is_file():
        raise RobofdiError(f"mjcf: file {str(path)!r} does not exist (looked in the working folder and {ASSETS})")
    return p


def sensor_channel_names(joints: Sequence[str]) -> list[str]:
    """Names of the measurement entries of an arm: every joint's position, then every joint's velocity."""
    return [f"{j}_pos" for j in joints] + [f"{j}_vel" for j in joints]


# ---------------------------------------------------------------------------------------------------------------
# Compiling the file and reading the arm's drive table
# ---------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Drive:
    """How one arm joint is driven. ``gain``: joint torque [N·m] (force [N] for a slide joint) per unit of the
    actuator's ctrl (= gear · gainprm[0]; ctrl = τ / gain); ``torque_range``: what the drive can deliver."""

    joint: str
    joint_id: int
    kind: str                      # "hinge" or "slide"
    qpos: int                      # address in qpos
    dof: int                       # address in qvel / qfrc
    body: str                      # the link the joint moves
    actuator: str
    actuator_id: int
    gain: float
    torque_range: tuple[float, float]

    @property
    def torque_limit(self) -> float:
        """Largest torque magnitude the drive can deliver [N·m or N]."""
        return max(abs(self.torque_range[0]), abs(self.torque_range[1]))


@dataclass(frozen=True, eq=False)
class CompiledArm:
    """An MJCF file compiled by MuJoCo, with its arm joints and their drives (in arm order)."""

    path: Path
    model: mujoco.MjModel
    system: str
    drives: tuple[Drive, ...]

    @property
    def joint_names(self) -> list[str]:
        return [d.joint for d in self.drives]

    @property
    def torque_range(self) -> np.ndarray:
        """(n, 2) lower and upper joint torque of each drive."""
        return np.array([d.torque_range for d in self.drives], dtype=float).reshape(-1, 2)

    @property
    def torque_limit(self) -> np.ndarray:
        return np.array([d.torque_limit for d in self.drives], dtype=float)


def _name(m: mujoco.MjModel, obj, i: int) -> str:
    return mujoco.mj_id2name(m, obj, i) or ""


def _actuator_label(m: mujoco.MjModel, a: int) -> str:
    name = _name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a)
    return repr(name) if name else f"#{a}"


def is_torque_motor(m: mujoco.MjModel, a: int) -> bool:
    """True when actuator a is a plain torque motor (fixed gain, no bias, no activation dynamics)."""
    return (m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED and m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE
            and m.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE)


def actuator_kind(m: mujoco.MjModel, a: int) -> str:
    """A short description of a non-motor actuator, for error messages."""
    dyn, gain, bias = (int(m.actuator_dyntype[a]), int(m.actuator_gaintype[a]), int(m.actuator_biastype[a]))
    if gain == mujoco.mjtGain.mjGAIN_MUSCLE:
        return "a muscle"
    if dyn == mujoco.mjtDyn.mjDYN_INTEGRATOR:
        return "an integrated-velocity servo (dyntype integrator)"
    if bias == mujoco.mjtBias.mjBIAS_AFFINE and m.actuator_biasprm[a, 1] != 0:
        return "a position servo (biastype affine, kp=%g)" % -m.actuator_biasprm[a, 1]
    if bias == mujoco.mjtBias.mjBIAS_AFFINE and m.actuator_biasprm[a, 2] != 0:
        return "a velocity servo (biastype affine, kv=%g)" % -m.actuator_biasprm[a, 2]
    return (f"not a motor (gaintype {mujoco.mjtGain(gain).name}, biastype {mujoco.mjtBias(bias).name}, "
            f"dyntype {mujoco.mjtDyn(dyn).name})")


def _joint_actuators(m: mujoco.MjModel) -> dict[int, list[int]]:
    """joint id -> ids of the actuators driving it through a joint transmission."""
    out: dict[int, list[int]] = {}
    for a in range(m.nu):
        if int(m.actuator_trntype[a]) in _JOINT_TRANSMISSIONS:
            out.setdefault(int(m.actuator_trnid[a, 0]), []).append(a)
    return out


def _compile(spec: mujoco.MjSpec, path: Path) -> mujoco.MjModel:
    try:
        return spec.compile()
    except Exception as exc:
        raise RobofdiError(f"mjcf: MuJoCo cannot compile {str(path)!r}: {' '.join(str(exc).split())}") from None


def _select_arm(m: mujoco.MjModel, path: Path, joints: Sequence[str] | None, torque_motors: bool) -> list[int]:
    """Ids of the arm joints, in the file's order (checked: hinge/slide, exactly one joint actuator each)."""
    actuated = _joint_actuators(m)
    file = path.name
    names = [_name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    if joints is None:
        ids = [j for j in range(m.njnt) if _JOINT_KINDS.get(int(m.jnt_type[j])) in ("hinge", "slide")
               and any(is_torque_motor(m, a) or torque_motors for a in actuated.get(j, []))]
        if not ids:
            servos = [f"{names[j]!r} ({actuator_kind(m, a)})" for j, acts in actuated.items() for a in acts
                      if not is_torque_motor(m, a)]
            hint = (f"; its joint actuators are {', '.join(servos)}: pass torque_motors=True to turn them into motors"
                    if servos else "")
            raise RobofdiError(f"mjcf: no hinge/slide joint of {file} is driven by a motor-type actuator{hint}")
    else:
        if isinstance(joints, str) or not all(isinstance(j, str) for j in joints):
            raise RobofdiError(f"joints: expected a sequence of joint names, got {joints!r}")
        unknown = [j for j in joints if j not in names]
        if unknown:
            raise RobofdiError(f"joints: {unknown} are not joints of {file} (its joints: {[n for n in names if n]})")
        if len(set(joints)) != len(joints):
            raise RobofdiError(f"joints: names must be unique, got {list(joints)}")
        ids = [names.index(j) for j in joints]
        for j in ids:
            kind = _JOINT_KINDS.get(int(m.jnt_type[j]), "unknown")
            if kind not in ("hinge", "slide"):
                raise RobofdiError(f"joints: {names[j]!r} of {file} is a {kind} joint; arm joints must be hinge or slide")
        if ids != sorted(ids):
            order = [names[j] for j in sorted(ids)]
            raise RobofdiError(f"joints: list the arm joints in the file's order {order}, got {list(joints)}")
    for j in ids:
        acts = actuated.get(j, [])
        if len(acts) != 1:
            which = ", ".join(_actuator_label(m, a) for a in acts) or "none"
            raise RobofdiError(f"mjcf: arm joint {names[j]!r} of {file} is driven by {len(acts)} joint actuators "
                               f"({which}); expected exactly one")
        if not is_torque_motor(m, acts[0]) and not torque_motors:
            raise _not_a_motor(m, acts[0], names[j], file)
    arm = set(ids)
    for j in ids:                                        # nothing but arm joints between an arm joint and the world
        b = int(m.body_parentid[m.jnt_bodyid[j]])
        while b > 0:
            for k in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
                if k in arm:
                    continue
                servos = [a for a in actuated.get(k, []) if not is_torque_motor(m, a)]
                if joints is None and servos and _JOINT_KINDS.get(int(m.jnt_type[k])) in ("hinge", "slide"):
                    raise _not_a_motor(m, servos[0], names[k], file)
                raise RobofdiError(f"joints: arm joint {names[j]!r} of {file} moves with the non-arm joint "
                                   f"{names[k]!r}; include it in the arm or weld it")
            b = int(m.body_parentid[b])
    return ids


def _not_a_motor(m: mujoco.MjModel, a: int, joint: str, file: str) -> RobofdiError:
    return RobofdiError(
        f"mjcf: actuator {_actuator_label(m, a)} on arm joint {joint!r} of {file} is {actuator_kind(m, a)}; "
        f"expected a torque motor (<motor>, or <general> with gaintype fixed, biastype none, dyntype none); "
        f"pass torque_motors=True to convert the arm joints' actuators into motors")


def _torque_range(m: mujoco.MjModel, a: int, j: int, path: Path) -> tuple[float, float]:
    """Joint torque range of actuator a on joint j: ctrlrange · gain ∩ forcerange · gear ∩ the joint's
    actuatorfrcrange (each where limited)."""
    gear, gain = float(m.actuator_gear[a, 0]), float(m.actuator_gear[a, 0] * m.actuator_gainprm[a, 0])
    lo, hi = -np.inf, np.inf
    for limited, rng_, scale in ((m.actuator_ctrllimited[a], m.actuator_ctrlrange[a], gain),
                                 (m.actuator_forcelimited[a], m.actuator_forcerange[a], gear),
                                 (m.jnt_actfrclimited[j], m.jnt_actfrcrange[j], 1.0)):
        if limited:
            r = np.sort(np.asarray(rng_, dtype=float) * scale)
            lo, hi = max(lo, r[0]), min(hi, r[1])
    joint = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise RobofdiError(f"mjcf: actuator {_actuator_label(m, a)} on arm joint {joint!r} of {path.name}: neither its "
                           f"ctrlrange, its forcerange nor the joint's actuatorfrcrange bounds the torque; expected one")
    if not hi > lo:
        raise RobofdiError(f"mjcf: actuator {_actuator_label(m, a)} on arm joint {joint!r} of {path.name}: empty torque "
                           f"range [{lo}, {hi}]")
    return float(lo), float(hi)


def _to_motors(spec: mujoco.MjSpec, m: mujoco.MjModel, ids: list[int], path: Path) -> bool:
    """Turn the non-motor actuators of the arm joints into motors in ``spec`` (``actuator.set_to_motor()``),
    keeping the servo's force bound (forcerange, else the joint's actuatorfrcrange) as the torque limit.
    Returns whether anything changed."""
    actuated = _joint_actuators(m)
    changed = False
    for j in ids:
        a = actuated[j][0]
        if is_torque_motor(m, a):
            continue
        act = spec.actuators[a]
        if act.name != _name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a):        # spec order == compiled order
            raise RobofdiError(f"torque_motors: cannot match actuator {_actuator_label(m, a)} of {path.name} in its spec")
        gear = float(m.actuator_gear[a, 0])
        lo, hi = -np.inf, np.inf
        if m.actuator_forcelimited[a]:
            lo, hi = np.sort(m.actuator_forcerange[a] * gear)
        if m.jnt_actfrclimited[j]:
            lo, hi = max(lo, m.jnt_actfrcrange[j, 0]), min(hi, m.jnt_actfrcrange[j, 1])
        if not (np.isfinite(lo) and np.isfinite(hi)):
            joint = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            raise RobofdiError(f"torque_motors: actuator {_actuator_label(m, a)} on arm joint {joint!r} of {path.name} "
                               f"has no forcerange and the joint no actuatorfrcrange; expected one to bound the torque")
        act.set_to_motor()
        act.ctrlrange = np.sort([lo / gear, hi / gear])
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        changed = True
    return changed


def compile_arm(mjcf: str | Path, joints: Sequence[str] | None = None, torque_motors: bool = False) -> CompiledArm:
    """Compile ``mjcf`` with ``mujoco.MjSpec.from_file`` and read its arm: the joints (``joints``, or every
    hinge/slide joint driven by a motor-type actuator; with ``torque_motors``, by any joint actuator) and, per
    joint, the actuator driving it through a joint transmission, its gain and its torque range.
    ``torque_motors``: convert the arm joints' servos into motors."""
    path = resolve_asset(mjcf)
    if not isinstance(torque_motors, bool):
        raise RobofdiError(f"torque_motors: expected True or False, got {torque_motors!r}")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as exc:
        raise RobofdiError(f"mjcf: MuJoCo cannot read {str(path)!r}: {' '.join(str(exc).split())}") from None
    m = _compile(spec, path)
    ids = _select_arm(m, path, joints, torque_motors)
    if torque_motors and _to_motors(spec, m, ids, path):
        m = _compile(spec, path)
    actuated = _joint_actuators(m)
    drives = []
    for j in ids:
        a = actuated[j][0]
        gain = float(m.actuator_gear[a, 0] * m.actuator_gainprm[a, 0])
        if gain == 0 or not np.isfinite(gain):
            raise RobofdiError(f"mjcf: actuator {_actuator_label(m, a)} of {path.name} has gear·gain {gain}; expected "
                               "a finite non-zero value")
        drives.append(Drive(
            joint=_name(m, mujoco.mjtObj.mjOBJ_JOINT, j), joint_id=j, kind=_JOINT_KINDS[int(m.jnt_type[j])],
            qpos=int(m.jnt_qposadr[j]), dof=int(m.jnt_dofadr[j]),
            body=_name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.jnt_bodyid[j])),
            actuator=_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a), actuator_id=a, gain=gain,
            torque_range=_torque_range(m, a, j, path)))
    unnamed = [d.joint_id for d in drives if not d.joint]
    if unnamed:
        raise RobofdiError(f"mjcf: arm joints {unnamed} of {path.name} have no name; expected named joints")
    system = spec.modelname if spec.modelname and spec.modelname != _DEFAULT_MODEL_NAME else path.stem
    return CompiledArm(path, m, system, tuple(drives))


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


class ManipulatorModel:
    """M̂(q), n̂(q, q̇) of an n-joint arm — the nominal model of eq. (3) (Caccavale & Villani).

    ``joints`` and ``torque_motors`` select the arm exactly as :class:`robofdi.sims.ArmSimulator` does. q is in
    the file's joint coordinates [rad or m], velocities in rad/s or m/s, torques in N·m or N.
    """

    def __init__(self, mjcf: str | Path, mismatch: ModelMismatch | None = None,
                 joints: Sequence[str] | None = None, torque_motors: bool = False):
        mismatch = mismatch or ModelMismatch()
        if not isinstance(mismatch, ModelMismatch):
            raise RobofdiError(f"mismatch: expected a ModelMismatch, got {type(mismatch).__name__}")
        arm = compile_arm(mjcf, joints, torque_motors)
        m = arm.model
        self.path = arm.path
        self.system = arm.system
        self.mismatch = mismatch
        model = pinocchio_model(m, [d.joint_id for d in arm.drives])
        model.name = arm.system
        self._perturb(model, mismatch)
        self.model = model
        self.data = model.createData()
        self.joint_names = arm.joint_names
        self.n = model.nv
        self.damping = np.array(model.damping, dtype=float)
        self.torque_limit = arm.torque_limit
        self.torque_range = arm.torque_range
        ids = [d.joint_id for d in arm.drives]
        self.joint_range = np.where(m.jnt_limited[ids, None].astype(bool), m.jnt_range[ids], [-np.inf, np.inf])
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
        M = pin.crba(self.model, self.data, self._q(q)).copy()   # crba fills the upper triangle only
        M[self._lower] = M.T[self._lower]
        return M

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
