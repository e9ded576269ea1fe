"""What a diagnoser returns each sample, and the input check every diagnoser applies."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError, all_finite
from robofdi.jit import kernel

__all__ = ["Residual", "check_measurement", "shared_measurement"]


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


@kernel
def _copy_finite(v, out):
    """out = v, entry by entry; False when an entry is not finite."""
    finite = True
    for i in range(v.shape[0]):
        out[i] = v[i]
        finite = finite and math.isfinite(v[i])
    return finite


_FLOAT = np.dtype(float)
_SHARED: dict[str, tuple[bytes, np.ndarray]] = {}     # field name → (the last checked values' bytes, their copy)


def shared_measurement(v, size: int, field: str) -> np.ndarray:
    """:func:`check_measurement` for diagnosers that never write into their inputs: the checked copy is read-only,
    and the same copy is handed to every caller that checks the same values (the same bytes) under the same field
    name as the last such check. The arm's diagnosers see one y and one ū a sample, so the copy and the finiteness
    test are made once a sample, not once per diagnoser. Bytes equal means bits equal: the result is what
    :func:`check_measurement` returns (a new buffer's values make a new copy)."""
    if type(v) is np.ndarray and v.dtype is _FLOAT and v.shape == (size,):
        key = v.tobytes()
        hit = _SHARED.get(field)
        if hit is not None and hit[0] == key:
            return hit[1]
        a = np.empty(size)
        if not _copy_finite(v, a):                # NaN/inf: check_measurement's error names the entries
            a = check_measurement(v, size, field)
        a.flags.writeable = False
        _SHARED[field] = (key, a)
        return a
    a = check_measurement(v, size, field)
    a.flags.writeable = False
    return a
