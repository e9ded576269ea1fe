"""Position–velocity consistency of each joint's sensors: the analytical redundancy between an encoder and an
independent velocity measurement (motor-side encoder, resolver or tachometer).

Per joint and sample (trapezoidal integration with a sampling skew τ_s between the two sensors):

    e_k = q_k − q_{k−1} − T (q̇_k + q̇_{k−1})/2 − τ_s (q̇_k − q̇_{k−1})                          [rad]

A position-sensor step shows as one large e_k; a position drift or a velocity bias as a persistent mean of e,
which the sums over sliding windows of W samples accumulate (the GLR for a change in mean of known duration,
Basseville & Nikiforov 1993, Sec. 2.4, evaluated on a few window lengths). Each window's sum is divided by its
fault-free scale σ_W = a_W + b_W · mean_W |q̇| + c_W · |q̇_k − q̇_{k−W}| (integration errors grow with speed;
the skew's error telescopes in a window sum to δτ_s (q̇_k − q̇_{k−W}); a, b, c >= 0 designed as the tightest
bound over fault-free runs, :func:`robofdi.decision.envelope.design_envelope`), so the residual
max_W |Σ_W e| / σ_W is dimensionless and ≤ 1 on fault-free data where the scales were designed. Actuator
faults cannot raise it: the relation is pure kinematics.

The scales are valid over the operating envelope they were designed on: the largest mean_W |q̇| and
|q̇_k − q̇_{k−W}| seen (``reach``). Outside it the bound is not extrapolated linearly: σ_W is multiplied by how
far outside the point is (the product of the ratios over the reach, each at least 1), and the samples outside
are counted (:attr:`KinematicConsistency.outside`), so a motion faster than any calibrated one widens the
tolerance instead of raising a false alarm.

Valid only when the velocity does not come from differentiating the same encoder (then e ≡ 0 by construction
and encoder faults must be found through the dynamics).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.decision.envelope import design_envelope
from robofdi.errors import RobofdiError
from robofdi.jit import kernel

__all__ = ["KinematicConsistency", "kinematic_increments", "identify_skew", "design_window_scales", "WINDOWS",
           "SKEW_INSTRUMENT", "window_reach"]

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


#: Instrument of :func:`identify_skew`: the velocity change q̇_{k−L} − q̇_{k−L−S} with lag L and span S [samples].
SKEW_INSTRUMENT = (2, 2)


def identify_skew(qs: Sequence[np.ndarray], vs: Sequence[np.ndarray], T: float, skip: int = 0) -> np.ndarray:
    """Sampling skew τ_s [s] per joint from fault-free runs: e (with τ_s = 0) regressed on Δq̇_k by instrumental
    variables (Söderström & Stoica 1989, *System Identification*, Sec. 8.1: τ = Σ e z / Σ Δq̇ z).

    Ordinary least squares is biased towards 0 here (errors in variables): the regressor Δq̇_k carries twice the
    velocity-noise variance, which on slow motions is as large as the true velocity change (measured on arm6:
    0.14–0.2 ms where the integration implies 0.25 ms). The instrument z_k = q̇_{k−2} − q̇_{k−4}
    (:data:`SKEW_INSTRUMENT`) follows the true velocity change of a smooth motion but shares no noise sample
    with e_k (whose noise is that of q_k, q_{k−1}, q̇_k and q̇_{k−1}), so the estimate is consistent. For a
    plant integrated with semi-implicit Euler steps of h and accelerations constant over a sample, the skew
    is h/2 (q gains h·q̇_{j+1} per step: Σ h q̇_j − T (q̇_k + q̇_{k−1})/2 = (h/2) Δq̇)."""
    lag, span = SKEW_INSTRUMENT
    first = max(skip, 1, lag + span)
    num, den = 0.0, 0.0
    for q, v in zip(qs, vs):
        v = np.asarray(v, dtype=float)
        if v.shape[0] <= first:
            continue
        e = kinematic_increments(q, v, T)[first:]
        dv = (v[1:] - v[:-1])[first - 1:]
        z = v[first - lag:v.shape[0] - lag] - v[first - lag - span:v.shape[0] - lag - span]
        num, den = num + (e * z).sum(axis=0), den + (dv * z).sum(axis=0)
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


def _scale_features(mean_speed: np.ndarray, change: np.ndarray) -> np.ndarray:
    return np.stack([np.ones_like(mean_speed), mean_speed, change], axis=-1)


def _window_features(v: np.ndarray, sizes: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(mean_W |q̇|, |q̇_k − q̇_{k−W}|), each (N, n, len(sizes)), of velocities v (N, n) (fewer at the start)."""
    v = np.asarray(v, dtype=float)
    dv = np.zeros_like(v)
    dv[1:] = v[1:] - v[:-1]
    return _window_sums(np.abs(v), sizes) / np.array(sizes), np.abs(_window_sums(dv, sizes))


def design_window_scales(increments: Sequence[np.ndarray], velocities: Sequence[np.ndarray], T: float,
                         skip: int = 0, windows: Sequence[float] = WINDOWS) -> np.ndarray:
    """Scale coefficients (n, len(windows), 3) = (a_W, b_W, c_W) [rad, rad/(rad/s), s] of
    σ_W = a_W + b_W mean_W |q̇| + c_W |q̇_k − q̇_{k−W}|: the tightest such bound on |Σ_W e| over fault-free runs
    (increments e and velocities: one (N, n) each)."""
    if not increments or len(increments) != len(velocities):
        raise RobofdiError("design_window_scales: expected as many increment as velocity runs (>= 1)")
    sizes = _window_samples(T, windows)
    sums = [_window_sums(np.asarray(e, dtype=float), sizes) for e in increments]
    feats = [_window_features(v, sizes) for v in velocities]
    n = sums[0].shape[1]
    coef = np.zeros((n, len(sizes), 3))
    for j in range(len(sizes)):
        coef[:, j] = design_envelope([_scale_features(f[0][..., j], f[1][..., j]) for f in feats],
                                     [s[..., j] for s in sums], skip)
    coef[..., 0] = np.maximum(coef[..., 0], 1e-9)      # a quantised, resting joint still gets a positive scale
    learnt = [j for j, w in enumerate(windows) if w <= LEARNT_WINDOW]
    if learnt:
        base = max(learnt, key=lambda j: windows[j])
        for j, w in enumerate(windows):
            if w > LEARNT_WINDOW:
                coef[:, j, 0] = np.maximum(coef[:, j, 0], coef[:, base, 0] * np.sqrt(sizes[j] / sizes[base]))
                coef[:, j, 1:] = np.maximum(coef[:, j, 1:], coef[:, base, 1:])
    return coef


def window_reach(velocities: Sequence[np.ndarray], T: float, skip: int = 0,
                 windows: Sequence[float] = WINDOWS) -> np.ndarray:
    """The operating envelope the scales were designed on: (n, len(windows), 2) largest mean_W |q̇| [rad/s] and
    |q̇_k − q̇_{k−W}| [rad/s] over the fault-free runs (samples k < ``skip`` left out)."""
    sizes = _window_samples(T, windows)
    reach = None
    for v in velocities:
        speed, change = _window_features(v, sizes)
        here = np.stack([speed[skip:].max(axis=0), change[skip:].max(axis=0)], axis=-1)
        reach = here if reach is None else np.maximum(reach, here)
    if reach is None:
        raise RobofdiError("window_reach: expected at least one fault-free run")
    return np.maximum(reach, 1e-9)


class KinematicConsistency:
    """Stepping form: ``update(q, v)`` → (per joint: max_W |Σ_W e| / σ_W (dimensionless), e_k [rad]).
    ``reach`` (n, len(windows), 2): the designed operating envelope (:func:`window_reach`); None = unbounded.
    :attr:`outside` (n,) says, per joint, whether the last sample was outside it in some window, and
    :attr:`outside_samples` counts such samples since :meth:`reset`; :attr:`scale` (n, len(windows)) holds the
    last sample's σ_W [rad]."""

    def __init__(self, T: float, skew: np.ndarray, scales: np.ndarray, windows: Sequence[float] = WINDOWS,
                 reach: np.ndarray | None = None):
        self.T = float(T)
        self.skew = np.asarray(skew, dtype=float)
        self.scales = np.asarray(scales, dtype=float)
        n = self.skew.shape[0]
        if (self.scales.shape != (n, len(windows), 3) or np.any(self.scales[..., 0] <= 0)
                or np.any(self.scales[..., 1:] < 0)):
            raise RobofdiError(f"KinematicConsistency: field 'scales' must be an ({n}, {len(windows)}, 3) array of "
                               f"(a > 0, b >= 0, c >= 0), got shape {self.scales.shape}")
        self.reach = None if reach is None else np.asarray(reach, dtype=float)
        if self.reach is not None and (self.reach.shape != (n, len(windows), 2) or np.any(self.reach <= 0)):
            raise RobofdiError(f"KinematicConsistency: field 'reach' must be None or an ({n}, {len(windows)}, 2) "
                               f"array > 0, got shape {self.reach.shape}")
        self.sizes = _window_samples(self.T, windows)
        self._sizes = np.array(self.sizes, dtype=np.int64)
        self._reach = np.ones((n, len(windows), 2)) if self.reach is None else np.ascontiguousarray(self.reach)
        self.scales = np.ascontiguousarray(self.scales)
        self.skew = np.ascontiguousarray(self.skew)
        self.reset()

    def reset(self) -> None:
        self._prev = None
        n = self.skew.shape[0]
        self._history = np.zeros((max(self.sizes) + 1, 3, n))   # ring buffer of cumulative sums of e, |q̇|, Δq̇
        self._k = 0
        self.outside = np.zeros(n, dtype=bool)
        self.outside_samples = np.zeros(n, dtype=int)

    def update(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n, windows = self.skew.shape[0], len(self.sizes)
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        ratio, e = np.empty(n), np.empty(n)
        outside, scales = np.empty(n, dtype=bool), np.empty((n, windows))
        qp, vp = self._prev if self._prev is not None else (q, v)
        _kinematic_step(q, v, qp, vp, self._prev is None, self.T, self.skew, self._history, self._k, self._sizes,
                        self.scales, self._reach, self.reach is not None, ratio, e, outside, scales,
                        self.outside_samples)
        self._prev = (q, v)
        self._k += 1
        self.outside, self.scale = outside, scales
        return ratio, e


@kernel
def _kinematic_step(q, v, qp, vp, first, T, skew, history, k, sizes, scales, reach, bounded, ratio, e, outside,
                    scale, outside_samples):
    """One sample of :meth:`KinematicConsistency.update`, joint by joint in the order of operations of its array
    form: e_k, the cumulative sums in the ring buffer ``history`` at sample ``k``, each window's sum over its
    scale σ_W (widened outside ``reach`` when ``bounded``); writes ``ratio``, ``e``, ``outside``, ``scale``
    and counts ``outside_samples``."""
    size = history.shape[0]
    now, before = k % size, (k - 1) % size
    for i in range(q.shape[0]):
        if first:
            ei, dvi = 0.0, 0.0
        else:
            dvi = v[i] - vp[i]
            ei = q[i] - qp[i] - T * (v[i] + vp[i]) / 2 - skew[i] * dvi
        e[i] = ei
        if k:
            c0, c1, c2 = history[before, 0, i] + ei, history[before, 1, i] + abs(v[i]), history[before, 2, i] + dvi
        else:
            c0, c1, c2 = ei, abs(v[i]), dvi
        history[now, 0, i], history[now, 1, i], history[now, 2, i] = c0, c1, c2
        peak, out = 0.0, False
        for j in range(sizes.shape[0]):
            w = sizes[j]
            if k >= w:
                back = (k - w) % size
                w0, w1, w2 = c0 - history[back, 0, i], c1 - history[back, 1, i], c2 - history[back, 2, i]
            else:
                w0, w1, w2 = c0, c1, c2
            speed, change = w1 / w, abs(w2)
            sigma = scales[i, j, 0] + scales[i, j, 1] * speed + scales[i, j, 2] * change
            if bounded:     # outside the designed envelope: widen, never extrapolate linearly
                over_speed, over_change = speed / reach[i, j, 0], change / reach[i, j, 1]
                if over_speed < 1.0:
                    over_speed = 1.0
                if over_change < 1.0:
                    over_change = 1.0
                excess = over_speed * over_change
                out = out or excess > 1.0
                sigma = sigma * excess
            scale[i, j] = sigma
            x = abs(w0) / sigma
            if x > peak or x != x:
                peak = x
        ratio[i], outside[i] = peak, out
        if out:
            outside_samples[i] += 1
