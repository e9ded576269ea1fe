"""Position–velocity consistency of each joint's sensors: the analytical redundancy between an encoder and an
independent velocity measurement (motor-side encoder, resolver or tachometer).

Per joint and sample (trapezoidal integration with a sampling skew τ_s between the two sensors):

    e_k = q_k − q_{k−1} − T (q̇_k + q̇_{k−1})/2 − τ_s (q̇_k − q̇_{k−1})                          [rad]

A position-sensor step shows as one large e_k; a position drift or a velocity bias as a persistent mean of e,
which the sums over sliding windows of W samples accumulate (the GLR for a change in mean of known duration,
Basseville & Nikiforov 1993, Sec. 2.4, evaluated on a few window lengths). Each window's sum is divided by its
fault-free scale σ_W = a_W + b_W · mean_W |q̇| (integration errors grow with speed; a, b >= 0 designed as the
tightest bound over fault-free runs, :func:`robofdi.decision.envelope.design_envelope`), so the residual
max_W |Σ_W e| / σ_W is dimensionless and ≤ 1 on fault-free data where the scales were designed. Actuator
faults cannot raise it: the relation is pure kinematics.

Valid only when the velocity does not come from differentiating the same encoder (then e ≡ 0 by construction
and encoder faults must be found through the dynamics).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.decision.envelope import design_envelope
from robofdi.errors import RobofdiError

__all__ = ["KinematicConsistency", "kinematic_increments", "identify_skew", "design_window_scales", "WINDOWS"]

#: Window lengths [s] of the accumulated inconsistency (0 = the single sample).
WINDOWS = (0.0, 0.1, 0.5, 2.0, 4.0)
#: The longest window whose scale is learnt from the calibration suite alone. A 2 s scale learnt from the suite's
#: few 2 s windows was measured to underestimate the random walk of the integrated velocity noise (false alarms on
#: unseen motions: arm campaign, run 1 of seed 10); longer windows get at least this window's scale grown as a
#: random walk, a_W >= a_L √(W/L), b_W >= b_L (the trapezoid and skew errors telescope in a sum: they do not grow).
LEARNT_WINDOW = 0.5


def kinematic_increments(q: np.ndarray, v: np.ndarray, T: float, skew: np.ndarray | float = 0.0) -> np.ndarray:
    """e_k of the module docstring for sampled positions q (N, n) [rad] and velocities v (N, n) [rad/s]; e_0 = 0."""
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    e = np.zeros_like(q)
    e[1:] = q[1:] - q[:-1] - T * (v[1:] + v[:-1]) / 2 - np.asarray(skew) * (v[1:] - v[:-1])
    return e


def identify_skew(qs: Sequence[np.ndarray], vs: Sequence[np.ndarray], T: float, skip: int = 0) -> np.ndarray:
    """Least-squares sampling skew τ_s [s] per joint from fault-free runs (e with τ_s = 0 regressed on Δq̇)."""
    num, den = 0.0, 0.0
    for q, v in zip(qs, vs):
        e = kinematic_increments(q, v, T)[max(skip, 1):]
        dv = np.diff(np.asarray(v, dtype=float), axis=0)[max(skip, 1) - 1:]
        num, den = num + (e * dv).sum(axis=0), den + (dv * dv).sum(axis=0)
    den = np.asarray(den, dtype=float)
    if np.isscalar(num) or np.any(den <= 0):
        raise RobofdiError("identify_skew: the fault-free runs must move every joint (no velocity change seen)")
    return num / den


def _window_samples(T: float, windows: Sequence[float]) -> list[int]:
    return [max(1, int(round(w / T))) for w in windows]


def _window_sums(x: np.ndarray, sizes: Sequence[int]) -> np.ndarray:
    """(N, n, len(sizes)) sums of x over the last W samples (fewer at the start of the run)."""
    c = np.cumsum(x, axis=0)
    out = np.empty(x.shape + (len(sizes),))
    for j, w in enumerate(sizes):
        lag = np.zeros_like(c)
        lag[w:] = c[:-w]
        out[..., j] = c - lag
    return out


def _scale_features(mean_speed: np.ndarray) -> np.ndarray:
    return np.stack([np.ones_like(mean_speed), mean_speed], axis=-1)


def design_window_scales(increments: Sequence[np.ndarray], velocities: Sequence[np.ndarray], T: float,
                         skip: int = 0, windows: Sequence[float] = WINDOWS) -> np.ndarray:
    """Scale coefficients (n, len(windows), 2) = (a_W, b_W) [rad, rad/(rad/s)] of σ_W = a_W + b_W mean_W |q̇|:
    the tightest such bound on |Σ_W e| over fault-free runs (increments e and velocities: one (N, n) each)."""
    if not increments or len(increments) != len(velocities):
        raise RobofdiError("design_window_scales: expected as many increment as velocity runs (>= 1)")
    sizes = _window_samples(T, windows)
    sums = [_window_sums(np.asarray(e, dtype=float), sizes) for e in increments]
    speeds = [_window_sums(np.abs(np.asarray(v, dtype=float)), sizes) / np.array(sizes) for v in velocities]
    n = sums[0].shape[1]
    coef = np.zeros((n, len(sizes), 2))
    for j in range(len(sizes)):
        coef[:, j] = design_envelope([_scale_features(s[..., j]) for s in speeds], [s[..., j] for s in sums], skip)
    coef[..., 0] = np.maximum(coef[..., 0], 1e-9)      # a quantised, resting joint still gets a positive scale
    learnt = [j for j, w in enumerate(windows) if w <= LEARNT_WINDOW]
    if learnt:
        base = max(learnt, key=lambda j: windows[j])
        for j, w in enumerate(windows):
            if w > LEARNT_WINDOW:
                coef[:, j, 0] = np.maximum(coef[:, j, 0], coef[:, base, 0] * np.sqrt(sizes[j] / sizes[base]))
                coef[:, j, 1] = np.maximum(coef[:, j, 1], coef[:, base, 1])
    return coef


class KinematicConsistency:
    """Stepping form: ``update(q, v)`` → (per joint: max_W |Σ_W e| / σ_W (dimensionless), e_k [rad])."""

    def __init__(self, T: float, skew: np.ndarray, scales: np.ndarray, windows: Sequence[float] = WINDOWS):
        self.T = float(T)
        self.skew = np.asarray(skew, dtype=float)
        self.scales = np.asarray(scales, dtype=float)
        n = self.skew.shape[0]
        if (self.scales.shape != (n, len(windows), 2) or np.any(self.scales[..., 0] <= 0)
                or np.any(self.scales[..., 1] < 0)):
            raise RobofdiError(f"KinematicConsistency: field 'scales' must be an ({n}, {len(windows)}, 2) array of "
                               f"(a > 0, b >= 0), got shape {self.scales.shape}")
        self.sizes = _window_samples(self.T, windows)
        self.reset()

    def reset(self) -> None:
        self._prev = None
        n = self.skew.shape[0]
        self._history = np.zeros((max(self.sizes) + 1, 2, n))   # ring buffer of cumulative sums of e and |q̇|
        self._k = 0

    def update(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self._prev is None:
            e = np.zeros_like(q)
        else:
            qp, vp = self._prev
            e = q - qp - self.T * (v + vp) / 2 - self.skew * (v - vp)
        self._prev = (q, v)
        size = self._history.shape[0]
        now = np.stack([e, np.abs(v)])
        cum = self._history[(self._k - 1) % size] + now if self._k else now
        self._history[self._k % size] = cum
        ratio = np.zeros_like(q)
        for j, w in enumerate(self.sizes):
            window = cum - self._history[(self._k - w) % size] if self._k >= w else cum
            scale = self.scales[:, j, 0] + self.scales[:, j, 1] * window[1] / w
            ratio = np.maximum(ratio, np.abs(window[0]) / scale)
        self._k += 1
        return ratio, e
