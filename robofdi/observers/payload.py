"""The payload hypothesis: what a point mass at the arm's payload point does to the momentum residual.

A mass δm at the payload point p (the file's ``robofdi_payload_body`` and ``robofdi_payload_offset``,
:func:`robofdi.mjcf.payload_point`) adds δm·Y(q, q̇, q̈) to the torques the joints need, with
Y = J_pᵀ (p̈ − g) the torque a unit point mass needs along the motion (no rotational inertia). The momentum
residual of the nominal model (De Luca & Mattone 2003, eq. (10)) estimates the unmodelled torque through its own
first-order dynamics LP, so with the payload it reads r ≈ −δm·LP(Y).

LP(Y) needs no q̈: it is the momentum observer of the unit point mass alone (M_u = J_pᵀJ_p, C_u, g_u, no
armature, no friction) with no applied torque. Its "external torque" is exactly what the unit mass needs along
the measured motion (:class:`PayloadRegressor`).

The decision statistic of :func:`payload_evidence` compares two explanations of the normalised dynamic
residual ρ (each joint's residual over its bound): a payload (ρ along y = LP(Y)/bound) or one actuator (ρ along
a single joint). It is the part of ρ along y that exceeds what a single joint could explain,
√max(0, (y·ρ)²/(y·y) − max_i ρ_i²). For an actuator fault it is 0, since ρ lies along one joint and no direction
explains more of it. For a payload it grows with δm and with how many joints the payload loads.
"""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from robofdi import RobofdiError
from robofdi.jit import kernel
from robofdi.models.manipulator import ManipulatorModel, mirror_upper, payload_inertia
from robofdi.observers.momentum import _momentum_step

__all__ = ["unit_payload_model", "PayloadRegressor", "payload_evidence"]


def unit_payload_model(model: ManipulatorModel) -> pin.Model:
    """A copy of the nominal Pinocchio model whose only inertia is a 1 kg point mass at the payload point (no
    armature, no damping): its dynamics are the payload regressor Y per kg."""
    unit = pin.Model(model.model)
    joint, load = payload_inertia(unit, model.payload_body, model.payload_offset, 1.0)
    for j in range(unit.njoints):
        unit.inertias[j] = pin.Inertia.Zero()
    unit.inertias[joint] = load
    unit.armature = np.zeros(unit.nv)
    unit.damping = np.zeros(unit.nv)
    return unit


class PayloadRegressor:
    """Stepping form: ``update(q, v)`` → LP(Y) (n,) [N·m/kg]: the momentum residual (eq. (10), gain K_O [1/s],
    sample time T [s]) of the unit point mass at the payload point with no applied torque, i.e. the filtered
    torque per kg a payload needs along the measured motion (module docstring). Positions in the file's joint
    coordinates [rad or m], as the nominal model takes them."""

    def __init__(self, model: ManipulatorModel, T: float, gain: float):
        if not (np.isfinite(T) and T > 0 and np.isfinite(gain) and 0 < gain * T < 1):
            raise RobofdiError(f"PayloadRegressor: fields 'T' and 'gain' must be > 0 with gain·T < 1, got {T}, {gain}")
        self._nominal = model
        self.model = unit_payload_model(model)
        self.data = self.model.createData()
        self.n, self.T, self.gain = model.n, float(T), float(gain)
        self._lower = np.tril_indices(self.n, -1)
        self._zeros = np.zeros(self.n)
        self.reset()

    def reset(self) -> None:
        self._prev = None
        self._r = np.zeros(self.n)

    def update(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        m, d = self.model, self.data
        qp = self._nominal._q(q)
        M = mirror_upper(pin.crba(m, d, qp).copy())
        p = M.dot(v)
        if self._prev is None:
            self._p0, self._integral = p, np.zeros(self.n)
        else:
            q1, v1 = self._prev
            gravity = pin.computeGeneralizedGravity(m, d, q1)
            coriolis = pin.computeCoriolisMatrix(m, d, q1, v1).T.dot(v1)
            integral, r = np.empty(self.n), np.empty(self.n)
            _momentum_step(gravity, self._zeros, v1, coriolis, None, self._zeros, self._r, p, self._p0,
                           self._integral, self.T, self.gain, integral, r)
            self._integral, self._r = integral, r
        self._prev = (qp, np.array(v, dtype=float))
        return self._r


def payload_evidence(rho: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(evidence, δm̂) for normalised dynamic residuals ``rho`` (n,) and the normalised payload direction ``y``
    (n,) [1/kg] (module docstring): evidence = √max(0, (y·ρ)²/(y·y) − max_i ρ_i²) (dimensionless) and the
    least-squares payload δm̂ = −(y·ρ)/(y·y) [kg] (r ≈ −δm LP(Y)); (0, 0) where y vanishes."""
    return _payload_evidence(np.asarray(rho, dtype=float), np.asarray(y, dtype=float))


@kernel
def _payload_evidence(rho, y):
    """:func:`payload_evidence`, entry by entry."""
    yy, yr, largest = 0.0, 0.0, 0.0
    for i in range(rho.shape[0]):
        yy += y[i] * y[i]
        yr += y[i] * rho[i]
        if rho[i] * rho[i] > largest or rho[i] != rho[i]:
            largest = rho[i] * rho[i]
    if not yy > 1e-300:
        return 0.0, 0.0
    excess = yr * yr / yy - largest
    return (math.sqrt(excess) if excess > 0 else 0.0), -yr / yy
