"""Hotelling T² detection — the data-driven, model-free scheme of Antonelli's survey, Sec. 4 ([7, 29]; its digest
§3.7 gives the standard form used here).

A feature vector x (e.g. body velocities, commanded thrusts, tracking errors) is fitted on m fault-free samples
(mean μ, covariance S); a new sample is out of control when

    T² = (x − μ)ᵀ S⁻¹ (x − μ)  >  UCL = p (m + 1)(m − 1) / (m (m − p)) · F_α(p, m − p)

(the upper control limit for a new observation, p features, F the Fisher quantile at 1 − α). Isolation [a
reconstruction: the survey names none]: the nearest faulty-class centroid in the whitened space, when classes are
given; "unknown" otherwise.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import f as fisher

from robofdi.decision.isolation import Alarms
from robofdi.errors import RobofdiError, all_finite

__all__ = ["HotellingFit", "hotelling_fit", "hotelling_ucl", "HotellingT2Decision"]


def hotelling_ucl(p: int, m: int, alpha: float) -> float:
    """UCL = p (m+1)(m−1) / (m (m−p)) · F_{1−α}(p, m−p), for a new observation (p features, m fit samples)."""
    if not (isinstance(p, (int, np.integer)) and isinstance(m, (int, np.integer)) and 1 <= p < m):
        raise RobofdiError(f"hotelling_ucl: need integers 1 <= p < m (features, samples), got p={p!r}, m={m!r}")
    if not (isinstance(alpha, float) and 0 < alpha < 1):
        raise RobofdiError(f"hotelling_ucl: field 'alpha' must be a probability in (0, 1), got {alpha!r}")
    return float(p * (m + 1) * (m - 1) / (m * (m - p)) * fisher.ppf(1 - alpha, p, m - p))


@dataclass(frozen=True)
class HotellingFit:
    """μ (p,), S⁻¹ (p, p), the whitening W (S⁻¹ = WᵀW), UCL and the fit size m."""

    mean: np.ndarray
    precision: np.ndarray
    whitening: np.ndarray
    ucl: float
    samples: int


def hotelling_fit(samples, alpha: float = 0.01) -> HotellingFit:
    """Fit μ and S on fault-free rows ``samples`` (m, p); UCL at false-alarm probability ``alpha`` per sample."""
    X = np.asarray(samples, dtype=float)
    if X.ndim != 2 or X.shape[0] <= X.shape[1] or not np.all(np.isfinite(X)):
        raise RobofdiError(f"hotelling_fit: field 'samples' must be finite (m, p) rows with m > p, got shape {X.shape}")
    m, p = X.shape
    S = np.cov(X, rowvar=False).reshape(p, p)
    if np.linalg.matrix_rank(S) < p:
        raise RobofdiError("hotelling_fit: the sample covariance is singular (a constant or dependent feature)")
    precision = np.linalg.inv(S)
    W = np.linalg.cholesky(precision).T                   # precision = Wᵀ W
    return HotellingFit(X.mean(axis=0), precision, W, hotelling_ucl(p, m, alpha), m)


class HotellingT2Decision:
    """Decision protocol: T² of each feature row against the fit's UCL; when it exceeds, every component alarms
    (T² is a joint statistic) and the sample is classified to the nearest of ``classes`` (name → feature-space
    centroid of that faulty class) in the whitened space, or "unknown". ``statistic`` holds the last T²;
    ``isolated`` accumulates the classes named so far."""

    def __init__(self, components: Sequence[str], fit: HotellingFit, classes: Mapping[str, Sequence[float]] | None = None):
        self.components = [str(c) for c in components]
        p = len(self.components)
        if not isinstance(fit, HotellingFit) or fit.mean.shape != (p,):
            raise RobofdiError(f"HotellingT2Decision: field 'fit' must be a HotellingFit of {p} features")
        self.fit = fit
        self.threshold = np.full(p, fit.ucl)
        self.classes = {}
        for name, c in (classes or {}).items():
            c = np.asarray(c, dtype=float)
            if c.shape != (p,) or not np.all(np.isfinite(c)):
                raise RobofdiError(f"HotellingT2Decision: class {name!r} must be a centroid of {p} finite values")
            self.classes[str(name)] = fit.whitening @ (c - fit.mean)
        self.reset()

    def reset(self) -> None:
        self.statistic = 0.0
        self._isolated: list[str] = []

    def update(self, residual: np.ndarray) -> Alarms:
        x = np.asarray(residual, dtype=float)
        p = len(self.components)
        if x.shape != (p,) or not all_finite(x):
            raise RobofdiError(f"HotellingT2Decision: field 'residual' must be {p} finite values, got {x!r}")
        d = x - self.fit.mean
        t2 = float(d @ self.fit.precision @ d)
        self.statistic = t2
        if t2 <= self.fit.ucl:
            return Alarms(alarm=np.zeros(p, dtype=bool), isolated=tuple(self._isolated))
        name = "unknown"
        if self.classes:
            z = self.fit.whitening @ d
            name = min(self.classes, key=lambda k: float(np.sum((z - self.classes[k]) ** 2)))
        new = () if name in self._isolated else (name,)
        self._isolated += list(new)
        return Alarms(alarm=np.ones(p, dtype=bool), isolated=tuple(self._isolated), new=new)
