"""Nominal manipulator model (the diagnoser's belief), built with Pinocchio from an MJCF file.

The plant is simulated by MuJoCo from the same file; here we read only the file, never the MuJoCo model,
and perturb the parameters on purpose (:class:`ModelMismatch`) so that diagnosers face real model error.
Pinocchio's ``crba``/``aba`` include the joint armature read from the MJCF; ``nonLinearEffects`` does not
include damping, so the nominal bias is n̂ = nle(q, q̇) + D̂ q̇ (viscous friction, eq. (2) of Caccavale &
Villani); Coulomb friction is deliberately left out of the belief.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from robofdi import ASSETS, RobofdiError

__all__ = ["ModelMismatch", "ManipulatorModel", "resolve_asset"]


def resolve_asset(path: str | Path) -> Path:
    """A file name of the shipped assets or a path; raises RobofdiError naming the file if it does not exist."""
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = ASSETS / p
    if not p.is_file():
        raise RobofdiError(f"mjcf: file {str(path)!r} does not exist (looked in the working folder and {ASSETS})")
    return p


@dataclass(frozen=True)
class ModelMismatch:
    """Deliberate errors of the nominal parameters, as relative 1-sigma errors drawn with ``seed``
    (normal draws truncated at ±2σ, so with σ < 0.5 every parameter keeps its sign).

    mass: link masses (and the rotational inertias scale with them); inertia: extra error on the
    rotational inertias; damping: viscous friction coefficients; armature: rotor inertias.
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


def _motor_limits(path: Path, joints: list[str]) -> np.ndarray:
    """Motor torque limits (datasheet knowledge) from the MJCF's <motor ctrlrange>; inf where none is given."""
    import xml.etree.ElementTree as ET

    limits = dict.fromkeys(joints, np.inf)
    for motor in ET.parse(path).getroot().iter("motor"):
        rng = motor.get("ctrlrange")
        if motor.get("joint") in limits and rng:
            limits[motor.get("joint")] = max(abs(float(v)) for v in rng.split())
    return np.array([limits[j] for j in joints])


class ManipulatorModel:
    """M̂(q), n̂(q, q̇) of an n-joint serial arm — the nominal model of eq. (3)."""

    def __init__(self, mjcf: str | Path, mismatch: ModelMismatch | None = None):
        mismatch = mismatch or ModelMismatch()
        self.path = resolve_asset(mjcf)
        try:
            model = pin.buildModelFromMJCF(str(self.path))
        except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError on malformed XML
            raise RobofdiError(f"mjcf: cannot build a Pinocchio model from {str(self.path)!r}: {exc}") from None
        self.mismatch = mismatch
        self._perturb(model, mismatch)
        self.model = model
        self.data = model.createData()
        self.joint_names = [model.names[i] for i in range(1, model.njoints)]
        self.n = model.nv
        self.damping = np.array(model.damping, dtype=float)
        self.torque_limit = _motor_limits(self.path, self.joint_names)
        self._lower = np.tril_indices(self.n, -1)

    @staticmethod
    def _perturb(model: pin.Model, mm: ModelMismatch) -> None:
        rng = np.random.default_rng(mm.seed)

        def factor(sigma, size=None):
            return 1.0 + sigma * np.clip(rng.standard_normal(size), -2.0, 2.0)

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

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M̂(q), symmetric, armature included."""
        M = pin.crba(self.model, self.data, q).copy()   # crba fills the upper triangle only
        M[self._lower] = M.T[self._lower]
        return M

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """n̂(q, q̇) = C(q, q̇) q̇ + g(q) + D̂ q̇."""
        return pin.nonLinearEffects(self.model, self.data, q, v) + self.damping * v

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """τ = M̂(q) q̈ + n̂(q, q̇) (RNEA, armature included, plus viscous friction)."""
        return pin.rnea(self.model, self.data, q, v, a) + self.damping * v

    def gravity(self, q: np.ndarray) -> np.ndarray:
        return pin.computeGeneralizedGravity(self.model, self.data, q)

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """C(q, q̇) with Ṁ = C + Cᵀ (Pinocchio's factorisation)."""
        return pin.computeCoriolisMatrix(self.model, self.data, q, v)

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q̈ = M̂⁻¹(τ − n̂) (forward dynamics with viscous friction)."""
        return pin.aba(self.model, self.data, q, v, tau - self.damping * v)
