"""Nominal model of a (possibly underactuated) MuJoCo multibody: every hinge/slide joint, with the actuators mapped
onto the joints by an actuation matrix.

The arm model (:class:`~robofdi.models.manipulator.ManipulatorModel`) keeps only actuated joints and locks the
rest; a cart-pole, a finger with its free spinner or any underactuated system needs every degree of freedom in the
dynamics. :class:`MultibodyModel` is the same Pinocchio rigid-body model (:func:`pinocchio_model`, same mismatch)
over all hinge/slide joints, plus the actuation matrix B (nv × nu) of the equation of motion
M(q) q̈ + n(q, q̇) = B u (e.g. Spong, *Underactuated mechanical systems*, 1998, eq. (1)); unactuated joints have a
zero row of B.
"""
from __future__ import annotations

import mujoco
import numpy as np

from robofdi.errors import RobofdiError
from robofdi.mjcf import _JOINT_KINDS, _JOINT_TRANSMISSIONS, _name, actuator_kind, is_torque_motor
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, pinocchio_model

__all__ = ["MultibodyModel", "actuation_matrix"]


def actuation_matrix(m: mujoco.MjModel, joint_ids: list[int], actuators: list[int] | None = None) -> np.ndarray:
    """B (len(joint_ids) × len(actuators)): joint torque [N·m] or force [N] per unit of each actuator's ctrl
    (gear · gain); ``actuators``: MuJoCo actuator ids (default all). Every one must be a motor on one of the joints
    (a joint transmission, fixed gain, no bias, no dynamics)."""
    dof = {j: k for k, j in enumerate(joint_ids)}
    actuators = list(range(m.nu)) if actuators is None else list(actuators)
    B = np.zeros((len(joint_ids), len(actuators)))
    for col, a in enumerate(actuators):
        label = _name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"#{a}"
        if int(m.actuator_trntype[a]) not in _JOINT_TRANSMISSIONS or int(m.actuator_trnid[a, 0]) not in dof:
            raise RobofdiError(f"model: actuator {label!r} does not drive a hinge/slide joint; expected joint "
                               "transmissions only (tendon and site actuators are not supported)")
        if not is_torque_motor(m, a):
            raise RobofdiError(f"model: actuator {label!r} is {actuator_kind(m, a)}; expected a torque motor")
        B[dof[int(m.actuator_trnid[a, 0])], col] = m.actuator_gear[a, 0] * m.actuator_gainprm[a, 0]
    return B


class MultibodyModel(ManipulatorModel):
    """M̂(q), n̂(q, q̇) over every hinge/slide joint of ``m`` and the actuation matrix :attr:`B` (nv × nu).

    ``m``: a MuJoCo model compiled from the MJCF file (not the running simulator's: the belief is read from the
    file). Free and ball joints are refused. The dynamics methods are :class:`ManipulatorModel`'s; the joint torque
    of an action u is ``B @ u`` (:meth:`joint_torque`).

    ``joints``: the joint names to model (in tree order), e.g. a robot's arm in a scene with objects and a gripper;
    every other joint (free objects included) is locked at its reference and its bodies are lumped into the modelled
    joint that carries them (objects on the world: into the fixed base). The actuators are then those driving the
    listed joints. Default: every joint.
    """

    def __init__(self, m: mujoco.MjModel, system: str, mismatch: ModelMismatch | None = None,
                 joints: list[str] | None = None):
        mismatch = mismatch or ModelMismatch()
        if not isinstance(mismatch, ModelMismatch):
            raise RobofdiError(f"mismatch: expected a ModelMismatch, got {type(mismatch).__name__}")
        all_names = [_name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
        if joints is None:
            ids = list(range(m.njnt))
        else:
            unknown = [j for j in joints if j not in all_names]
            if unknown or not joints:
                raise RobofdiError(f"joints: {unknown or joints} are not joints of {system}; expected names among {all_names}")
            ids = [all_names.index(j) for j in joints]
            if ids != sorted(ids):
                raise RobofdiError(f"joints: list them in the model's order, got {list(joints)}")
        kinds = [_JOINT_KINDS.get(int(m.jnt_type[j]), "unknown") for j in ids]
        bad = [f"{all_names[j] or j} ({k})" for j, k in zip(ids, kinds) if k not in ("hinge", "slide")]
        if bad:
            raise RobofdiError(f"model: {system} has joints {', '.join(bad)}; expected hinge and slide joints only")
        names = [all_names[j] or f"joint{j}" for j in ids]
        self.path, self.system, self.mismatch = None, system, mismatch
        model = pinocchio_model(m, ids)
        model.name = system
        self._perturb(model, mismatch)
        self.model, self.data = model, model.createData()
        self.joint_names, self.n = names, model.nv
        self.joint_kinds = kinds            # "hinge" / "slide" per joint
        self.damping = np.array(model.damping, dtype=float)
        chosen = set(ids)
        acts = [a for a in range(m.nu) if joints is None or (int(m.actuator_trntype[a]) in _JOINT_TRANSMISSIONS
                                                             and int(m.actuator_trnid[a, 0]) in chosen)]
        self.B = actuation_matrix(m, ids, acts)
        self.actuator_names = [_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"actuator{a}" for a in acts]
        lim = np.where(m.actuator_ctrllimited[acts, None].astype(bool), m.actuator_ctrlrange[acts], [-np.inf, np.inf])
        self.torque_range = np.sort(np.abs(self.B).sum(axis=0)[:, None] * lim, axis=1) if acts else np.zeros((0, 2))
        self.torque_limit = np.abs(self.torque_range).max(axis=1) if acts else np.zeros(0)
        self.joint_range = np.where(m.jnt_limited[ids, None].astype(bool), m.jnt_range[ids], [-np.inf, np.inf])
        self._ref = np.array([m.qpos0[m.jnt_qposadr[j]] for j in ids])
        self._has_ref = bool(np.any(self._ref != 0))
        self._lower = np.tril_indices(self.n, -1)

    @property
    def actuated(self) -> list[str]:
        """Joints with a non-zero row of B."""
        return [j for j, row in zip(self.joint_names, self.B) if np.any(row)]

    def joint_torque(self, u: np.ndarray) -> np.ndarray:
        """τ = B u [N·m or N per joint] of the action u."""
        return self.B @ np.asarray(u, dtype=float)
