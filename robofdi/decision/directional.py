"""Directional residual evaluation with confirmation: isolate the hypothesis whose fault direction explains the
alarmed residual best, once the same hypothesis has won several consecutive samples — fixed-direction residuals
(Gertler, *Fault Detection and Diagnosis in Engineering Systems*, 1998, Sec. 7.1; Chen & Patton 1999, Sec. 2.4).

A threshold signature test decides on which components cross first; during an observer's transient an actuator
fault can raise the components of a sensor fault before its own steady pattern appears (the race noted in the
linear core). Comparing the residual's *direction* with each hypothesis' steady-state direction gᵢ (e.g. the DC
gain columns of :class:`robofdi.observers.linear.ObserverResidual`) and waiting for ``confirm`` agreeing samples
removes that race:

    misfitᵢ = ‖W^{1/2}(r − gᵢ f̂ᵢ)‖ / ‖W^{1/2} r‖,   f̂ᵢ = gᵢᵀ W r / gᵢᵀ W gᵢ,   W = diag(threshold⁻²)
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from robofdi.decision.isolation import Alarms
from robofdi.errors import RobofdiError

__all__ = ["DirectionalDecision"]


class DirectionalDecision:
    """Decision protocol: alarms |r_j| > threshold_j; isolation by the best-fitting direction, confirmed.

    directions: hypothesis name → its residual direction (one value per component). confirm: consecutive alarmed
    samples the same hypothesis must win (with misfit ≤ ``max_misfit``) before it is isolated. latch: an isolated
    hypothesis stays isolated. blanking: start-up samples without alarms. ``misfit``: the last misfits.
    """

    def __init__(self, components: Sequence[str], threshold, directions: Mapping[str, Sequence[float]],
                 confirm: int = 10, max_misfit: float = 0.5, latch: bool = True, blanking: int = 0):
        self.components = tuple(components)
        m = len(self.components)
        self.threshold = np.array(threshold, dtype=float)
        if self.threshold.shape != (m,) or not np.all(np.isfinite(self.threshold) & (self.threshold > 0)):
            raise RobofdiError(f"DirectionalDecision: field 'threshold' must be {m} finite values > 0")
        if not directions:
            raise RobofdiError("DirectionalDecision: field 'directions' must name at least one hypothesis")
        self.names = list(directions)
        G = np.array([np.asarray(directions[h], dtype=float) for h in self.names])
        if G.shape != (len(self.names), m) or not np.all(np.isfinite(G)):
            raise RobofdiError(f"DirectionalDecision: every direction must hold {m} finite values (one per component)")
        w = 1.0 / self.threshold**2
        norms = np.einsum("hj,j,hj->h", G, w, G)
        if np.any(norms <= 0):
            bad = self.names[int(np.flatnonzero(norms <= 0)[0])]
            raise RobofdiError(f"DirectionalDecision: hypothesis {bad!r} has a zero direction (undetectable)")
        if isinstance(confirm, bool) or not isinstance(confirm, (int, np.integer)) or confirm < 1:
            raise RobofdiError(f"DirectionalDecision: field 'confirm' must be an integer >= 1, got {confirm!r}")
        if not (0 < max_misfit <= 1):
            raise RobofdiError(f"DirectionalDecision: field 'max_misfit' must be in (0, 1], got {max_misfit!r}")
        self._G, self._w, self._norms = G, w, norms
        self.confirm, self.max_misfit, self.latch, self.blanking = int(confirm), float(max_misfit), latch, int(blanking)
        self.reset()

    def reset(self) -> None:
        self._samples = 0
        self._streak = 0
        self._leader = None
        self._isolated: list[str] = []
        self.misfit = np.ones(len(self.names))

    def update(self, residual: np.ndarray) -> Alarms:
        r = np.asarray(residual, dtype=float)
        if r.shape != self.threshold.shape or not np.all(np.isfinite(r)):
            raise RobofdiError(f"DirectionalDecision: residual must be {self.threshold.size} finite values")
        self._samples += 1
        alarm = np.abs(r) > self.threshold
        if self._samples <= self.blanking:
            alarm[:] = False
        previous = list(self._isolated)
        if alarm.any():
            w = self._w
            fit = (self._G * w) @ r / self._norms                               # f̂ᵢ
            res = r[None, :] - fit[:, None] * self._G
            self.misfit = np.sqrt(np.einsum("hj,j,hj->h", res, w, res) / max(float(r @ (w * r)), 1e-300))
            best = int(np.argmin(self.misfit))
            if self.misfit[best] <= self.max_misfit and best == self._leader:
                self._streak += 1
            else:
                self._leader, self._streak = (best, 1) if self.misfit[best] <= self.max_misfit else (None, 0)
            if self._streak >= self.confirm:
                name = self.names[best]
                self._isolated = (self._isolated + [name]) if self.latch and name not in self._isolated else (
                    self._isolated if self.latch else [name])
        else:
            self._leader, self._streak = None, 0
            if not self.latch:
                self._isolated = []
        new = tuple(f for f in self._isolated if f not in previous)
        return Alarms(alarm=alarm, isolated=tuple(self._isolated), new=new)
