"""What a diagnoser returns each sample, and the input check every diagnoser applies."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError, all_finite

__all__ = ["Residual", "check_measurement"]


@dataclass
class Residual:
    """One sample of a diagnoser: the residual vector and the fault-magnitude candidates (identification)."""

    r: np.ndarray
    estimate: np.ndarray
    state_residual: np.ndarray | None = None


def check_measurement(v, size: int, field: str) -> np.ndarray:
    """Return v as a float vector of ``size`` entries; NaN/inf or a wrong shape raise naming the field."""
    a = np.array(v, dtype=float)  # a copy: diagnosers keep past samples, callers may reuse their buffers
    if a.shape != (size,):
        raise RobofdiError(f"diagnoser input {field!r} must be a vector of {size} values, got shape {a.shape}")
    if not all_finite(a):
        bad = np.flatnonzero(~np.isfinite(a)).tolist()
        raise RobofdiError(f"diagnoser input {field!r} has non-finite values at indices {bad} (NaN/inf measurement)")
    return a
