"""Discrete-time generalised-momentum observer — the industrial baseline residual for collision and actuator-fault
detection (De Luca & Mattone, ICRA 2003, eq. (10), discretised with the forward Euler rule):

    r(k) = K_O ( M̂(q_k) q̇_k − p₀ − Σ_{j<k} T (ū_j + Ĉᵀ(q_j, q̇_j) q̇_j − ĝ(q_j) − D̂ q̇_j + r_j) )

r is a first-order low-pass estimate of the unmodelled joint torque δτ (N·m), bandwidth K_O.
"""
from __future__ import annotations

import numpy as np

from robofdi import RobofdiError
from robofdi.models.manipulator import ManipulatorModel
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["MomentumObserver"]


class MomentumObserver:
    """Residual components ``joint{i}`` in N·m; the residual is also the actuator-fault estimate."""

    def __init__(self, model: ManipulatorModel, T: float, gain: float = 50.0):
        if not (np.isfinite(T) and T > 0):
            raise RobofdiError(f"MomentumObserver: field 'T' must be a positive sample time, got {T}")
        if not (np.isfinite(gain) and 0 < gain * T < 1):
            raise RobofdiError(f"MomentumObserver: field 'gain' must be in (0, 1/T) = (0, {1 / T:g}), got {gain}")
        self.model, self.T, self.gain, self.n = model, float(T), float(gain), model.n
        self.inputs = list(model.joint_names)
        self.measurements = [f"{j}_pos" for j in model.joint_names] + [f"{j}_vel" for j in model.joint_names]
        self.components = list(model.joint_names)
        self.estimate_components = list(model.joint_names)
        self.estimate_modes = ["level"] * self.n
        self.units = {"residual": ["N·m"] * self.n, "estimate": ["N·m"] * self.n}
        self.reset()

    def reset(self) -> None:
        self._prev = None

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y = [q; q̇](k), u = ū(k−1)."""
        n, m = self.n, self.model
        y = check_measurement(y, 2 * n, "y")
        u = check_measurement(u, n, "u")
        q, v = y[:n], y[n:]
        p = m.mass_matrix(q) @ v
        if self._prev is None:
            self._p0, self._integral, self._r = p, np.zeros(n), np.zeros(n)
        else:
            qp, vp = self._prev
            beta = m.gravity(qp) + m.damping * vp - m.coriolis(qp, vp).T @ vp
            self._integral = self._integral + self.T * (u - beta + self._r)
            self._r = self.gain * (p - self._p0 - self._integral)
        self._prev = (q, v)
        return Residual(self._r.copy(), self._r.copy())

    def signatures(self):
        from robofdi.decision import Signature

        return [Signature(j, frozenset([j])) for j in self.model.joint_names]
