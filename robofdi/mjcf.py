"""Model files for MuJoCo: finding them, compiling them, and reading an arm's drive table.

Used by the simulators (the truth) and the nominal models (the belief) alike, so both read a file the same way:
MJCF through MuJoCo's own compiler (``mujoco.MjSpec``: ``<include>``, ``<default>`` classes, degrees, meshes),
and URDF as ROS description packages ship it (:func:`urdf_to_mjcf`: ``package://`` mesh paths resolved, motors
from the joints' effort limits), turned into one MJCF file that both sides then read.
"""
from __future__ import annotations

import copy
import hashlib
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from robofdi import ASSETS, RobofdiError

__all__ = ["Drive", "CompiledArm", "compile_arm", "load_model", "model_xml", "fixed_distance_pairs", "resolve_asset",
           "is_torque_motor", "actuator_kind", "joint_actuators", "urdf_to_mjcf", "find_package_root", "URDF_TIMESTEP",
           "VELOCITY_LIMIT"]

_JOINT_KINDS = {int(mujoco.mjtJoint.mjJNT_HINGE): "hinge", int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
                int(mujoco.mjtJoint.mjJNT_BALL): "ball", int(mujoco.mjtJoint.mjJNT_FREE): "free"}
_JOINT_TRANSMISSIONS = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
_DEFAULT_MODEL_NAME = "MuJoCo Model"      # what MuJoCo calls a model whose <mujoco> has no name


def resolve_asset(path: str | Path) -> Path:
    """A file name of the shipped assets or a path; raises RobofdiError naming the file if it does not exist."""
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = ASSETS / p
    if p.exists() and not p.is_file():
        what = "a folder" if p.is_dir() else "not a regular file"
        raise RobofdiError(f"mjcf: {str(path)!r} is {what}; expected an MJCF or URDF file")
    if not p.is_file():
        raise RobofdiError(f"mjcf: file {str(path)!r} does not exist (looked in the working folder and {ASSETS})")
    return p


#: The largest physics step of an arm [s]: beyond it the stiff joint dynamics are not integrated (and a 1 kHz drive
#: loop cannot run); MuJoCo's default is 0.002 s.
MAX_ARM_TIMESTEP = 0.01
#: The largest joint torque range an arm may declare [N·m or N]: a bigger one is a unit slip or a placeholder.
MAX_TORQUE = 1e6


def check_model_text(path: Path) -> None:
    """Refuse what MuJoCo would read without complaint but not as written: a file that is not UTF-8 (named with the
    byte position), and a non-finite number (``nan``, ``inf``) in any attribute (MuJoCo replaces a NaN mass by a
    default of its own with one warning line). ``path``: an MJCF file."""
    import xml.etree.ElementTree as ET

    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RobofdiError(f"mjcf: {str(path)!r} is not UTF-8 text (byte {exc.start}: {exc.object[exc.start:exc.start + 1]!r}); "
                           "expected an MJCF/URDF XML file in UTF-8") from None
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return                                              # MuJoCo reports malformed XML with its own message
    for element in root.iter():
        for key, value in element.attrib.items():
            for token in value.split():
                try:
                    number = float(token)
                except ValueError:
                    continue
                if not np.isfinite(number):
                    name = element.get("name")
                    where = f"<{element.tag}{f' name={name!r}' if name else ''}>"
                    raise RobofdiError(f"mjcf: {path.name}: {where} attribute {key}={value!r} is not a finite number "
                                       "(MuJoCo would silently replace it); expected finite values")


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

    @property
    def without_armature(self) -> list[str]:
        """The arm joints the file gives no armature (rotor inertia): a drive without its rotor, as in a file that
        models the links only (a URDF, robosuite's raw ``robot.xml``); ``drive_inertia`` gives them one."""
        return [d.joint for d in self.drives if self.model.dof_armature[d.dof] <= 0]


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


def joint_actuators(m: mujoco.MjModel) -> dict[int, list[int]]:
    """joint id -> ids of the actuators driving it through a joint transmission."""
    out: dict[int, list[int]] = {}
    for a in range(m.nu):
        if int(m.actuator_trntype[a]) in _JOINT_TRANSMISSIONS:
            out.setdefault(int(m.actuator_trnid[a, 0]), []).append(a)
    return out


#: MuJoCo's refusal of a mesh too thin to be a solid (its message then advises shell inertia).
_THIN_MESH = re.compile(r"mesh volume is too small: (\S+)")


def _compile(spec: mujoco.MjSpec, path: Path) -> mujoco.MjModel:
    """``spec`` compiled. A mesh MuJoCo refuses as too thin to be a solid ("mesh volume is too small", e.g. the
    visual head shells of robosuite's raw sawyer ``robot.xml``, which robosuite's own loader leaves out of the
    inertia by its ``inertiagrouprange``) gets shell inertia, as MuJoCo's message advises; a body that declares its
    ``<inertial>`` keeps that mass and inertia either way."""
    shelled: set[str] = set()
    while True:
        try:
            return spec.compile()
        except Exception as exc:
            message = " ".join(str(exc).split())
            thin = _THIN_MESH.search(message)
            mesh = spec.mesh(thin.group(1)) if thin and thin.group(1) not in shelled else None
            if mesh is None:
                raise RobofdiError(f"mjcf: MuJoCo cannot compile {str(path)!r}: {message}") from None
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            shelled.add(thin.group(1))


def _read(path: Path) -> mujoco.MjSpec:
    try:
        return mujoco.MjSpec.from_file(str(path))
    except Exception as exc:
        raise RobofdiError(f"mjcf: MuJoCo cannot read {str(path)!r}: {' '.join(str(exc).split())}") from None


def load_model(mjcf: str | Path) -> mujoco.MjModel:
    """The MuJoCo model of the MJCF file ``mjcf`` (a shipped asset name or a path) as :func:`compile_arm` compiles it,
    with no arm read from it; raises RobofdiError naming the file if MuJoCo cannot read or compile it."""
    path = resolve_asset(mjcf)
    return _compile(_read(path), path)


def model_xml(mjcf: str | Path) -> str:
    """The MJCF text MuJoCo writes back for the file ``mjcf`` (includes, defaults and meshes resolved), with the
    meshes :func:`load_model` gives shell inertia marked so: what a cache keys a model file's content on."""
    path = resolve_asset(mjcf)
    spec = _read(path)
    probe = spec.copy()
    _compile(probe, path)
    for mesh in probe.meshes:
        if mesh.inertia == mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL:
            spec.mesh(mesh.name).inertia = mesh.inertia
    return spec.to_xml()


def _select_arm(m: mujoco.MjModel, path: Path, joints: Sequence[str] | None, torque_motors: bool) -> list[int]:
    """Ids of the arm joints, in the file's order (checked: hinge/slide, exactly one joint actuator each)."""
    actuated = joint_actuators(m)
    file = path.name
    names = [_name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    if joints is None:
        ids = [j for j in range(m.njnt) if _JOINT_KINDS.get(int(m.jnt_type[j])) in ("hinge", "slide")
               and any(is_torque_motor(m, a) or torque_motors for a in actuated.get(j, []))]
        if not ids:
            servos = [f"{names[j]!r} ({actuator_kind(m, a)})" for j, acts in actuated.items() for a in acts
                      if not is_torque_motor(m, a)]
            hint = (f"; its joint actuators are {', '.join(servos)}: pass torque_motors=True to turn them into motors"
                    if servos else "" if actuated else
                    f"; it has no joint actuators: give each arm joint a torque motor with its limit, e.g. in a file "
                    f"that includes it, <include file=\"{file}\"/><actuator><motor joint=\"...\" ctrlrange=\"-30 30\" "
                    f"ctrllimited=\"true\"/>...</actuator> (docs/howto/own-arm.md)")
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
    if max(abs(lo), abs(hi)) > MAX_TORQUE:
        raise RobofdiError(f"mjcf: actuator {_actuator_label(m, a)} on arm joint {joint!r} of {path.name}: torque range "
                           f"[{lo:g}, {hi:g}] (ctrlrange · gear · gain); expected at most {MAX_TORQUE:g} in magnitude")
    if not hi > lo:
        raise RobofdiError(f"mjcf: actuator {_actuator_label(m, a)} on arm joint {joint!r} of {path.name}: empty torque "
                           f"range [{lo}, {hi}]")
    return float(lo), float(hi)


def fixed_distance_pairs(m: mujoco.MjModel, joints: Sequence[int], margin: float, poses: int = 8) -> dict:
    """{(geom1, geom2): distance [m]} of the geom pairs within ``margin`` [m] (or their own larger margin) of each
    other at ``poses`` poses of the ``joints`` drawn over their ranges (one turn for an unlimited joint; a fixed
    draw, the other joints at their reference), at the same distance to 1 µm each time: links whose distance no joint
    changes, such as a cover turning about its joint's own axis. MuJoCo's collision detection on a copy of ``m``
    (contype/conaffinity, parent filter and excludes as the file sets them)."""
    scratch = copy.copy(m)
    scratch.geom_margin[:] = np.maximum(m.geom_margin, margin)
    d = mujoco.MjData(scratch)
    joints = np.asarray(joints, dtype=int)
    qadr = scratch.jnt_qposadr[joints]
    lo = np.where(scratch.jnt_limited[joints], scratch.jnt_range[joints, 0], -np.pi)
    hi = np.where(scratch.jnt_limited[joints], scratch.jnt_range[joints, 1], np.pi)
    draw = np.random.default_rng(0)
    seen = []
    for _ in range(poses):
        d.qpos[:] = scratch.qpos0
        d.qpos[qadr] = draw.uniform(lo, hi)
        mujoco.mj_kinematics(scratch, d)
        mujoco.mj_collision(scratch, d)
        pairs: dict[tuple[int, int], float] = {}
        for c in d.contact[:d.ncon]:
            pair = (int(c.geom1), int(c.geom2))
            pairs[pair] = min(pairs.get(pair, np.inf), float(c.dist))
        seen.append(pairs)
    fixed = {}
    for pair in set(seen[0]).intersection(*seen[1:]):
        distances = [pairs[pair] for pairs in seen]
        if max(distances) - min(distances) < 1e-6:
            fixed[pair] = float(np.mean(distances))
    return fixed


def _exclude_bearings(spec: mujoco.MjSpec, m: mujoco.MjModel, ids: Sequence[int]) -> bool:
    """Exclude in ``spec`` the contacts of the links that touch at every pose of the arm (:func:`fixed_distance_pairs`
    at the geoms' own margin): a surface resting on the link below it and turning about the same axis (robosuite's
    raw sawyer file has its shoulder sphere on the base cylinder) is a bearing, which MuJoCo's parent filter leaves in
    only because the lower link is fixed to the world. Left in, its contact friction brakes the joint, a drag no
    drive has. Returns whether anything changed."""
    bodies = set()
    for g1, g2 in fixed_distance_pairs(m, ids, 0.0):
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        if b1 != b2:
            bodies.add((min(b1, b2), max(b1, b2)))
    changed = False
    for pair in sorted(bodies):
        names = [_name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in pair]
        if all(names):                            # an exclude names its bodies; an unnamed one keeps its contact
            spec.add_exclude(bodyname1=names[0], bodyname2=names[1])
            changed = True
    return changed


def _to_motors(spec: mujoco.MjSpec, m: mujoco.MjModel, ids: list[int], path: Path) -> bool:
    """Turn the non-motor actuators of the arm joints into motors in ``spec`` (``actuator.set_to_motor()``),
    keeping the servo's force bound (forcerange, else the joint's actuatorfrcrange) as the torque limit.
    Returns whether anything changed."""
    actuated = joint_actuators(m)
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


def _drive_inertia(spec: mujoco.MjSpec, m: mujoco.MjModel, drives: Sequence[Drive], ratio: float) -> bool:
    """Give every arm joint whose armature is below ``ratio`` × its drive's torque limit that armature in ``spec``
    (the reflected rotor inertia of a geared drive of that size). Returns whether anything changed."""
    changed = False
    for d in drives:
        floor = ratio * d.torque_limit
        if m.dof_armature[d.dof] < floor:
            spec.joint(d.joint).armature = floor
            changed = True
    return changed


def compile_arm(mjcf: str | Path, joints: Sequence[str] | None = None, torque_motors: bool = False,
                drive_inertia: float = 0.0) -> CompiledArm:
    """Compile ``mjcf`` with ``mujoco.MjSpec.from_file`` and read its arm: the joints (``joints``, or every
    hinge/slide joint driven by a motor-type actuator; with ``torque_motors``, by any joint actuator) and, per
    joint, the actuator driving it through a joint transmission, its gain and its torque range.
    ``torque_motors``: convert the arm joints' servos into motors. ``drive_inertia`` [kg·m²/(N·m) = s²]: every arm
    joint gets an armature (rotor inertia) of at least ``drive_inertia`` × its torque limit; 0 (the default) keeps
    the file's. A file that models the links only (robosuite's raw ``robot.xml`` files have no armature, a URDF has
    none) describes a drive without its rotor; the drives of robofdi's arm6 and arm7 have 0.002–0.023 s².
    A ``.urdf`` file is first turned into MJCF (:func:`urdf_to_mjcf`); the returned ``path`` is then that MJCF
    file, the one simulator and belief both read."""
    path = resolve_asset(mjcf)
    if path.suffix.lower() == ".urdf":
        path = urdf_to_mjcf(path)
    if not isinstance(torque_motors, bool):
        raise RobofdiError(f"torque_motors: expected True or False, got {torque_motors!r}")
    if isinstance(drive_inertia, bool) or not isinstance(drive_inertia, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(drive_inertia) and drive_inertia >= 0):
        raise RobofdiError(f"drive_inertia: expected a finite armature per unit torque limit >= 0 s², "
                           f"got {drive_inertia!r}")
    try:
        key = (str(path.resolve()), path.stat().st_mtime_ns, path.stat().st_size,
               None if joints is None else tuple(joints), torque_motors, float(drive_inertia))
        hash(key)
    except (OSError, TypeError):
        key = None                               # not cacheable (e.g. unhashable joints): compiled, then checked
    if key is None:
        return _compile_arm(path, joints, torque_motors, float(drive_inertia))
    template = _COMPILED.get(key)
    if template is None:
        template = _compile_arm(path, joints, torque_motors, float(drive_inertia))
        if len(_COMPILED) >= _COMPILED_SIZE:
            _COMPILED.pop(next(iter(_COMPILED)))
        _COMPILED[key] = template
    return replace(template, model=copy.copy(template.model))     # each caller its own MjModel (faults change it)


#: Compiled arms by (file, its mtime and size, joints, torque_motors, drive_inertia): a file is compiled once per
#: process (a robosuite arm with meshes takes seconds), and every caller gets its own copy of the MjModel.
_COMPILED: dict[tuple, CompiledArm] = {}
_COMPILED_SIZE = 16


def _compile_arm(path: Path, joints, torque_motors: bool, drive_inertia: float) -> CompiledArm:
    check_model_text(path)
    spec = _read(path)
    m = _compile(spec, path)
    if not 0 < m.opt.timestep <= MAX_ARM_TIMESTEP:
        raise RobofdiError(f"mjcf: {path.name}: <option timestep> is {m.opt.timestep:g} s; expected a physics step in "
                           f"(0, {MAX_ARM_TIMESTEP:g}] s for an arm (MuJoCo's default is 0.002 s)")
    ids = _select_arm(m, path, joints, torque_motors)
    if _exclude_bearings(spec, m, ids):
        m = _compile(spec, path)
    if torque_motors and _to_motors(spec, m, ids, path):
        m = _compile(spec, path)
    drives = _drives(m, ids, path)
    if drive_inertia > 0 and _drive_inertia(spec, m, drives, float(drive_inertia)):
        m = _compile(spec, path)
        drives = _drives(m, ids, path)
    system = spec.modelname if spec.modelname and spec.modelname != _DEFAULT_MODEL_NAME else path.stem
    return CompiledArm(path, m, system, tuple(drives))


def _drives(m: mujoco.MjModel, ids: Sequence[int], path: Path) -> list[Drive]:
    """The drive table of the arm joints ``ids`` of the compiled model ``m``."""
    actuated = joint_actuators(m)
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
    return drives


# ---------------------------------------------------------------------------------------------------------------
# URDF, as ROS description packages ship it
# ---------------------------------------------------------------------------------------------------------------
#: Physics step [s] of an arm read from URDF (URDF has none): 1 ms, a 1 kHz drive loop.
URDF_TIMESTEP = 1e-3
#: Name of the <custom> numeric holding the arm joints' velocity limits [rad/s or m/s] (read by the nominal model).
VELOCITY_LIMIT = "robofdi_velocity_limit"
#: Name of the <custom> numeric holding the arm joints' gear ratios (dimensionless, the drives' datasheet values),
#: and the ratio of a joint whose file gives none.
GEAR_RATIO, DEFAULT_GEAR_RATIO = "robofdi_gear_ratio", 100.0


def custom_numeric(m: mujoco.MjModel, name: str) -> np.ndarray | None:
    """The data of ``<custom><numeric name=...>`` of a compiled model, None when the file has none."""
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, name)
    return None if i < 0 else np.array(m.numeric_data[m.numeric_adr[i]: m.numeric_adr[i] + m.numeric_size[i]])


def custom_text(m: mujoco.MjModel, name: str) -> str | None:
    """The data of ``<custom><text name=...>`` of a compiled model, None when the file has none."""
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TEXT, name)
    if i < 0:
        return None
    raw = bytes(m.text_data[m.text_adr[i]: m.text_adr[i] + m.text_size[i]])
    return raw.split(b"\0", 1)[0].decode("utf-8").strip()


def payload_point(arm: CompiledArm) -> tuple[str, np.ndarray]:
    """(body, offset (3,) [m] in its frame) of the arm's payload point from ``<text name="robofdi_payload_body">``
    and ``<numeric name="robofdi_payload_offset">`` (defaults: the body of the last arm joint, offset 0): where the
    plant's ``payload`` and "payload" mass faults put their mass, and where the payload hypothesis looks for it."""
    m, file = arm.model, arm.path.name
    body = custom_text(m, "robofdi_payload_body") or arm.drives[-1].body
    if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body) < 0:
        raise RobofdiError(f"mjcf: <text name='robofdi_payload_body'> of {file} names {body!r}, which is not a body")
    offset = custom_numeric(m, "robofdi_payload_offset")
    if offset is None:
        offset = np.zeros(3)
    elif offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise RobofdiError(f"mjcf: <numeric name='robofdi_payload_offset'> of {file} must hold 3 finite values "
                           f"x y z [m], got {offset.tolist()}")
    return body, offset


def gear_ratio(arm: CompiledArm) -> np.ndarray:
    """(n,) gear ratios of the arm joints from ``<numeric name="robofdi_gear_ratio">`` (one per arm joint;
    :data:`DEFAULT_GEAR_RATIO` each when the file gives none): a datasheet value, which the plant's torque ripple
    and the diagnosers' ripple orders both read."""
    n = len(arm.drives)
    gear = custom_numeric(arm.model, GEAR_RATIO)
    if gear is None:
        return np.full(n, DEFAULT_GEAR_RATIO)
    if gear.shape != (n,) or not np.all(np.isfinite(gear) & (gear > 0)):
        raise RobofdiError(f"mjcf: <numeric name='{GEAR_RATIO}'> of {arm.path.name} must hold {n} finite values > 0 "
                           f"(one per arm joint {arm.joint_names}), got {gear.tolist()}")
    return gear


def _package_name(folder: Path) -> str | None:
    """The <name> of ``folder``/package.xml, None when there is none (or it cannot be read)."""
    manifest = folder / "package.xml"
    if not manifest.is_file():
        return None
    try:
        name = ET.parse(manifest).getroot().findtext("name")
    except (ET.ParseError, OSError):
        return None
    return name.strip() if name else None


def find_package_root(package: str, start: str | Path | None = None) -> Path | None:
    """The folder of ROS package ``package`` (the one whose package.xml names it; catkin/ament convention): searched
    upward from ``start`` (each ancestor and its sub-folders, as in a workspace's src/), then in every folder of
    $ROS_PACKAGE_PATH (os.pathsep-separated; the folder itself and its sub-folders to three levels). None if not found."""
    def candidates(folder: Path, depth: int):
        yield folder
        if depth > 0:
            try:
                subs = sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith("."))
            except OSError:
                return
            for sub in subs:
                yield from candidates(sub, depth - 1)

    searched: list[tuple[Path, int]] = []
    if start is not None:
        here = Path(start).resolve()
        searched += [(folder, 1) for folder in [here, *here.parents]]
    searched += [(Path(p), 3) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    for folder, depth in searched:
        for candidate in candidates(folder, depth):
            if _package_name(candidate) == package:
                return candidate
    return None


def _resolve_mesh(filename: str, urdf: Path) -> Path:
    """A URDF mesh filename as a file: ``package://<pkg>/<path>`` against the package root
    (:func:`find_package_root`), ``file://<path>``, or a path relative to the URDF's folder."""
    if filename.startswith("package://"):
        rest = filename[len("package://"):]
        package, _, inner = rest.partition("/")
        root = find_package_root(package, urdf.parent)
        if root is None:
            raise RobofdiError(
                f"urdf: {urdf.name}: mesh {filename!r} names package {package!r}, but no package.xml with "
                f"<name>{package}</name> was found above {str(urdf.parent)!r} or in $ROS_PACKAGE_PATH; expected the "
                "description package's folder (or set ROS_PACKAGE_PATH)")
        path = root / inner
    elif filename.startswith("file://"):
        path = Path(filename[len("file://"):])
    else:
        path = Path(filename) if Path(filename).is_absolute() else urdf.parent / filename
    if not path.is_file():
        raise RobofdiError(f"urdf: {urdf.name}: mesh {filename!r} resolves to {str(path)!r}, which does not exist; "
                           "expected a mesh file there")
    return path.resolve()


def _cache_dir() -> Path:
    """Where generated model files go: $ROBOFDI_CACHE/models, else ~/.cache/robofdi/models."""
    return Path(os.environ.get("ROBOFDI_CACHE") or Path.home() / ".cache" / "robofdi") / "models"


def urdf_to_mjcf(urdf: str | Path, out_dir: str | Path | None = None) -> Path:
    """Turn a URDF (as a ROS description package ships it) into one MJCF file, the file both the simulator and
    the nominal model then read, and return its path (``out_dir``, default $ROBOFDI_CACHE/models; the name carries
    a hash of the generated MJCF, so a changed URDF gives a new file).

    What the conversion does and assumes (URDF carries no actuators, no physics step, no rotor inertia):

    * mesh filenames ``package://<pkg>/...`` are resolved against the package root (the folder whose package.xml
      names ``<pkg>``, searched upward from the URDF and in $ROS_PACKAGE_PATH), ``file://`` and relative paths
      against the URDF's folder; the MJCF refers to them by absolute path;
    * MuJoCo's own URDF reader builds the bodies: ``<inertial>`` as given, ``<dynamics damping friction>`` as
      joint ``damping`` [N·m·s/rad] and Coulomb ``frictionloss`` [N·m], ``<limit lower upper>`` as the joint
      range (continuous joints: unlimited), ``<limit effort>`` as the joint's ``actuatorfrcrange``, fixed joints
      fused into their parent body;
    * every revolute, continuous or prismatic joint with ``effort`` > 0 gets a torque motor (gear 1,
      ctrlrange = ±effort [N·m or N]); joints without an effort limit get none;
    * ``<limit velocity>`` [rad/s or m/s] of the motor joints is kept as ``<numeric name="robofdi_velocity_limit">``
      (0 = none given) for the motion design; the simulator does not enforce it;
    * armature (rotor inertia) 0, physics step :data:`URDF_TIMESTEP`, integrator implicitfast, gravity −9.81 m/s²
      along z; the base link is fixed to the world.

    Raises RobofdiError naming the file for XML that cannot be parsed, a root that is not <robot>, a mesh that
    cannot be found, or a model MuJoCo cannot compile.
    """
    path = resolve_asset(urdf)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise RobofdiError(f"urdf: {str(path)!r} is not well-formed XML ({exc}); expected a URDF <robot>") from None
    if root.tag != "robot":
        raise RobofdiError(f"urdf: {str(path)!r} has root element <{root.tag}>; expected <robot>")
    if not root.findall("link"):
        raise RobofdiError(f"urdf: {str(path)!r} has no <link>; expected a robot with links and joints")
    for mesh in root.iter("mesh"):
        name = mesh.get("filename")
        if not name:
            raise RobofdiError(f"urdf: {path.name}: a <mesh> has no 'filename'; expected a mesh file")
        mesh.set("filename", str(_resolve_mesh(name, path)))
    motors = []
    for joint in root.findall("joint"):
        limit = joint.find("limit")
        if joint.get("type") in ("revolute", "continuous", "prismatic") and limit is not None:
            try:
                effort, velocity = float(limit.get("effort", "0")), float(limit.get("velocity", "0"))
            except ValueError:
                raise RobofdiError(f"urdf: {path.name}: joint {joint.get('name')!r} has a non-numeric <limit effort "
                                   "velocity>; expected numbers") from None
            if effort > 0 and np.isfinite(effort):
                motors.append((joint.get("name"), effort, velocity if np.isfinite(velocity) and velocity > 0 else 0.0))
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except Exception as exc:
        raise RobofdiError(f"urdf: MuJoCo cannot read {str(path)!r}: {' '.join(str(exc).split())}") from None
    spec.option.timestep = URDF_TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    for name, effort, _ in motors:
        spec.add_actuator(name=f"{name}_motor", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                          ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE, ctrlrange=[-effort, effort])
    if motors:
        spec.add_numeric(name=VELOCITY_LIMIT, data=[v for _, _, v in motors])
    _compile(spec, path)
    xml = spec.to_xml()
    out = Path(out_dir) if out_dir is not None else _cache_dir()
    target = out / f"{path.stem}-{hashlib.sha256(xml.encode()).hexdigest()[:16]}.xml"
    if not target.is_file():
        try:
            out.mkdir(parents=True, exist_ok=True)
            tmp = target.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(xml)
            tmp.replace(target)
        except OSError as exc:
            raise RobofdiError(f"urdf: cannot write the MJCF of {path.name} to {str(out)!r} ({exc}); expected a "
                               "writable folder (set ROBOFDI_CACHE)") from None
    return target
