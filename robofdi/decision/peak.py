"""Decisions for sliding-mode residuals — Saif & Xiong, book ch. 1: the peak (max-hold) test of the incipient-fault
SMFO (Sec. 6.2, "a peak appears when the fault derivative changes abruptly") and the logic-table isolation of
Example 5 (r1 = r2 ≠ 0: f_a2; r1 = 0, r2 ≠ 0: f_a1; r1 ≠ 0, r2 ≠ 0, r1 ≠ r2: both)."""
from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robofdi.checks import is_int
from robofdi.decision.isolation import Alarms, Signature, ThresholdDecision
from robofdi.errors import RobofdiError, all_finite

__all__ = ["PeakHoldDecision", "LogicRule", "LogicTableDecision"]


class PeakHoldDecision:
    """Decision protocol: the max-hold of |r_j| over the last ``hold`` samples against ``threshold_j``, then
    isolation by ``signatures`` as :class:`ThresholdDecision` does (latched). A residual peak shorter than one
    sample is caught when the diagnoser reports its in-interval peak (:attr:`CascadeSMO.peak`) as the residual.
    ``held``: the held values of the last sample."""

    def __init__(self, components: Sequence[str], threshold, signatures: Sequence[Signature] = (), hold: int = 50,
                 blanking: int = 0, latch: bool = True):
        if not is_int(hold, 1):
            raise RobofdiError(f"PeakHoldDecision: field 'hold' must be a number of samples >= 1, got {hold!r}")
        self._decision = ThresholdDecision(components, threshold, signatures, latch=latch, blanking=blanking)
        self.components, self.threshold = self._decision.components, self._decision.threshold
        self.hold = int(hold)
        self.reset()

    def reset(self) -> None:
        self._decision.reset()
        self._window: deque = deque(maxlen=self.hold)
        self.held = np.zeros(len(self.components))

    def update(self, residual) -> Alarms:
        r = np.asarray(residual, dtype=float)
        if r.shape != (len(self.components),) or not all_finite(r):
            raise RobofdiError(f"PeakHoldDecision: field 'residual' must be {len(self.components)} finite values, got {r!r}")
        self._window.append(np.abs(r))
        self.held = np.max(np.array(self._window), axis=0)
        return self._decision.update(self.held)


@dataclass(frozen=True)
class LogicRule:
    """One row of a logic table: the faults it isolates, which components must be nonzero (True) or zero
    (False), and pairs (a, b) that must agree (|r_a − r_b| ≤ agreement) or differ (in ``differ``)."""

    faults: tuple[str, ...]
    nonzero: dict
    agree: tuple[tuple[str, str], ...] = ()
    differ: tuple[tuple[str, str], ...] = ()


class LogicTableDecision:
    """Decision protocol: Example 5's isolation logic table on moving-average residuals.

    Each component is averaged over the last ``window`` samples (the digest: r2 scatters ±0.3–0.4 from chattering,
    so it needs ≥ 2 s of averaging), is "nonzero" when |r̄_j| > ``threshold_j``; the first rule whose pattern
    holds isolates its faults (latched: once a rule fires for ``confirm`` consecutive samples it stays).
    Alarms: the nonzero pattern. ``agreement``: |r̄_a − r̄_b| ≤ agreement·max(|r̄_a|, |r̄_b|) counts as equal."""

    def __init__(self, components: Sequence[str], threshold, rules: Sequence[LogicRule], window: int = 2000,
                 agreement: float = 0.25, confirm: int = 100, blanking: int = 0):
        self.components = tuple(components)
        m = len(self.components)
        self.threshold = np.array(threshold, dtype=float)
        if self.threshold.shape != (m,) or not np.all(np.isfinite(self.threshold)) or np.any(self.threshold <= 0):
            raise RobofdiError(f"LogicTableDecision: field 'threshold' must be {m} values > 0, got {threshold!r}")
        for name, v, least in (("window", window, 1), ("confirm", confirm, 1), ("blanking", blanking, 0)):
            if not is_int(v, least):
                raise RobofdiError(f"LogicTableDecision: field {name!r} must be an integer >= {least}, got {v!r}")
        if not (np.isfinite(agreement) and 0 < agreement < 1):
            raise RobofdiError(f"LogicTableDecision: field 'agreement' must be in (0, 1), got {agreement!r}")
        self._index = {c: j for j, c in enumerate(self.components)}
        for rule in rules:
            names = list(rule.nonzero) + [c for pair in rule.agree + rule.differ for c in pair]
            unknown = [c for c in names if c not in self._index]
            if unknown:
                raise RobofdiError(f"LogicTableDecision: rule {rule.faults}: component {unknown[0]!r} is not one of "
                                   f"{list(self.components)}")
        self.rules = tuple(rules)
        self.window, self.agreement, self.confirm, self.blanking = int(window), float(agreement), int(confirm), int(blanking)
        self.reset()

    def reset(self) -> None:
        self._sum = np.zeros(len(self.components))
        self._buf: deque = deque()
        self._samples = 0
        self._streak = (None, 0)
        self._isolated: tuple[str, ...] = ()
        self.mean = np.zeros(len(self.components))
        self.rule = None

    def _equal(self, a: float, b: float) -> bool:
        return abs(a - b) <= self.agreement * max(abs(a), abs(b))

    def classify(self, mean: np.ndarray):
        """The first rule whose pattern the averaged residuals ``mean`` satisfy (None: no rule)."""
        nz = np.abs(mean) > self.threshold
        ix = self._index
        for rule in self.rules:
            if any(bool(nz[ix[c]]) != bool(want) for c, want in rule.nonzero.items()):
                continue
            if any(not self._equal(mean[ix[a]], mean[ix[b]]) for a, b in rule.agree):
                continue
            if any(self._equal(mean[ix[a]], mean[ix[b]]) for a, b in rule.differ):
                continue
            return rule
        return None

    def update(self, residual) -> Alarms:
        r = np.asarray(residual, dtype=float)
        m = len(self.components)
        if r.shape != (m,) or not all_finite(r):
            raise RobofdiError(f"LogicTableDecision: field 'residual' must be {m} finite values, got {r!r}")
        self._samples += 1
        if self._samples <= self.blanking:
            return Alarms(np.zeros(m, dtype=bool), self._isolated)
        self._buf.append(r)
        self._sum += r
        if len(self._buf) > self.window:
            self._sum -= self._buf.popleft()
        self.mean = self._sum / len(self._buf)
        alarm = np.abs(self.mean) > self.threshold
        if len(self._buf) < self.window:
            return Alarms(np.zeros(m, dtype=bool), self._isolated)
        rule = self.classify(self.mean)
        self.rule = rule
        last, count = self._streak
        self._streak = (rule, count + 1 if rule is last else 1)
        new: tuple[str, ...] = ()
        if rule is not None and self._streak[1] >= self.confirm:
            merged = tuple(dict.fromkeys(self._isolated + rule.faults))
            new = tuple(f for f in merged if f not in self._isolated)
            self._isolated = merged
        return Alarms(alarm, self._isolated, new)
