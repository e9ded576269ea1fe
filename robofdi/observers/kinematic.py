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

The velocity noise, integrated. White velocity noise of σ_v makes the window sums a random walk: Σ_W e has a
standard deviation of σ_n √W, with σ_n = T σ_v the long-run standard deviation of e's noise per sample (the
trapezoid integrates the velocity noise; the encoder's quantisation telescopes out of a sum). Near rest σ_W is
its constant a_W alone, and the tightest bound over the design runs is the largest of a few hundred window sums
there, about 3 σ_n √W: a lucky low one that runs of an hour exceed by chance (arm7: a 0.5 s window at 4.9 σ_n √W
as a joint came to rest, with the skew's share). So each window's constant is at least
:data:`NOISE_WALK_SIGMAS` σ_n √W, with σ_n identified from the design runs' increments
(:func:`identify_noise_walk`).

The scales are valid over the operating envelope they were designed on: the largest mean_W |q̇| and
|q̇_k − q̇_{k−W}| seen (``reach``). Outside it the bound is not extrapolated linearly: σ_W is multiplied by how
far outside the point is (the product of the ratios over the reach, each at least 1), and the samples outside
are counted (:attr:`KinematicConsistency.outside`), so a motion faster than any calibrated one widens the
tolerance instead of raising a false alarm.

Aliased torque ripple. A drive's ripple of order m (cycles per radian of the joint: multiples of 6 per
electrical period, twice per motor revolution for a strain-wave gear, so m = k G for the gear ratio G) makes a
small velocity ripple at m|q̇|/2π Hz, which the velocity sensor samples without an anti-aliasing filter. Where
that frequency comes near a non-zero multiple of the diagnosis rate 1/T, the ripple is sampled at nearly the same
phase every sample and the trapezoid integrates it as if it were a velocity bias: e_k holds c_m exp(i m q_k)
(its real part; c_m complex, |c_m| [rad] the per-sample error of the aliased ripple), whose window sum is at most
|c_m| |Σ_W a_k exp(i m q_k)|, with a_k = 1 on samples near an alias (the ripple phase advance per sample,
m|q̇_k| T, within :data:`ALIAS_BAND` of a turn of a non-zero whole number of turns: an aliased frequency below
0.1/T), else 0 (farther from an alias the aliased ripple turns fast and averages out in the sums, which the
design's scales hold). That sum is W for a ripple whose aliased phase stands still. |c_m| is identified per joint
and order from the design runs' samples near an alias (:func:`identify_ripple`), and σ_W gains
Σ_m |c_m| |Σ_W a_k exp(i m q_k)|: the tolerance follows the ripple's coherence, which no design run has to have
held (arm6's wrist cruising at 8.7 rad/s, G = 60: 6G|q̇|/2π = 500 Hz, reached 2.8× its threshold without it).
Near an alias a velocity bias and the ripple cannot be told apart; the term is what that costs. An order whose
alias no design run came near gets the single-sample scale as |c_m| (:func:`identify_ripple`'s fallback). The
orders are nominal (:func:`ripple_orders`, from the file's gear ratios), not the plant's.

A drive's ripple also grows with the torque it carries (the load-dependent ripple of a permanent-magnet drive:
Jahns & Soong 1996), so c_m = A_m + B_m τ_k, with τ_k the joint's torque command over the sample. Where the design
runs' near-alias samples show B_m (its Wald statistic above :data:`RIPPLE_LOAD_WALD`), the window sum is at most
|A_m| |Σ_W a_k exp(i m q_k)| + |B_m| |Σ_W a_k τ_k exp(i m q_k)|; elsewhere B_m = 0 and the term is the one above
(arm6's wrist passing the alias only on the top-speed motion, at −20 to +25 N·m: |c| 1.8 µrad as a constant,
5.2 µrad at −18 N·m with the torque, where a fault-free fast run cruising there showed 5.8 µrad).

Valid only when the velocity does not come from differentiating the same encoder (then e ≡ 0 by construction
and encoder faults must be found through the dynamics).
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from robofdi.decision.envelope import design_envelope
from robofdi.errors import RobofdiError
from robofdi.jit import kernel

__all__ = ["KinematicConsistency", "kinematic_increments", "identify_skew", "design_window_scales", "WINDOWS",
           "SKEW_INSTRUMENT", "window_reach", "ripple_orders", "identify_ripple", "RIPPLE_CYCLES", "ALIAS_BAND",
           "ALIAS_SAMPLES", "identify_noise_walk", "NOISE_WALK_SIGMAS", "NOISE_WALK_LAGS"]

#: Window lengths [s] of the accumulated inconsistency (0 = the single sample).
WINDOWS = (0.0, 0.1, 0.5, 2.0, 4.0)
#: The longest window whose scale is learnt from the calibration suite alone. A 2 s scale learnt from the suite's
#: few 2 s windows was measured to underestimate the random walk of the integrated velocity noise (false alarms on
#: unseen motions: arm campaign, run 1 of seed 10); longer windows get at least this window's scale grown as a
#: random walk, a_W >= a_L √(W/L), b_W >= b_L (the trapezoid and skew errors telescope in a sum: they do not grow).
LEARNT_WINDOW = 0.5
#: Standard deviations of the velocity noise's random walk that every window's constant covers: a_W >=
#: κ σ_n √W (module docstring). A sum of white noise passes 4 σ with a probability of 6.3e-5 per window, and the
#: calibrated threshold multiplies the scale again; the design's own constants were measured at 2.9–4.6 σ_n √W
#: (arm7, robot instance 11; joint 6's 0.5 s window, which alarmed on a fault-free run, at 3.0).
NOISE_WALK_SIGMAS = 4.0
#: Lags of the autocovariance that :func:`identify_noise_walk` sums: e's noise is a moving average over two
#: samples (the trapezoid, the skew term and the quantisation difference), with a little room for a drive's filter.
NOISE_WALK_LAGS = 3


#: Samples near an alias, for :func:`identify_ripple`: the ripple phase advance per sample within this fraction of
#: a turn of a non-zero whole number of turns.
ALIAS_BAND = 0.1
#: Fewest near-alias samples of a joint and order from which :func:`identify_ripple` estimates |c_m|.
ALIAS_SAMPLES = 20
#: The Wald statistic (two degrees of freedom) above which :func:`identify_ripple` keeps a torque-dependent ripple
#: B_m: far beyond chance (χ²₂ exceeds 25 with probability 4e-6), since the increments' errors are not white.
RIPPLE_LOAD_WALD = 25.0

#: Torque-ripple periods per motor revolution whose aliasing the kinematic rows guard against: the permanent-magnet
#: drive's 6th harmonic of the electrical period and its 2nd and 3rd multiples (Jahns & Soong 1996, IEEE TIE 43(2)),
#: and the strain-wave gear's 2 per wave-generator revolution (Tuttle & Seering 1996, IEEE TRA 12(2)).
RIPPLE_CYCLES = (6.0, 12.0, 18.0, 2.0)


def ripple_orders(gear_ratio: np.ndarray, cycles: Sequence[float] = RIPPLE_CYCLES) -> np.ndarray:
    """(n, len(cycles)) ripple orders m = k G [cycles/rad of the joint] of drives with gear ratios G (n,)
    (dimensionless, from the datasheet: :attr:`robofdi.models.ManipulatorModel.gear_ratio`)."""
    G = np.asarray(gear_ratio, dtype=float)
    if G.ndim != 1 or not np.all(np.isfinite(G) & (G > 0)):
        raise RobofdiError(f"ripple_orders: field 'gear_ratio' must be finite values > 0 (one per joint), got {G!r}")
    k = np.asarray(cycles, dtype=float)
    if k.ndim != 1 or not np.all(np.isfinite(k) & (k > 0)):
        raise RobofdiError(f"ripple_orders: field 'cycles' must be finite values > 0, got {cycles!r}")
    return G[:, None] * k[None, :]


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
    with e_k (whose noise is that of q_k, q_{k−1}, q̇_k and q̇_{k−1}), so the estimate is consistent; the
    denominator Σ Δq̇ z may be negative (a joint oscillating at about a quarter of the sample rate, where the
    lagged change is anti-correlated: robosuite's iiwa's light last joint), only not ≈ 0. For a
    plant integrated with semi-implicit Euler steps of h and accelerations constant over a sample, the skew
    is h/2 (q gains h·q̇_{j+1} per step: Σ h q̇_j − T (q̇_k + q̇_{k−1})/2 = (h/2) Δq̇)."""
    lag, span = SKEW_INSTRUMENT
    first = max(skip, 1, lag + span)
    num, den, size = 0.0, 0.0, 0.0
    for q, v in zip(qs, vs):
        v = np.asarray(v, dtype=float)
        if v.shape[0] <= first:
            continue
        e = kinematic_increments(q, v, T)[first:]
        dv = (v[1:] - v[:-1])[first - 1:]
        z = v[first - lag:v.shape[0] - lag] - v[first - lag - span:v.shape[0] - lag - span]
        num, den, size = num + (e * z).sum(axis=0), den + (dv * z).sum(axis=0), size + np.abs(dv * z).sum(axis=0)
    den = np.asarray(den, dtype=float)
    if np.isscalar(num) or np.any(~(np.abs(den) > 1e-6 * size)):
        raise RobofdiError("identify_skew: the fault-free runs must move every joint (no velocity change seen)")
    return num / den


def identify_noise_walk(increments: Sequence[np.ndarray], skip: int = 0, lags: int = NOISE_WALK_LAGS) -> np.ndarray:
    """(n,) long-run standard deviation σ_n [rad] per sample of the fault-free increments e (one (N, n) array per
    run): √(γ₀ + 2 Σ_{l=1}^{L} γ_l), the autocovariances γ_l of e pooled over the runs (each run's mean removed,
    samples k < ``skip`` left out), truncated at L = ``lags`` (the long-run variance, Newey & West 1987,
    Econometrica 55(3)). A window sum of W samples of e's noise then has a standard deviation of σ_n √W; for a
    drive's white velocity noise σ_v, σ_n = T σ_v."""
    gamma, count = 0.0, 0
    for e in increments:
        e = np.asarray(e, dtype=float)[max(skip, 1):]
        if e.shape[0] <= lags:
            continue
        e = e - e.mean(axis=0)
        gamma = gamma + np.stack([(e[l:] * e[:e.shape[0] - l]).sum(axis=0) for l in range(lags + 1)])
        count += e.shape[0]
    if not count:
        raise RobofdiError(f"identify_noise_walk: expected fault-free runs longer than skip + {lags} samples")
    gamma = gamma / count
    return np.sqrt(np.maximum(gamma[0] + 2 * gamma[1:].sum(axis=0), 0.0))


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
                         skip: int = 0, windows: Sequence[float] = WINDOWS,
                         noise_walk: np.ndarray | None = None) -> np.ndarray:
    """Scale coefficients (n, len(windows), 3) = (a_W, b_W, c_W) [rad, rad/(rad/s), s] of
    σ_W = a_W + b_W mean_W |q̇| + c_W |q̇_k − q̇_{k−W}|: the tightest such bound on |Σ_W e| over fault-free runs
    (increments e and velocities: one (N, n) each), each constant at least :data:`NOISE_WALK_SIGMAS` σ_n √W given
    the noise's long-run standard deviation ``noise_walk`` σ_n (n,) [rad] (:func:`identify_noise_walk`)."""
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
    if noise_walk is not None:                          # the velocity noise's random walk (module docstring)
        walk = np.asarray(noise_walk, dtype=float)
        if walk.shape != (n,) or not np.all(np.isfinite(walk) & (walk >= 0)):
            raise RobofdiError(f"design_window_scales: field 'noise_walk' must be {n} finite values >= 0 [rad], "
                               f"got {noise_walk!r}")
        coef[..., 0] = np.maximum(coef[..., 0], NOISE_WALK_SIGMAS * walk[:, None] * np.sqrt(sizes)[None, :])
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


def identify_ripple(qs: Sequence[np.ndarray], vs: Sequence[np.ndarray], T: float, skew: np.ndarray,
                    orders: np.ndarray, skip: int = 0, fallback: np.ndarray | None = None,
                    us: Sequence[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(|A_m|, |B_m|), each (n, n_orders), of each aliased ripple order (module docstring): the per-sample error
    |c_m| = |A_m + B_m τ| [rad] with B_m [rad/(N·m)]. e_k is regressed on (cos m q_k, sin m q_k) and, given the
    torque commands ``us`` (one (K, n) array per run, τ_k the command over the sample ending at k), on τ_k times
    them, by least squares over the fault-free runs' samples whose ripple phase advance m|q̇_k| T is within
    :data:`ALIAS_BAND` of a turn of a non-zero whole number of turns (near an alias, where e_k ≈ Re(c_m exp(i m q_k))).
    B_m is kept where its Wald statistic exceeds :data:`RIPPLE_LOAD_WALD`; elsewhere B_m = 0 and A_m is the fit
    without it. Where fewer than :data:`ALIAS_SAMPLES` such samples exist, A_m is ``fallback`` (n,) (e.g. the
    single-sample scale) for every order of that joint, or 0 if None."""
    orders = np.asarray(orders, dtype=float)
    n, n_orders = orders.shape
    gram = np.zeros((n, n_orders, 4, 4))
    moment = np.zeros((n, n_orders, 4))
    square = np.zeros((n, n_orders))
    count = np.zeros((n, n_orders), dtype=int)
    for r, (q, v) in enumerate(zip(qs, vs)):
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        tau = np.zeros_like(q) if us is None else np.asarray(us[r], dtype=float)
        e = kinematic_increments(q, v, T, skew)[max(skip, 1):, :, None]
        q, v, tau = q[max(skip, 1):, :, None], v[max(skip, 1):, :, None], tau[max(skip, 1):, :, None]
        turns = orders[None] * np.abs(v) * T / (2 * np.pi)
        whole = np.floor(turns + 0.5)
        near = (whole >= 1) & (np.abs(turns - whole) < ALIAS_BAND)
        c, s = np.cos(orders[None] * q), np.sin(orders[None] * q)
        x = np.stack([c, s, tau * c, tau * s], axis=-1) * near[..., None]
        gram += np.einsum("kjoa,kjob->joab", x, x)
        moment += np.einsum("kjoa,kjo->joa", x, e * near)
        square += np.einsum("kjo,kjo->jo", e * near, e * near)
        count += near.sum(axis=0)
    amplitude, load = np.zeros((n, n_orders)), np.zeros((n, n_orders))
    enough = count >= ALIAS_SAMPLES
    for i, o in zip(*np.nonzero(enough)):
        amplitude[i, o] = np.hypot(*np.linalg.lstsq(gram[i, o, :2, :2], moment[i, o, :2], rcond=None)[0])
        if us is None or count[i, o] < 2 * ALIAS_SAMPLES:
            continue
        g, m = gram[i, o], moment[i, o]
        if np.linalg.cond(g) > 1e12:
            continue
        coef = np.linalg.solve(g, m)
        dof = count[i, o] - 4
        variance = max(square[i, o] - coef @ m, 0.0) / dof              # the residual variance of the full fit
        wald = coef[2:] @ np.linalg.solve(np.linalg.inv(g)[2:, 2:] * variance, coef[2:]) if variance > 0 else np.inf
        if wald > RIPPLE_LOAD_WALD:
            amplitude[i, o], load[i, o] = np.hypot(*coef[:2]), np.hypot(*coef[2:])
    if fallback is not None:
        amplitude = np.where(enough, amplitude, np.asarray(fallback, dtype=float)[:, None])
    return amplitude, load


class KinematicConsistency:
    """Stepping form: ``update(q, v)`` → (per joint: max_W |Σ_W e| / σ_W (dimensionless), e_k [rad]).
    ``reach`` (n, len(windows), 2): the designed operating envelope (:func:`window_reach`); None = unbounded.
    ``orders`` (n, n_orders) [cycles/rad] and ``ripple`` (n, n_orders) [rad]: the drives' ripple orders
    (:func:`ripple_orders`) and their aliased per-sample errors |A_m| (:func:`identify_ripple`), whose coherent
    sums widen σ_W (module docstring); None = none. ``ripple_load`` (n, n_orders) [rad/(N·m)]: |B_m|, the part
    that grows with the joint's torque command (``update``'s ``tau``); None = none. :attr:`outside` (n,) says,
    per joint, whether the last sample was outside the reach in some window, and :attr:`outside_samples` counts
    such samples since :meth:`reset`; :attr:`scale` (n, len(windows)) holds the last sample's σ_W [rad]."""

    def __init__(self, T: float, skew: np.ndarray, scales: np.ndarray, windows: Sequence[float] = WINDOWS,
                 reach: np.ndarray | None = None, orders: np.ndarray | None = None, ripple: np.ndarray | None = None,
                 ripple_load: np.ndarray | None = None):
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
        if (orders is None) != (ripple is None):
            raise RobofdiError("KinematicConsistency: give both 'orders' and 'ripple' (one amplitude per order), or "
                               "neither")
        self.orders = np.zeros((n, 0)) if orders is None else np.asarray(orders, dtype=float)
        self.ripple = np.zeros((n, 0)) if ripple is None else np.asarray(ripple, dtype=float)
        if (self.orders.ndim != 2 or self.orders.shape[0] != n or not np.all(np.isfinite(self.orders) & (self.orders > 0))
                or self.ripple.shape != self.orders.shape or not np.all(np.isfinite(self.ripple) & (self.ripple >= 0))):
            raise RobofdiError(f"KinematicConsistency: fields 'orders' and 'ripple' must be ({n}, n_orders) arrays of "
                               f"ripple orders > 0 [cycles/rad] and amplitudes >= 0 [rad], got shapes "
                               f"{self.orders.shape} and {self.ripple.shape}")
        self.ripple_load = np.zeros_like(self.ripple) if ripple_load is None else np.asarray(ripple_load, dtype=float)
        if self.ripple_load.shape != self.ripple.shape or not np.all(np.isfinite(self.ripple_load) & (self.ripple_load >= 0)):
            raise RobofdiError(f"KinematicConsistency: field 'ripple_load' must be None or an array of the shape of "
                               f"'ripple' {self.ripple.shape} of amplitudes >= 0 [rad/(N·m)], got shape "
                               f"{self.ripple_load.shape}")
        self.ripple_load = np.ascontiguousarray(self.ripple_load)
        self.sizes = _window_samples(self.T, windows)
        self._none = np.zeros(0)
        self._no_torque = np.zeros(n)
        self._sizes = np.array(self.sizes, dtype=np.int64)
        self._reach = np.ones((n, len(windows), 2)) if self.reach is None else np.ascontiguousarray(self.reach)
        self.scales = np.ascontiguousarray(self.scales)
        self.skew = np.ascontiguousarray(self.skew)
        self.orders, self.ripple = np.ascontiguousarray(self.orders), np.ascontiguousarray(self.ripple)
        self.reset()

    def reset(self) -> None:
        self._prev = None
        n = self.skew.shape[0]
        # ring buffer of cumulative sums of e, |q̇|, Δq̇ and, per ripple order, cos and sin of m q, and τ times them
        self._history = np.zeros((max(self.sizes) + 1, 3 + 4 * self.orders.shape[1], n))
        self._k = 0
        self.outside = np.zeros(n, dtype=bool)
        self.outside_samples = np.zeros(n, dtype=int)

    def update(self, q: np.ndarray, v: np.ndarray, explained: np.ndarray | None = None,
               tau: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """One sample: (the ratios, the increments e_k [rad]). ``explained`` (n,) [rad]: the part of e_k that a
        velocity change within the sample makes (:class:`~robofdi.observers.consistency.ConsistencyResidual`): the
        window sums take e_k shrunk towards 0 by up to it where it has e_k's sign; None: all of e_k. ``tau`` (n,)
        [N·m]: the torque commands over the sample, which the load-dependent ripple follows; None: 0."""
        n, windows = self.skew.shape[0], len(self.sizes)
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        ratio, e = np.empty(n), np.empty(n)
        outside, scales = np.empty(n, dtype=bool), np.empty((n, windows))
        qp, vp = self._prev if self._prev is not None else (q, v)
        _kinematic_step(q, v, qp, vp, self._prev is None, self.T, self.skew,
                        self._none if explained is None else explained, self._history, self._k, self._sizes,
                        self.scales, self.orders, self.ripple, self._reach, self.reach is not None, ratio, e, outside,
                        scales, self.outside_samples, self._no_torque if tau is None else np.asarray(tau, dtype=float),
                        self.ripple_load)
        self._prev = (q, v)
        self._k += 1
        self.outside, self.scale = outside, scales
        return ratio, e


@kernel
def _kinematic_step(q, v, qp, vp, first, T, skew, explained, history, k, sizes, scales, orders, ripple, reach,
                    bounded, ratio, e, outside, scale, outside_samples, tau, ripple_load):
    """One sample of :meth:`KinematicConsistency.update`, joint by joint in the order of operations of its array
    form: e_k (summed shrunk towards 0 by up to ``explained``, where that has its sign; length 0: none), the
    cumulative sums in the ring buffer ``history`` at sample ``k`` (e, |q̇|, Δq̇, then cos and
    sin of m q per ripple order of ``orders`` on samples near an alias, and ``tau`` times them), each window's sum
    over its scale σ_W (plus the ``ripple`` amplitude times each order's coherent sum and ``ripple_load`` times its
    torque-weighted one; widened outside ``reach`` when ``bounded``); writes
    ``ratio``, ``e``, ``outside``, ``scale`` and counts ``outside_samples``."""
    size, n_orders = history.shape[0], orders.shape[1]
    now, before = k % size, (k - 1) % size
    for i in range(q.shape[0]):
        if first:
            ei, dvi = 0.0, 0.0
        else:
            dvi = v[i] - vp[i]
            ei = q[i] - qp[i] - T * (v[i] + vp[i]) / 2 - skew[i] * dvi
        e[i] = ei
        x = explained[i] if explained.shape[0] else 0.0
        if x * ei > 0:          # a velocity change within the sample made (up to) x of e_k: not summed
            ei = ei - x if abs(x) < abs(ei) else 0.0
        if k:
            c0, c1, c2 = history[before, 0, i] + ei, history[before, 1, i] + abs(v[i]), history[before, 2, i] + dvi
        else:
            c0, c1, c2 = ei, abs(v[i]), dvi
        history[now, 0, i], history[now, 1, i], history[now, 2, i] = c0, c1, c2
        for o in range(n_orders):
            phase = orders[i, o] * q[i]
            turns = orders[i, o] * abs(v[i]) * T / (2 * math.pi)
            whole = math.floor(turns + 0.5)
            if whole >= 1 and abs(turns - whole) < ALIAS_BAND:      # near an alias (module docstring)
                cos, sin = math.cos(phase), math.sin(phase)
            else:
                cos, sin = 0.0, 0.0
            if ripple_load[i, o] > 0:       # the torque-weighted sums, read only where a load part was kept
                tcos, tsin = tau[i] * cos, tau[i] * sin
                if k:
                    tcos, tsin = history[before, 5 + 4 * o, i] + tcos, history[before, 6 + 4 * o, i] + tsin
                history[now, 5 + 4 * o, i], history[now, 6 + 4 * o, i] = tcos, tsin
            if k:
                cos, sin = history[before, 3 + 4 * o, i] + cos, history[before, 4 + 4 * o, i] + sin
            history[now, 3 + 4 * o, i], history[now, 4 + 4 * o, i] = cos, sin
        peak, out = 0.0, False
        for j in range(sizes.shape[0]):
            w = sizes[j]
            back = (k - w) % size
            if k >= w:
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
            for o in range(n_orders):       # the aliased ripple's largest contribution to this window's sum
                wc, ws = history[now, 3 + 4 * o, i], history[now, 4 + 4 * o, i]
                if k >= w:
                    wc, ws = wc - history[back, 3 + 4 * o, i], ws - history[back, 4 + 4 * o, i]
                sigma = sigma + ripple[i, o] * math.sqrt(wc * wc + ws * ws)
                if ripple_load[i, o] > 0:   # and its load-dependent part's
                    wc, ws = history[now, 5 + 4 * o, i], history[now, 6 + 4 * o, i]
                    if k >= w:
                        wc, ws = wc - history[back, 5 + 4 * o, i], ws - history[back, 6 + 4 * o, i]
                    sigma = sigma + ripple_load[i, o] * math.sqrt(wc * wc + ws * ws)
            scale[i, j] = sigma
            x = abs(w0) / sigma
            if x > peak or x != x:
                peak = x
        ratio[i], outside[i] = peak, out
        if out:
            outside_samples[i] += 1


# The batch form of the kernel above (robofdi.lockstep): on every run's rows, one call a sample for all runs.
@kernel
def _kinematic_step_each(Y, Y_prev, first, T, skew, explained, history, k, sizes, scales, orders, ripple, reach, bounded,
                         ratio, e, outside, scale, outside_samples, U, ripple_load):
    """One sample per run (``ratio`` (a, n); Y, Y_prev (a, 2n) the states [q; q̇]; the per-run arrays (≥ a, …)):
    _kinematic_step."""
    n = ratio.shape[1]
    for i in range(ratio.shape[0]):
        _kinematic_step(Y[i, :n], Y[i, n:], Y_prev[i, :n], Y_prev[i, n:], first, T, skew[i], explained[i], history[i], k,
                        sizes, scales[i], orders[i], ripple[i], reach[i], bounded[i], ratio[i], e[i], outside[i],
                        scale[i], outside_samples[i], U[i], ripple_load[i])
