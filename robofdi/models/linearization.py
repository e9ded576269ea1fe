"""Linearisation of a manipulator's nominal model about a rest pose, for the linear diagnosers (cross-use).

    M(q) q̈ + n(q, q̇) = τ   about (q₀, q̇ = 0, τ₀ = g(q₀)):   d/dt [δq; q̇] = [[0, I], [∂q̈/∂q, ∂q̈/∂q̇]] [δq; q̇] + [0; M⁻¹(q₀)] δτ

with the Jacobians of the forward dynamics q̈ = M̂⁻¹(τ − n̂) (Pinocchio ABA on the belief) by central differences.
The result is the belief's linear model about an equilibrium; use it where the motion stays near q₀ (a hold, a
slow task), with the operating point (x₀ = [q₀; 0], u₀ = g(q₀)) handed to the diagnoser.
"""
from __future__ import annotations

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.models.linear import LinearModel

__all__ = ["linearize_manipulator"]


def linearize_manipulator(model, q0, step: float = 1e-6) -> tuple[LinearModel, np.ndarray, np.ndarray]:
    """(continuous LinearModel with x = [q; q̇], u = τ, y = x; x₀; u₀) of ``model`` (a ManipulatorModel, the
    belief) at rest at ``q0`` — central differences of the forward dynamics with ``step``."""
    n = model.n
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (n,) or not np.all(np.isfinite(q0)):
        raise RobofdiError(f"linearize_manipulator: field 'q0' must be {n} finite joint positions, got {q0!r}")
    u0 = np.asarray(model.gravity(q0), dtype=float)
    v0 = np.zeros(n)
    Jq, Jv, Ju = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = step
        Jq[:, i] = (model.acceleration(q0 + e, v0, u0) - model.acceleration(q0 - e, v0, u0)) / (2 * step)
        Jv[:, i] = (model.acceleration(q0, e, u0) - model.acceleration(q0, -e, u0)) / (2 * step)
        Ju[:, i] = (model.acceleration(q0, v0, u0 + e) - model.acceleration(q0, v0, u0 - e)) / (2 * step)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [Jq, Jv]])
    B = np.vstack([np.zeros((n, n)), Ju])
    joints = list(model.joint_names)
    from robofdi.models.manipulator import sensor_channel_names

    lin = LinearModel(A, B, np.eye(2 * n), state_names=[f"{j}_q" for j in joints] + [f"{j}_qd" for j in joints],
                      input_names=joints, output_names=sensor_channel_names(joints),
                      units={"state": ["rad"] * n + ["rad/s"] * n, "u": ["N*m"] * n,
                             "y": ["rad"] * n + ["rad/s"] * n})
    return lin, np.concatenate([q0, v0]), u0
