"""Windowed parity (t-type) test on a residual — Wang, book ch. 2, eqs. (20)–(23)."""
from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np

from robofdi.decision.isolation import Alarms, Signature, ThresholdDecision
from robofdi.errors import RobofdiError, all_finite

__all__ = ["WindowedTTest", "DENOMINATORS"]

DENOMINATORS = ("std", "var_literal")


class WindowedTTest:
    """Decision protocol: per component the statistic |m_ε − v₀| / (s / √(N+1)) over the last N+1 samples,
    m_ε the window mean (21), s_ε = Σ(ē − m_ε)²/N the window variance (22); alarm where it exceeds λ (23), then
    isolation by ``signatures`` as in :class:`ThresholdDecision`.

    denominator: "std" divides by √s_ε (a t statistic: the digest's recommended reading); "var_literal" by s_ε as
    printed (scale-dependent; spec W2 [GARBLED]). With s_ε = 0 (noise-free) the statistic is 0 when
    |m_ε − v₀| < ``tol`` and +inf otherwise. No alarm before the window is full. ``statistic``: the last value.
    """

    def __init__(self, components: Sequence[str], threshold, signatures: Sequence[Signature], window: int = 10,
                 v0=0.0, denominator: str = "std", tol: float = 1e-9, latch: bool = False):
        if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
            raise RobofdiError(f"WindowedTTest: field 'window' must be an integer N >= 1, got {window!r}")
        if denominator not in DENOMINATORS:
            raise RobofdiError(f"WindowedTTest: field 'denominator' must be one of {DENOMINATORS}, got {denominator!r}")
        self._decision = ThresholdDecision(components, threshold, signatures, latch=latch)
        self.components = self._decision.components
        self.threshold = self._decision.threshold
        self.window, self.denominator, self.tol = int(window), denominator, float(tol)
        self.v0 = np.broadcast_to(np.array(v0, dtype=float), (len(self.components),)).copy()
        self.reset()

    def reset(self) -> None:
        self._decision.reset()
        self._buffer: deque = deque(maxlen=self.window + 1)
        self.statistic = np.zeros(len(self.components))

    def update(self, residual: np.ndarray) -> Alarms:
        r = np.asarray(residual, dtype=float)
        if r.shape != (len(self.components),) or not all_finite(r):
            raise RobofdiError(f"WindowedTTest: field 'residual' must be {len(self.components)} finite values, got {r!r}")
        self._buffer.append(r)
        m = len(self.components)
        if len(self._buffer) <= self.window:
            self.statistic = np.zeros(m)
            return Alarms(alarm=np.zeros(m, dtype=bool), isolated=tuple(self._decision._isolated))
        w = np.array(self._buffer)
        N = self.window
        mean = w.mean(axis=0)                                                    # (21)
        var = np.sum((w - mean) ** 2, axis=0) / N                                # (22)
        scale = np.sqrt(var) if self.denominator == "std" else var
        dev = np.abs(mean - self.v0)
        with np.errstate(divide="ignore", invalid="ignore"):
            stat = np.where(scale > 0, dev / (scale / np.sqrt(N + 1)), np.where(dev < self.tol, 0.0, np.inf))
        self.statistic = stat
        # the threshold decision sees the statistic in units of λ (finite stand-in for +inf)
        return self._decision.update(np.minimum(stat, 1e300))
