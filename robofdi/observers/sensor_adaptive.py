"""Adaptive sensor-failure estimation — Bošković & Mehra, "Failure detection, identification and reconfiguration
in flight control", §3–4: bias / drift / loss of accuracy with C = I (eqs. (6)–(10)), the generalised
y = Cx + d case (eqs. (23)–(26), with the sign fix of the Ĉ_o block) and the projection operator (its missing
appendix, the standard box projection).

:class:`SensorBiasEstimator` is the diagnoser of eqs. (8)–(10); a controller uses its ``bias`` as the static
state estimate x̂ = y − d̂ (the chapter's eq. (12)).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.decision.isolation import Signature
from robofdi.errors import RobofdiError
from robofdi.observers.effector_bank import foh_discretize
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["box_projection", "bias_rate", "bias_gains", "generalised_regressor", "generalised_rate", "SensorBiasEstimator"]


def box_projection(theta, v, lower, upper) -> np.ndarray:
    """Proj{v} on the box [lower, upper] at θ: v_k, or 0 where θ_k is at (or beyond) a bound and v_k points
    outward (the standard projection; the chapter's appendix is not available)."""
    theta, v = np.asarray(theta, dtype=float), np.array(v, dtype=float)
    out = ((theta >= upper) & (v > 0)) | ((theta <= lower) & (v < 0))
    v[out] = 0.0
    return v


def bias_rate(A, Gamma, e_y, d_hat, d_bar) -> np.ndarray:
    """ḋ̂ = Proj_{[−d̄, d̄]}{Γ Aᵀ e_y} — eq. (10), e_y = ŷ − y."""
    A = np.asarray(A, dtype=float)
    return box_projection(d_hat, np.asarray(Gamma) @ A.T @ np.asarray(e_y, dtype=float), -np.asarray(d_bar),
                          np.asarray(d_bar))


def bias_gains(A, lam, tau: float, channels=None, weights=None) -> np.ndarray:
    """Diagonal Γ of (10) giving each bias estimate the time constant ``tau`` [s] in the quasi-static
    approximation (e_y ≈ Aφ_d/|λ|, so φ̇_{d,i} ≈ −γᵢ Σⱼ Pⱼ A_ji² φ_{d,i}/|λᵢ|): γᵢ = |λᵢ| / (τ Σⱼ Pⱼ A_ji²), P =
    diag(``weights``) the error weight of a law ḋ̂ = ΓAᵀPe_y (None: P = I, eq. (10) itself). Channels
    outside ``channels`` (indices; None: all) get γᵢ = 0 (not estimated). Equal convergence times keep the
    noise a well-observed channel feeds into a weakly observed one's estimate small (plain Γ = γI does not)."""
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    lam = np.broadcast_to(np.abs(np.asarray(lam, dtype=float)), (n,))
    if not (np.isfinite(tau) and tau > 0):
        raise RobofdiError(f"bias_gains: field 'tau' must be a time > 0 s, got {tau!r}")
    col = np.sum(A**2, axis=0) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), (n,)) @ A**2
    g = np.where(col > 0, lam / (tau * np.maximum(col, 1e-300)), 0.0)
    if channels is not None:
        keep = np.zeros(n, dtype=bool)
        keep[list(channels)] = True
        g = np.where(keep, g, 0.0)
    return g


def generalised_regressor(A, B, c_hat, d_hat, y, u) -> np.ndarray:
    """Ω̃ = [−Ĉ_o  Ω] (n × 2n) of the error model ė_y = Λe_y + Ω̃φ, φ = [φ_d; φ_c] — eq. (25) with the digest's sign
    fix (the first block is −Ĉ_o, Ĉ_o = ĈAĈ⁻¹) and Ω = ∂g/∂c at (ĉ, d̂), g(c, d) = CAC⁻¹(y − d) + CBu."""
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    c, d = np.asarray(c_hat, dtype=float), np.asarray(d_hat, dtype=float)
    if np.any(c <= 0):
        raise RobofdiError(f"generalised_regressor: field 'c_hat' must be > 0 (calibration factors), got {c}")
    z = np.asarray(y, dtype=float) - d
    Co = (c[:, None] * A) / c[None, :]
    Bu = B @ np.asarray(u, dtype=float)
    Omega = -(c[:, None] * A * z[None, :]) / c[None, :] ** 2
    Omega[np.diag_indices_from(Omega)] += (A @ (z / c)) + Bu
    return np.hstack([-Co, Omega])


def generalised_rate(A, B, c_hat, d_hat, y, u, e_y, Gamma) -> np.ndarray:
    """θ̂̇ = −Γ Ω̃ᵀ e_y for θ̂ = [d̂; ĉ] — eq. (26) before its projection (apply :func:`box_projection`)."""
    Om = generalised_regressor(A, B, c_hat, d_hat, y, u)
    return -np.asarray(Gamma) @ Om.T @ np.asarray(e_y, dtype=float)


class SensorBiasEstimator:
    """Diagnoser: ŷ̇ = A(y − d̂) + Bu + Λe_y (8), ḋ̂ = Proj_{[−d̄, d̄]}{ΓAᵀe_y} (10) for y = x + d (C = I).

    The pair (ŷ, d̂) is linear between projections, so it is sampled exactly (y interpolated linearly between
    samples, u held) and d̂ clipped to its box after each step. Residual = estimate = d̂ per channel (in the
    channel's unit); Λ = diag(``lam``) Hurwitz, Γ = diag(``gamma``) ≥ 0 (positive definite on the estimated
    channels; :func:`bias_gains` designs it), ``d_bar`` the bound per channel
    (default 0.2 of the unit). ``bias`` is the current d̂ (for the static estimate x̂ = y − d̂, eq. (12))."""

    def __init__(self, A, B, states: Sequence[str], inputs: Sequence[str], units: Sequence[str], dt: float,
                 lam=-5.0, gamma=50.0, d_bar=None):
        self.A, self.B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
        n = self.A.shape[0]
        if self.A.shape != (n, n) or self.B.shape[0] != n or len(states) != n:
            raise RobofdiError(f"SensorBiasEstimator: fields 'A' (n×n), 'B' (n×m), 'states' (n) disagree: "
                               f"{self.A.shape}, {self.B.shape}, {len(states)}")
        lam = np.broadcast_to(np.asarray(lam, dtype=float), (n,)).copy()
        if not np.all(lam < 0):
            raise RobofdiError(f"SensorBiasEstimator: field 'lam' must be a Hurwitz diagonal Λ (every entry < 0), got {lam}")
        gamma = np.broadcast_to(np.asarray(gamma, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(gamma) & (gamma >= 0)) or not np.any(gamma > 0):
            raise RobofdiError(f"SensorBiasEstimator: field 'gamma' must be a diagonal Γ >= 0 (0: channel not "
                               f"estimated) with at least one entry > 0, got {gamma}")
        self.d_bar = np.broadcast_to(np.asarray(0.2 if d_bar is None else d_bar, dtype=float), (n,)).copy()
        if not np.all(self.d_bar > 0):
            raise RobofdiError(f"SensorBiasEstimator: field 'd_bar' must be bounds > 0, got {self.d_bar}")
        if not (np.isfinite(dt) and dt > 0):
            raise RobofdiError(f"SensorBiasEstimator: field 'dt' must be a sample time > 0 s, got {dt!r}")
        self.dt = float(dt)
        self.measurements, self.inputs = list(states), list(inputs)
        self.components = [f"d:{s}" for s in states]
        self.estimate_components = list(states)
        self.estimate_modes = ["level"] * n
        self.units = {"residual": list(units), "estimate": list(units)}
        L, G = np.diag(lam), np.diag(gamma)
        M = np.block([[L, -self.A], [G @ self.A.T, np.zeros((n, n))]])
        Nx = np.vstack([self.A - L, -G @ self.A.T])
        Ng = np.vstack([self.B, np.zeros_like(self.B)])
        self._disc = foh_discretize(M, Nx, Ng, self.dt)
        self.reset()

    def reset(self) -> None:
        n = self.A.shape[0]
        self._z = np.zeros(2 * n)
        self._prev = None

    @property
    def bias(self) -> np.ndarray:
        return self._z[self.A.shape[0]:].copy()

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        n = self.A.shape[0]
        y = check_measurement(y, n, "y")
        u = check_measurement(u, self.B.shape[1], "u")
        if self._prev is None:
            self._z[:n] = y
        else:
            Phi, G0, G1, Gg = self._disc
            z = Phi @ self._z + G0 @ self._prev + G1 @ (y - self._prev) + Gg @ u
            z[n:] = np.clip(z[n:], -self.d_bar, self.d_bar)          # projection (10), B8
            self._z = z
        self._prev = y
        d = self.bias
        return Residual(d, d.copy())

    def threshold(self, fraction: float = 0.05) -> np.ndarray:
        """Default alarm thresholds on |d̂|: ``fraction`` of d̄ per channel."""
        return fraction * self.d_bar

    def signatures(self):
        return [Signature(s, frozenset({c})) for s, c in zip(self.measurements, self.components)]
