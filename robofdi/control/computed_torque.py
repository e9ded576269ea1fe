"""Joint-space inverse-dynamics (computed-torque) control on the nominal model."""
from __future__ import annotations

import numpy as np

from robofdi import RobofdiError
from robofdi.models.manipulator import ManipulatorModel

__all__ = ["ComputedTorque"]


class ComputedTorque:
    """τ = M̂(q)(q̈_d + K_D(q̇_d − q̇) + K_P(q_d − q)) + n̂(q, q̇), clipped to the torque limits."""

    def __init__(self, model: ManipulatorModel, kp: float = 400.0, kd: float = 40.0, torque_limit=None):
        if not (kp > 0 and kd > 0):
            raise RobofdiError(f"ComputedTorque: fields 'kp' and 'kd' must be > 0, got {kp}, {kd}")
        self.model, self.kp, self.kd = model, float(kp), float(kd)
        self.torque_limit = None if torque_limit is None else np.asarray(torque_limit, dtype=float)

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        """y = [q; q̇] measured, reference = (q_d, q̇_d, q̈_d); returns the commanded torque."""
        n = self.model.n
        q, v = y[:n], y[n:]
        qd, vd, ad = reference
        a = ad + self.kd * (vd - v) + self.kp * (qd - q)
        tau = self.model.inverse_dynamics(q, v, a)
        limit = self.torque_limit
        if limit is not None:             # np.clip(tau, -limit, limit) without its Python wrapper (same numbers)
            tau = np.minimum(np.maximum(tau, -limit), limit)
        return tau
