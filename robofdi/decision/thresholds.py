"""Threshold design from fault-free residuals."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi import RobofdiError

__all__ = ["calibrate_thresholds", "extreme_value_thresholds", "THRESHOLD_FLOOR"]

#: Smallest threshold handed out, so that a residual component that stayed exactly 0 still gets a positive bound.
THRESHOLD_FLOOR = 1e-12


def calibrate_thresholds(residuals: Sequence[np.ndarray], margin: float = 1.2, skip: int = 0) -> np.ndarray:
    """Empirical thresholds, margin × max |r_j| over fault-free runs — Caccavale & Villani Sec. 6.

    ``residuals`` holds one (N_i, m) array per fault-free run; samples k < ``skip`` of every run (the
    observer's start-up transient) are ignored. Returns the (m,) threshold, every entry > 0.
    """
    if isinstance(residuals, np.ndarray):
        residuals = [residuals]
    if len(residuals) == 0:
        raise RobofdiError("residuals: expected at least one (N, m) array from a fault-free run, got none")
    margin = float(margin)
    if not np.isfinite(margin) or margin < 1.0:
        raise RobofdiError(f"margin: expected a finite number >= 1, got {margin}")
    if isinstance(skip, bool) or not isinstance(skip, (int, np.integer)) or skip < 0:
        raise RobofdiError(f"skip: expected an integer >= 0, got {skip!r}")

    m = None
    peak = None                          # running max |r| over the samples used so far
    for i, run in enumerate(residuals):
        r = np.asarray(run, dtype=float)
        if r.ndim != 2:
            raise RobofdiError(f"residuals[{i}]: expected a 2-D (N, m) array, got shape {r.shape}")
        if m is None:
            m = r.shape[1]
            if m == 0:
                raise RobofdiError("residuals[0]: expected at least one residual component, got 0")
        elif r.shape[1] != m:
            raise RobofdiError(f"residuals[{i}]: expected {m} components like residuals[0], got {r.shape[1]}")
        if not np.all(np.isfinite(r)):
            k, j = np.argwhere(~np.isfinite(r))[0]
            raise RobofdiError(f"residuals[{i}]: expected finite values, got {r[k, j]} at sample {k}, component {j}")
        used = r[skip:]
        if used.shape[0]:
            run_peak = np.abs(used).max(axis=0)
            peak = run_peak if peak is None else np.maximum(peak, run_peak)
    if peak is None:
        raise RobofdiError(f"residuals: no samples left after skip={skip} in any run; expected at least one")
    return np.maximum(margin * peak, THRESHOLD_FLOOR)


def extreme_value_thresholds(residuals: Sequence[np.ndarray], sample_time: float, rate_per_hour: float = 0.01,
                             block: float = 0.25, skip: int = 0, tail: str | Sequence[str] = "gumbel",
                             tail_fraction: float = 0.3) -> np.ndarray:
    """Thresholds for a target false-alarm rate λ [1/h] from fault-free residuals: the maxima of |r_j| over
    blocks of ``block`` s follow a Gumbel law (extreme-value theory, Coles 2001, *An Introduction to Statistical
    Modeling of Extreme Values*, Sec. 3.1–3.4); the threshold is the level a block maximum exceeds with
    probability λ·block/3600, i.e. λ exceedances per hour of operation. Never below the largest |r_j| seen.
    For Gaussian-like residuals the fitted Gumbel tail is conservative (measured: 5–10× fewer exceedances than
    λ, tests/test_decision.py); residuals dominated by motion-dependent model error are what it is for.
    ``residuals``: one (N_i, m) array per fault-free run, sampled every ``sample_time`` s; samples k < ``skip``
    ignored. Needs at least 20 blocks in all. A component whose block maxima do not vary (0 on fault-free data)
    gets that value.
    ``tail="exponential"`` fits only the largest ``tail_fraction`` of the block maxima instead of all of them: the
    excesses over their (1 − ζ) quantile u follow an exponential law (the generalized Pareto law with shape 0,
    Coles 2001 Sec. 4.2–4.3; σ̂ their mean), and the level is u + σ̂ ln(ζ/p) (Coles eq. 4.13, ξ = 0, with p the
    exceedance probability per block). The Gumbel fit lets the bulk of the maxima set the tail; this one only
    the upper part, which matters where the bulk spreads from 0 (a bound that fits some motions tightly and
    others loosely). It needs more data to be safe: each component's tail comes from ζ of the blocks. ``tail`` may
    also name one law per component."""
    from scipy.stats import gumbel_r

    if not (np.isfinite(rate_per_hour) and rate_per_hour > 0):
        raise RobofdiError(f"rate_per_hour: expected a false-alarm rate > 0 per hour, got {rate_per_hour!r}")
    tails = [tail] if isinstance(tail, str) else list(tail)
    if not tails or any(t not in ("gumbel", "exponential") for t in tails):
        raise RobofdiError(f"tail: expected 'gumbel' or 'exponential', or one of them per component, got {tail!r}")
    if not (np.isfinite(tail_fraction) and 0 < tail_fraction < 1):
        raise RobofdiError(f"tail_fraction: expected a fraction of the block maxima in (0, 1), got {tail_fraction!r}")
    if not (np.isfinite(sample_time) and sample_time > 0 and np.isfinite(block) and block >= sample_time):
        raise RobofdiError(f"block: expected a block length >= the sample time {sample_time!r} s, got {block!r}")
    size = int(round(block / sample_time))
    maxima = []
    for i, run in enumerate(residuals):
        r = np.abs(np.asarray(run, dtype=float))[skip:]
        if r.ndim != 2 or not np.all(np.isfinite(r)):
            raise RobofdiError(f"residuals[{i}]: expected a finite 2-D (N, m) array, got shape {r.shape}")
        whole = r.shape[0] // size
        if whole:
            maxima.append(r[: whole * size].reshape(whole, size, -1).max(axis=1))
    if not maxima or sum(m.shape[0] for m in maxima) < 20:
        raise RobofdiError(f"residuals: expected at least 20 blocks of {block} s of fault-free data, got "
                           f"{sum(m.shape[0] for m in maxima) if maxima else 0}")
    maxima = np.concatenate(maxima)
    if len(tails) not in (1, maxima.shape[1]):
        raise RobofdiError(f"tail: expected one law or one per component ({maxima.shape[1]}), got {len(tails)}")
    tails = tails * maxima.shape[1] if len(tails) == 1 else tails
    p = rate_per_hour * block / 3600.0
    out = np.empty(maxima.shape[1])
    for j in range(maxima.shape[1]):
        column = maxima[:, j]
        if np.ptp(column) <= 1e-12 * max(1.0, float(column.max())):   # no spread (a row that is 0 fault-free)
            out[j] = float(column.max())
            continue
        if tails[j] == "exponential":
            u = float(np.quantile(column, 1.0 - tail_fraction))
            excess = column[column > u] - u
            level = u + float(excess.mean()) * float(np.log(tail_fraction / p)) if excess.size else u
        else:
            level = float(gumbel_r.isf(p, *gumbel_r.fit(column)))
        out[j] = max(level, float(column.max()))
    return np.maximum(out, THRESHOLD_FLOOR)
