"""Joint-space inverse-dynamics (computed-torque) control on the nominal model."""
from __future__ import annotations

import numpy as np

from robofdi import RobofdiError
from robofdi.jit import kernel
from robofdi.models.manipulator import ManipulatorModel

__all__ = ["ComputedTorque"]


class ComputedTorque:
    """τ = M̂(q)(q̈_d + K_D(q̇_d − q̇) + K_P(q_d − q)) + n̂(q, q̇), clipped to the torque limits."""

    def __init__(self, model: ManipulatorModel, kp: float = 400.0, kd: float = 40.0, torque_limit=None):
        if not (kp > 0 and kd > 0):
            raise RobofdiError(f"ComputedTorque: fields 'kp' and 'kd' must be > 0, got {kp}, {kd}")
        self.model, self.kp, self.kd = model, float(kp), float(kd)
        self.torque_limit = None if torque_limit is None else np.asarray(torque_limit, dtype=float)
        n = model.n
        self._shape, self._y_shape = (n,), (2 * n,)
        # ManipulatorModel.inverse_dynamics returns a fresh float array of n entries (Pinocchio's result plus the
        # viscous term): clipped in place without checking it every tick
        self._clip_in_place = (type(model) is ManipulatorModel and self.torque_limit is not None
                               and self.torque_limit.shape == self._shape)

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        """y = [q; q̇] measured, reference = (q_d, q̇_d, q̈_d); returns the commanded torque."""
        n = self.model.n
        q, v = y[:n], y[n:]
        qd, vd, ad = reference
        shape = self._shape
        if (type(y) is np.ndarray and type(qd) is np.ndarray and type(vd) is np.ndarray and type(ad) is np.ndarray
                and y.dtype is _FLOAT and qd.dtype is _FLOAT and vd.dtype is _FLOAT and ad.dtype is _FLOAT
                and y.shape == self._y_shape and qd.shape == shape and vd.shape == shape and ad.shape == shape):
            a = np.empty(n)               # the same numbers as the array form below, entry by entry (a kernel)
            _feedback(ad, vd, qd, y, self.kd, self.kp, a)
        else:
            a = ad + self.kd * (vd - v) + self.kp * (qd - q)
        tau = self.model.inverse_dynamics(q, v, a)
        limit = self.torque_limit
        if limit is not None:             # np.clip(tau, -limit, limit) (the same numbers, a kernel)
            if self._clip_in_place or (
                    type(tau) is np.ndarray and tau.shape == limit.shape and tau.dtype == np.float64
                    and tau.base is None and tau.flags.owndata and tau.flags.writeable):      # a fresh result
                _clip(tau, limit)
            else:
                tau = np.minimum(np.maximum(tau, -limit), limit)
        return tau


_FLOAT = np.dtype(float)


@kernel
def _feedback(ad, vd, qd, y, kd, kp, a):
    """q̈_d + K_D (q̇_d − q̇) + K_P (q_d − q) entry by entry, as the array form computes it; y = [q; q̇]."""
    n = a.shape[0]
    for i in range(n):
        a[i] = ad[i] + kd * (vd[i] - y[n + i]) + kp * (qd[i] - y[i])


@kernel
def _clip(tau, limit):
    """tau clipped to [−limit, limit] in place: np.minimum(np.maximum(tau, −limit), limit), NaN kept."""
    for i in range(tau.shape[0]):
        low = -limit[i]
        if tau[i] < low:
            tau[i] = low
        if tau[i] > limit[i]:
            tau[i] = limit[i]
