"""Operating-point-dependent residual bounds (dynamic thresholds), designed once per robot.

A fault-free residual of a robot is not equally large everywhere: friction is uncertain near zero velocity
(stiction, the Stribeck hump), model errors grow with the torque. The bound

    |r_i(k)| ≤ b_i(k) = c_iᵀ LP(φ_i(k)),   φ_i = [1, |τ_i|, exp(−(q̇_i/v_r)²), exp(−(q̇_i/v_b)²)],   c_i ≥ 0

follows the operating point (LP: the residual's own dynamics, so that bound and residual lag alike). The
coefficients are the tightest such bound over fault-free runs — a linear programme (minimise the mean bound
subject to covering every sample; the adaptive-threshold idea of Frank & Ding 1997, J. Process Control 7(6),
with the envelope found by LP instead of by hand). A residual divided by its bound is ≤ 1 on the design runs;
how far above 1 it goes on motions the design never saw is measured and becomes the margin.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linprog

from robofdi.errors import RobofdiError
from robofdi.jit import kernel

__all__ = ["ENVELOPE_FEATURES", "envelope_features", "filtered_features", "design_envelope"]

#: Names of the features φ, in order.
ENVELOPE_FEATURES = ("constant", "torque", "rest", "low_speed")
REST_VELOCITY = 0.02      # v_r [rad/s]: the stiction zone
LOW_SPEED_VELOCITY = 0.15  # v_b [rad/s]: the Stribeck zone


def envelope_features(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., n, 4) features φ of the module docstring from torques u (..., n) [N·m] and velocities v [rad/s]."""
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    if u.shape != v.shape:          # np.stack names the mismatch
        return np.stack([np.ones_like(u), np.abs(u), np.exp(-(v / REST_VELOCITY) ** 2),
                         np.exp(-(v / LOW_SPEED_VELOCITY) ** 2)], axis=-1)
    if u.ndim == 1:                 # one sample (a diagnoser's hot path): the arithmetic compiled, exp NumPy's
        out, arguments = np.empty(u.shape + (4,)), np.empty((2,) + u.shape)
        _feature_rows(u, v, REST_VELOCITY, LOW_SPEED_VELOCITY, out, arguments)
        out[:, 2] = np.exp(arguments[0])
        out[:, 3] = np.exp(arguments[1])
        return out
    out = np.empty(u.shape + (4,))  # the rows np.stack makes, written in place (the same ufuncs on the same arrays)
    out[..., 0] = 1.0
    out[..., 1] = np.abs(u)
    out[..., 2] = np.exp(-(v / REST_VELOCITY) ** 2)
    out[..., 3] = np.exp(-(v / LOW_SPEED_VELOCITY) ** 2)
    return out


def filtered_features(features: np.ndarray, a: float, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(1 − a) ``features`` + a φ(u, v): one step of the first-order low pass LP of the features (module
    docstring), a new (n, 4) array; for one sample the arithmetic is compiled, exp NumPy's (the bits of the array
    form)."""
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    if u.ndim != 1 or u.shape != v.shape or np.shape(features) != u.shape + (4,):
        return (1 - a) * features + a * envelope_features(u, v)
    arguments, out = np.empty((2,) + u.shape), np.empty(u.shape + (4,))
    _feature_arguments(v, REST_VELOCITY, LOW_SPEED_VELOCITY, arguments)
    _low_pass(np.asarray(features, dtype=float), float(a), u, np.exp(arguments[0]), np.exp(arguments[1]), out)
    return out


@kernel
def _feature_arguments(v, rest, low_speed, arguments):
    """The exp arguments −(q̇/v_r)², −(q̇/v_b)² of the features into ``arguments`` (2, n)."""
    for i in range(v.shape[0]):
        x, y = v[i] / rest, v[i] / low_speed
        arguments[0, i] = -(x * x)
        arguments[1, i] = -(y * y)


@kernel
def _low_pass(features, a, u, rest, low_speed, out):
    """(1 − a) features + a φ entry by entry (φ = [1, |u|, rest, low_speed]), as the array form computes it."""
    b = 1.0 - a
    for i in range(u.shape[0]):
        out[i, 0] = b * features[i, 0] + a * 1.0
        out[i, 1] = b * features[i, 1] + a * abs(u[i])
        out[i, 2] = b * features[i, 2] + a * rest[i]
        out[i, 3] = b * features[i, 3] + a * low_speed[i]


@kernel
def _feature_rows(u, v, rest, low_speed, out, arguments):
    """The constant and |τ| features into ``out`` (n, 4), the exp arguments −(q̇/v_r)², −(q̇/v_b)² into
    ``arguments`` (2, n), entry by entry as the array form computes them."""
    for i in range(u.shape[0]):
        out[i, 0] = 1.0
        out[i, 1] = abs(u[i])
        x, y = v[i] / rest, v[i] / low_speed
        arguments[0, i] = -(x * x)
        arguments[1, i] = -(y * y)


def design_envelope(features: Sequence[np.ndarray], residuals: Sequence[np.ndarray], skip: int = 0,
                    max_samples: int = 20000) -> np.ndarray:
    """Coefficients c (n, F) >= 0 of the tightest bound c_iᵀ φ_i(k) >= |r_i(k)| over the runs (a linear
    programme per component, scipy's HiGHS). ``features``: one (N, n, F) array of *filtered* features per
    run; ``residuals``: one (N, n) array per run; samples k < ``skip`` left out. Long data: the programme starts
    from ``max_samples`` evenly spaced samples plus the largest |r|, and adds every sample the bound misses until
    none is left (cutting planes), so the bound covers every sample."""
    if len(features) == 0 or len(features) != len(residuals):
        raise RobofdiError(f"design_envelope: expected as many feature as residual runs (>= 1), got "
                           f"{len(features)} and {len(residuals)}")
    X = np.concatenate([np.asarray(f, dtype=float)[skip:] for f in features])
    R = np.abs(np.concatenate([np.asarray(r, dtype=float)[skip:] for r in residuals]))
    if X.ndim != 3 or R.shape != X.shape[:2]:
        raise RobofdiError(f"design_envelope: features {X.shape} must be (N, n, F) and residuals (N, n)")
    if X.shape[0] == 0:
        raise RobofdiError(f"design_envelope: no samples left after skip={skip}")
    n, F = X.shape[1], X.shape[2]
    coef = np.zeros((n, F))
    for i in range(n):
        # scaled to O(1) (the solver's tolerances are absolute), the result scaled back
        col = np.maximum(np.abs(X[:, i]).max(axis=0), 1e-300)
        top = max(float(R[:, i].max()), 1e-300)
        A, b = X[:, i] / col, R[:, i] / top
        rows = np.arange(A.shape[0])
        if rows.size > max_samples:     # start from a subset, then add every violated sample (cutting planes)
            rows = np.unique(np.concatenate([np.linspace(0, rows.size - 1, max_samples).astype(int),
                                             np.argsort(b)[-max_samples // 10:]]))
        for _ in range(20):
            res = linprog(c=A.mean(axis=0) + 1e-9, A_ub=-A[rows], b_ub=-b[rows], bounds=[(0, None)] * F,
                          method="highs")
            if res.status != 0:
                raise RobofdiError(f"design_envelope: component {i}: the linear programme failed ({res.message})")
            x = res.x * (1 + 1e-6)          # clear of the solver's feasibility tolerance
            violated = np.flatnonzero(A @ x < b)
            if violated.size == 0:
                break
            rows = np.union1d(rows, violated)
        coef[i] = x * top / col
    return coef
