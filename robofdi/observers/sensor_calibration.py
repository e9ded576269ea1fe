"""Adaptive sensor calibration-error and generalised-sensor diagnosers — Bošković & Mehra, "Failure detection,
identification and reconfiguration in flight control", §3.2 (y = Cx, eqs. (15)–(19)) and §4 (y = Cx + d,
eqs. (23)–(26), with the sign fix of the Ĉ_o block and Ω = ∂g/∂c of
:func:`robofdi.observers.sensor_adaptive.generalised_regressor`).

Both are one class, :class:`GeneralisedSensorEstimator`: ``estimate=("calibration",)`` is §3.2 with C_o
parameterised as ĈAĈ⁻¹ (A known, as §4's eq. (24) does), ``estimate=("bias", "calibration")`` is §4.
[RECONSTRUCTED] §3.2's eq. (19) adapts the n² entries of C_o freely; on a plant whose x₁ rows carry no input
(B₁ = 0, as on the flight surrogate) the calibration factors of x₁ would then not be identifiable at all, while
through ĈAĈ⁻¹ they are (the ratios cᵢ/cⱼ enter the off-diagonal entries). The error weight P (diagonal > 0) in
θ̂̇ = Proj{−Γ Ω̃ᵀ P e_y} keeps the Lyapunov argument of Theorems 2–3 (Λ diagonal, so PΛ + ΛP < 0) and keeps a
noisy channel (airspeed) from driving every estimate.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.decision.isolation import Signature
from robofdi.errors import RobofdiError
from robofdi.observers.residual import Residual, check_measurement
from robofdi.observers.sensor_adaptive import box_projection, generalised_regressor

__all__ = ["calibration_gains", "GeneralisedSensorEstimator", "ESTIMATES"]

ESTIMATES = (("calibration",), ("bias", "calibration"))


def calibration_gains(A, B, y, u, lam, tau: float, weights=None, channels=None) -> np.ndarray:
    """Diagonal Γ_c of the calibration law giving each estimate the time constant ``tau`` [s] at the excitation
    of fault-free samples (y (N, n), u (N, m)), in the quasi-static approximation e_y ≈ Ωφ_c/|λ|:
    γᵢ = |λᵢ| / (τ · mean_t Σⱼ Pⱼ Ω_ji²), Ω at ĉ = 1, d̂ = 0 (eq. (25)). Channels outside ``channels`` (None: all)
    and channels never excited get 0 (not estimated)."""
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    n = A.shape[0]
    y, u = np.atleast_2d(np.asarray(y, dtype=float)), np.atleast_2d(np.asarray(u, dtype=float))
    if y.shape[1] != n or u.shape[1] != B.shape[1] or len(y) != len(u) or len(y) == 0:
        raise RobofdiError(f"calibration_gains: fields 'y' (N, {n}) and 'u' (N, {B.shape[1]}) disagree: "
                           f"{y.shape}, {u.shape}")
    if not (np.isfinite(tau) and tau > 0):
        raise RobofdiError(f"calibration_gains: field 'tau' must be a time > 0 s, got {tau!r}")
    P = np.ones(n) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), (n,))
    lam = np.broadcast_to(np.abs(np.asarray(lam, dtype=float)), (n,))
    ones, zeros = np.ones(n), np.zeros(n)
    s = np.zeros(n)
    for yk, uk in zip(y, u):
        Om = generalised_regressor(A, B, ones, zeros, yk, uk)[:, n:]
        s += P @ Om**2
    s /= len(y)
    g = np.where(s > 1e-300, lam / (tau * np.maximum(s, 1e-300)), 0.0)
    if channels is not None:
        keep = np.zeros(n, dtype=bool)
        keep[list(channels)] = True
        g = np.where(keep, g, 0.0)
    return g


def _diag(value, n: int, field: str, positive: bool) -> np.ndarray:
    v = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    ok = np.isfinite(v) & ((v > 0) if positive else (v >= 0))
    if not np.all(ok):
        raise RobofdiError(f"GeneralisedSensorEstimator: field {field!r} must be {n} values "
                           f"{'> 0' if positive else '>= 0'}, got {value!r}")
    return v


class GeneralisedSensorEstimator:
    """Diagnoser: ŷ̇ = ĈAĈ⁻¹(y − d̂) + ĈBu + Λe_y with θ̂ = [d̂; ĉ],
    θ̂̇ = Proj_{[θ_min, θ_max]}{−Γ Ω̃ᵀ P e_y}, Ω̃ = [−Ĉ_o  Ω] — eqs. (24)–(26) (§4, y = Cx + d); with
    ``estimate=("calibration",)`` d̂ ≡ 0: §3.2's y = Cx, eqs. (16)–(19) with C_o = ĈAĈ⁻¹.

    Sampling: e_y = ŷ − y is propagated for y linear between samples (ė_y = Λe_y + g − ẏ, the drive
    g = ĈAĈ⁻¹(y − d̂) + ĈBu at the interval's mean y, u held); θ̂ is stepped by Euler on the new e_y and clipped to its box (B8).
    Λ = diag(``lam``) Hurwitz; Γ = diag(``gamma_d``, ``gamma_c``) ≥ 0 (0: that parameter is not estimated;
    :func:`robofdi.observers.sensor_adaptive.bias_gains` and :func:`calibration_gains` design them); ``weights``:
    the diagonal P > 0; ``d_bar``: the bias bound; ``c_bounds``: the box of ĉ (the chapter's [c̄, 1]; a
    campaign's sensor_scale faults read high, so the default reaches 2).

    Residual per channel: with ``("calibration",)`` ĉᵢ − 1 (components ``c:<channel>``, unit 1); with
    ``("bias", "calibration")`` the estimated sensor error yᵢ − x̂ᵢ, x̂ = Ĉ⁻¹(y − d̂) (components
    ``e:<channel>``, the channel's unit; = d̂ when ĉ = 1). Estimates: d̂ per channel (the channel's unit; only
    with the bias) then ĉᵢ − 1 (``scale:<channel>``, the sensor_scale fault's magnitude). One signature per
    channel (isolation by channel)."""

    def __init__(self, A, B, states: Sequence[str], inputs: Sequence[str], units: Sequence[str], dt: float,
                 lam=-5.0, gamma_d=0.0, gamma_c=1.0, weights=None, d_bar=0.2, c_bounds=(0.5, 2.0),
                 estimate: Sequence[str] = ("bias", "calibration")):
        self.A, self.B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
        n = self.A.shape[0]
        if self.A.shape != (n, n) or self.B.shape[0] != n or len(states) != n or len(units) != n:
            raise RobofdiError(f"GeneralisedSensorEstimator: fields 'A' (n×n), 'B' (n×m), 'states', 'units' (n) "
                               f"disagree: {self.A.shape}, {self.B.shape}, {len(states)}, {len(units)}")
        self.estimate = tuple(estimate)
        if self.estimate not in ESTIMATES:
            raise RobofdiError(f"GeneralisedSensorEstimator: field 'estimate' must be one of {ESTIMATES}, got "
                               f"{estimate!r}")
        self.has_bias = "bias" in self.estimate
        self.lam = np.broadcast_to(np.asarray(lam, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(self.lam) & (self.lam < 0)):
            raise RobofdiError(f"GeneralisedSensorEstimator: field 'lam' must be a Hurwitz diagonal Λ (every "
                               f"entry < 0), got {lam!r}")
        self.gamma_d = _diag(gamma_d if self.has_bias else 0.0, n, "gamma_d", positive=False)
        self.gamma_c = _diag(gamma_c, n, "gamma_c", positive=False)
        if not np.any(self.gamma_c > 0) and not np.any(self.gamma_d > 0):
            raise RobofdiError("GeneralisedSensorEstimator: fields 'gamma_d' / 'gamma_c' must estimate at least "
                               "one parameter (an entry > 0)")
        self.P = _diag(1.0 if weights is None else weights, n, "weights", positive=True)
        self.d_bar = _diag(d_bar, n, "d_bar", positive=True)
        lo, hi = (float(v) for v in c_bounds)
        if not (0 < lo < 1 < hi and np.isfinite(hi)):
            raise RobofdiError(f"GeneralisedSensorEstimator: field 'c_bounds' must be (c_min, c_max) with "
                               f"0 < c_min < 1 < c_max, got {c_bounds!r}")
        self.c_bounds = (lo, hi)
        if not (np.isfinite(dt) and dt > 0):
            raise RobofdiError(f"GeneralisedSensorEstimator: field 'dt' must be a sample time > 0 s, got {dt!r}")
        self.dt = float(dt)
        self.measurements, self.inputs = list(states), list(inputs)
        if self.has_bias:
            self.components = [f"e:{s}" for s in states]
            res_units = list(units)
            self.estimate_components = list(states) + [f"scale:{s}" for s in states]
            est_units = list(units) + ["1"] * n
        else:
            self.components = [f"c:{s}" for s in states]
            res_units = ["1"] * n
            self.estimate_components = [f"scale:{s}" for s in states]
            est_units = ["1"] * n
        self.estimate_modes = ["level"] * len(self.estimate_components)
        self.units = {"residual": res_units, "estimate": est_units}
        self._decay = np.exp(self.lam * self.dt)
        self._gain = (self._decay - 1.0) / self.lam           # ∫₀^dt e^{λs} ds
        self.reset()

    def reset(self) -> None:
        n = self.A.shape[0]
        self._e = np.zeros(n)
        self._d = np.zeros(n)
        self._c = np.ones(n)
        self._prev = None

    @property
    def bias(self) -> np.ndarray:
        return self._d.copy()

    @property
    def calibration(self) -> np.ndarray:
        return self._c.copy()

    def state_estimate(self, y) -> np.ndarray:
        """x̂ = Ĉ⁻¹(y − d̂) — the static estimate of §3.2 / §4 (the chapter's (21), printed as a derivative)."""
        return (np.asarray(y, dtype=float) - self._d) / self._c

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        n = self.A.shape[0]
        y = check_measurement(y, n, "y")
        u = check_measurement(u, self.B.shape[1], "u")
        if self._prev is not None:
            yp, c, d = self._prev, self._c, self._d
            Co = c[:, None] * self.A / c[None, :]
            g = Co @ (0.5 * (yp + y) - d) + c * (self.B @ u)      # trapezoid in y (y linear, u held)
            self._e = self._decay * self._e + self._gain * (g - (y - yp) / self.dt)
            Om = generalised_regressor(self.A, self.B, c, d, yp, u)
            rate = -(Om.T @ (self.P * self._e))
            if self.has_bias:
                dd = box_projection(d, self.gamma_d * rate[:n], -self.d_bar, self.d_bar)
                self._d = np.clip(d + self.dt * dd, -self.d_bar, self.d_bar)
            dc = box_projection(c, self.gamma_c * rate[n:], *self.c_bounds)
            self._c = np.clip(c + self.dt * dc, *self.c_bounds)
        self._prev = y
        scale = self._c - 1.0
        if self.has_bias:
            return Residual(y - self.state_estimate(y), np.concatenate([self._d, scale]))
        return Residual(scale.copy(), scale)

    def signatures(self):
        return [Signature(s, frozenset({c})) for s, c in zip(self.measurements, self.components)]
