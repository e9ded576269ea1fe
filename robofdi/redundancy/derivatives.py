"""Time derivatives of sampled, noisy signals: a Savitzky–Golay filter (scipy.signal.savgol_coeffs), sample by
sample, with its delay reported.

Savitzky & Golay, Anal. Chem. 36(8), 1964: a least-squares polynomial of degree ``order`` over the last
``window`` samples, differentiated at ``position`` inside the window. "center" (default) is the accurate, delayed
estimate: every signal and derivative refers to the time (window − 1)/2 samples ago, so a residual built from it
lags by :attr:`SavitzkyGolay.delay` — part of every detection delay. "end" evaluates at the newest sample (no
delay, noisier, biased on curvature).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.signal

from robofdi.errors import RobofdiError

__all__ = ["SavitzkyGolay", "DerivativeEstimator", "estimate_derivatives"]


@dataclass(frozen=True)
class SavitzkyGolay:
    """Filter settings: ``window`` samples (odd, > order), polynomial ``order``, derivatives up to ``max_derivative``
    (≤ order), evaluation ``position`` "center" or "end"; ``dt`` the sample period [s]."""

    dt: float
    window: int = 41
    order: int = 3
    max_derivative: int = 2
    position: str = "center"

    def __post_init__(self):
        if not (isinstance(self.dt, (int, float)) and np.isfinite(self.dt) and self.dt > 0):
            raise RobofdiError(f"SavitzkyGolay: field 'dt' must be a sample period > 0 s, got {self.dt!r}")
        if isinstance(self.order, bool) or not isinstance(self.order, (int, np.integer)) or self.order < 1:
            raise RobofdiError(f"SavitzkyGolay: field 'order' must be an integer >= 1, got {self.order!r}")
        w = self.window
        if isinstance(w, bool) or not isinstance(w, (int, np.integer)) or w % 2 == 0 or w <= self.order:
            raise RobofdiError(f"SavitzkyGolay: field 'window' must be an odd integer > order ({self.order}), got {w!r}")
        q = self.max_derivative
        if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or not 0 <= q <= self.order:
            raise RobofdiError(f"SavitzkyGolay: field 'max_derivative' must be in [0, order={self.order}], got {q!r}")
        if self.position not in ("center", "end"):
            raise RobofdiError(f"SavitzkyGolay: field 'position' must be 'center' or 'end', got {self.position!r}")

    @property
    def delay(self) -> float:
        """[s] between the newest sample and the instant the estimates refer to."""
        return (self.window - 1) / 2 * self.dt if self.position == "center" else 0.0

    def coefficients(self) -> np.ndarray:
        """(max_derivative + 1, window) weights on the samples oldest → newest; row k gives the k-th derivative."""
        pos = self.window // 2 if self.position == "center" else self.window - 1
        return np.array([scipy.signal.savgol_coeffs(self.window, self.order, deriv=k, delta=self.dt, pos=pos,
                                                    use="dot") for k in range(self.max_derivative + 1)])


@dataclass
class DerivativeEstimator:
    """Sample-by-sample derivatives of a vector signal: :meth:`update` pushes one sample of c channels and returns
    the (max_derivative + 1, c) estimates once ``window`` samples are in, None before."""

    settings: SavitzkyGolay
    channels: int
    _buffer: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        self._weights = self.settings.coefficients()
        self.reset()

    def reset(self) -> None:
        self._buffer = np.zeros((self.settings.window, self.channels))
        self._count = 0

    def update(self, x: np.ndarray) -> np.ndarray | None:
        buf = self._buffer
        buf[:-1] = buf[1:]
        buf[-1] = x
        self._count += 1
        if self._count < self.settings.window:
            return None
        return self._weights @ buf


def estimate_derivatives(signal, settings: SavitzkyGolay) -> np.ndarray:
    """Offline: (N − window + 1, max_derivative + 1, c) estimates of an (N, c) or (N,) record, one per full window
    (row i refers to sample i + window − 1 − delay/dt). Too short a record is an error naming the window."""
    x = np.asarray(signal, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise RobofdiError(f"estimate_derivatives: field 'signal' must be an (N,) or (N, c) array, got shape {x.shape}")
    if x.shape[0] < settings.window:
        raise RobofdiError(f"estimate_derivatives: too few samples for the derivative filter: {x.shape[0]} samples, "
                           f"the Savitzky–Golay window needs at least {settings.window}")
    windows = np.lib.stride_tricks.sliding_window_view(x, settings.window, axis=0)   # (M, c, w)
    return np.einsum("kw,mcw->mkc", settings.coefficients(), windows)
