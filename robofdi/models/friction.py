"""Joint friction as engineers identify it: Coulomb + viscous + Stribeck, per joint.

    τ_f,i(q̇) = F_c,i tanh(q̇_i/ε) + F_v,i q̇_i + F_s,i exp(−(q̇_i/v_s)²) tanh(q̇_i/ε) + τ_0,i

(Armstrong-Hélouvry, Dupont & Canudas de Wit 1994, Automatica 30(7), the static + Coulomb + viscous + Stribeck
model, with tanh smoothing of the sign). τ_f is the torque the joint loses to friction [N·m, N for a slide joint]:
the robot obeys M q̈ + C q̇ + g + τ_f(q̇) = τ. τ_0 absorbs a constant torque offset (sensor or cogging bias).
The model is linear in its four coefficients, so it is identified by least squares (see
:func:`robofdi.observers.momentum.identify_friction`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.jit import kernel

__all__ = ["JointFriction"]


@dataclass(frozen=True, eq=False)
class JointFriction:
    """Per-joint coefficients (each an (n,) array): ``coulomb`` F_c, ``viscous`` F_v [N·m·s/rad], ``stribeck``
    F_s (the breakaway excess), ``offset`` τ_0; shared shape parameters ``stribeck_velocity`` v_s and
    ``smoothing`` ε [rad/s]."""

    coulomb: np.ndarray
    viscous: np.ndarray
    stribeck: np.ndarray
    offset: np.ndarray
    stribeck_velocity: float = 0.05
    smoothing: float = 0.01

    def __post_init__(self):
        n = None
        for name in ("coulomb", "viscous", "stribeck", "offset"):
            a = np.array(getattr(self, name), dtype=float)
            if a.ndim != 1 or not np.all(np.isfinite(a)):
                raise RobofdiError(f"JointFriction: field {name!r} must be a finite 1-D array, got {getattr(self, name)!r}")
            if n is not None and a.shape != (n,):
                raise RobofdiError(f"JointFriction: field {name!r} must have {n} entries like 'coulomb', got {a.shape[0]}")
            n = a.shape[0]
            object.__setattr__(self, name, a)
        for name in ("stribeck_velocity", "smoothing"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"JointFriction: field {name!r} must be a velocity > 0 rad/s, got {v!r}")

    @property
    def n(self) -> int:
        return self.coulomb.shape[0]

    @property
    def coefficients(self) -> np.ndarray:
        """(n, 4): [F_c, F_v, F_s, τ_0] per joint, the order of :meth:`regressors`."""
        return np.stack([self.coulomb, self.viscous, self.stribeck, self.offset], axis=-1)

    @classmethod
    def from_coefficients(cls, coefficients: np.ndarray, stribeck_velocity: float = 0.05,
                          smoothing: float = 0.01) -> JointFriction:
        c = np.asarray(coefficients, dtype=float)
        if c.ndim != 2 or c.shape[1] != 4:
            raise RobofdiError(f"JointFriction: coefficients must be an (n, 4) array, got shape {c.shape}")
        return cls(c[:, 0], c[:, 1], c[:, 2], c[:, 3], stribeck_velocity, smoothing)

    @staticmethod
    def regressors(v: np.ndarray, stribeck_velocity: float = 0.05, smoothing: float = 0.01) -> np.ndarray:
        """(..., n, 4) regressors of the model at joint velocities v (..., n) [rad/s]."""
        v = np.asarray(v, dtype=float)
        sign = np.tanh(v / smoothing)
        return np.stack([sign, v, np.exp(-(v / stribeck_velocity) ** 2) * sign, np.ones_like(v)], axis=-1)

    def torque(self, v: np.ndarray) -> np.ndarray:
        """τ_f(q̇) [N·m] at joint velocities v (..., n)."""
        if type(v) is np.ndarray and v.shape == (self.n,) and v.dtype == np.float64:
            # one sample (an observer's hot path): the arithmetic compiled (:func:`_friction_arguments`,
            # :func:`_friction_sum`), tanh and exp NumPy's on the same arguments as below, so the same bits
            arguments = np.empty((2, v.shape[0]))
            _friction_arguments(v, self.smoothing, self.stribeck_velocity, arguments)
            out = np.empty(v.shape[0])
            _friction_sum(np.tanh(arguments[0]), np.exp(arguments[1]), v, self.coulomb, self.stribeck,
                          self.viscous, self.offset, out)
            return out
        sign = np.tanh(np.asarray(v, dtype=float) / self.smoothing)
        return ((self.coulomb + self.stribeck * np.exp(-(v / self.stribeck_velocity) ** 2)) * sign
                + self.viscous * v + self.offset)


@kernel
def _friction_arguments(v, smoothing, stribeck_velocity, arguments):
    """The arguments of :meth:`JointFriction.torque`'s tanh (q̇/ε) and exp (−(q̇/v_s)²), into ``arguments`` (2, n)."""
    for i in range(v.shape[0]):
        arguments[0, i] = v[i] / smoothing
        x = v[i] / stribeck_velocity
        arguments[1, i] = -(x * x)


@kernel
def _friction_sum(sign, bump, v, coulomb, stribeck, viscous, offset, out):
    """(F_c + F_s exp(…)) tanh(…) + F_v q̇ + τ_0 entry by entry, in the order of operations of the array form."""
    for i in range(v.shape[0]):
        out[i] = (coulomb[i] + stribeck[i] * bump[i]) * sign[i] + viscous[i] * v[i] + offset[i]


# The batch forms of the kernels above (robofdi.lockstep): on every run's rows, one call a sample for all runs.
@kernel
def _friction_arguments_each(V, smoothing, stribeck_velocity, arguments):
    """The arguments per run (velocities V (a, n), ``smoothing`` and ``stribeck_velocity`` (≥ a,), ``arguments``
    (2, a, n)): _friction_arguments."""
    for i in range(V.shape[0]):
        _friction_arguments(V[i], smoothing[i], stribeck_velocity[i], arguments[:, i])


@kernel
def _friction_sum_each(sign, bump, V, coulomb, stribeck, viscous, offset, out):
    """τ̂_f per run (``out`` (a, n); the coefficients (≥ a, n)): _friction_sum."""
    for i in range(out.shape[0]):
        _friction_sum(sign[i], bump[i], V[i], coulomb[i], stribeck[i], viscous[i], offset[i], out[i])
