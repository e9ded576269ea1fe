"""Threshold design from fault-free residuals."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi import RobofdiError

__all__ = ["calibrate_thresholds", "THRESHOLD_FLOOR"]

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
