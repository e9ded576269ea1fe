"""Threshold decision and isolation by fault signatures."""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from robofdi import RobofdiError
from robofdi.jit import kernel

__all__ = ["Signature", "Alarms", "ThresholdDecision", "STARTUP_BLANKING", "startup_samples"]

#: Default start-up blanking [s]: no alarm, and no calibration sample, in the first 10 ms of a run.
STARTUP_BLANKING = 0.010


def startup_samples(sample_time: float, blanking: float = STARTUP_BLANKING) -> int:
    """Number of diagnosis samples of period ``sample_time`` [s] inside the start-up blanking [s]."""
    if not (np.isfinite(sample_time) and sample_time > 0):
        raise RobofdiError(f"sample_time: expected a positive sample time in s, got {sample_time}")
    if not (np.isfinite(blanking) and blanking >= 0):
        raise RobofdiError(f"blanking: expected a duration >= 0 s, got {blanking}")
    return int(np.ceil(blanking / sample_time - 1e-9))


@kernel
def _peak_ratio(r, threshold):
    """max_j |r_j| / threshold_j, NaN when an entry of r is NaN: the one test of a sample (the values of
    ``(np.abs(r) / threshold).max()``, without its three array operations)."""
    peak = abs(r[0]) / threshold[0]
    for j in range(1, r.shape[0]):
        x = abs(r[j]) / threshold[j]
        if x > peak or x != x:
            peak = x
    return peak


@kernel
def _peak_ratio_each(R, thresholds, peaks):
    """:func:`_peak_ratio` of every run's row (R and thresholds (a, m)) into ``peaks`` (a,) (robofdi.lockstep)."""
    for i in range(peaks.shape[0]):
        peaks[i] = _peak_ratio(R[i], thresholds[i])


def _component_set(value: Iterable[str], name: str) -> frozenset[str]:
    if isinstance(value, str):
        raise RobofdiError(f"{name}: expected a set of component names, got the single string {value!r}")
    items = frozenset(value)
    bad = [c for c in items if not isinstance(c, str)]
    if bad:
        raise RobofdiError(f"{name}: expected component names (str), got {bad[0]!r}")
    return items


@dataclass(frozen=True)
class Signature:
    """Which residual components a fault must raise (``required``) and which it may also raise (``allowed``)."""

    fault: str
    required: frozenset[str]
    allowed: frozenset[str] = frozenset()

    def __post_init__(self):
        if not isinstance(self.fault, str) or not self.fault:
            raise RobofdiError(f"fault: expected a non-empty fault name such as 'joint3', got {self.fault!r}")
        if "+" in self.fault:
            raise RobofdiError(f"fault: '+' joins isolated faults in records and cannot be part of a name, got {self.fault!r}")
        required = _component_set(self.required, f"signature {self.fault!r} required")
        if not required:
            raise RobofdiError(f"signature {self.fault!r} required: expected at least one residual component")
        object.__setattr__(self, "required", required)
        object.__setattr__(self, "allowed", _component_set(self.allowed, f"signature {self.fault!r} allowed"))

    @property
    def explains(self) -> frozenset[str]:
        """Every component this fault can account for: required ∪ allowed."""
        return self.required | self.allowed


@dataclass(frozen=True)
class Alarms:
    """Decision at one sample: alarm per component, faults isolated so far, faults isolated at this sample."""

    alarm: np.ndarray
    isolated: tuple[str, ...] = ()
    new: tuple[str, ...] = ()


@dataclass
class ThresholdDecision:
    """Fixed-threshold alarms |r_j| > threshold_j — Caccavale & Villani eq. (49) — and signature isolation.

    At each sample the alarmed components are explained greedily: among signatures whose required components
    all alarm (and which explain a still unexplained one), pick the one with the largest
    max_{j in required} |r_j| / threshold_j (on a tie, the one with more required components), mark its
    required ∪ allowed components explained, repeat.
    Finally a pick is dropped when the other picks already explain all its required components
    (parsimony: a sensor fault that may raise every torque residual wins over the actuator faults it explains).
    With ``latch`` an isolated fault stays isolated for the rest of the run.

    Confirmation: with ``confirm`` = c > 0 samples, nothing is isolated at the first alarm; c samples later the
    decision is taken over every hypothesis at once, on the components that alarmed in at least two samples of
    that window (one isolated crossing is evidence of nothing) and their peak ratios — so isolation does not
    depend on which residual crossed first (a velocity-sensor fault raising its kinematic row one sample after
    its dynamic row). When nothing persisted, nothing is isolated ("unknown") and the next alarm opens a new
    window. Alarms are not delayed. With ``latch``, a confirmed fault keeps explaining its components: later alarms
    add a fault only for components it cannot raise (a velocity fault isolated from its step row is not joined
    by the encoder fault its kinematic row alone would suggest, once the step row has decayed). With ``overturn``
    = N > 0, evidence that persists overturns the hypothesis it refines: a hypothesis whose required components
    strictly contain an isolated fault's replaces that fault once they have all alarmed for N samples in a row,
    whichever isolated fault may also account for them (an encoder fault, its kinematic row, becomes a velocity
    fault, kinematic and step rows, once the step row has alarmed with it for N samples, also beside a payload
    change that may raise every step row).

    Deferral: with ``defer`` = D > 0 samples (and ``confirm``), a confirmation window whose picks include a fault
    that another hypothesis refines (its required components a strict superset of the fault's) runs D samples
    longer before it decides, over the whole window: the refinement's other components get the time the motion
    needs to show them (an encoder fault, its kinematic row alone, against a velocity-gain error, whose step row
    holds the gain evidence only once the joint has moved for a few tens of samples). Alarms are not delayed;
    the isolation of such a fault is, by D samples.

    Revision: with ``release`` = R > 0 samples (and ``confirm``), an isolation is a decision the evidence can
    overturn. Once no component has alarmed for R samples the alarm episode that led to it is over, and the next
    alarm opens a fresh confirmation window over every hypothesis; at its end the faults it isolates join those
    of the earlier isolation whose required components persisted in that window too, and the others are dropped
    (a false isolation on a fault-free transient does not explain, and so mask, a later real fault). A window
    that isolates nothing leaves the isolation as it was. R = 0: latched for the run, as before.

    Evidence thresholds: inside a confirmation window a component counts as evidence when |r_j| exceeds
    ``evidence_j`` (default: its alarm threshold; at most that). A lower evidence level suits a component that
    only tells hypotheses apart: it need not carry the false-alarm rate on its own, because it is read only
    once another component has alarmed (the two-threshold scheme: detection, then isolation).

    Start-up blanking: the first ``blanking`` samples after :meth:`reset` raise no alarm — the observer's
    start-up transient. Calibration ignores the same samples (``calibrate_thresholds(skip=blanking)``), so the
    threshold is never tested on samples it was not designed on; :func:`startup_samples` converts the
    duration (default :data:`STARTUP_BLANKING` = 10 ms) into samples for both.
    """

    components: Sequence[str]
    threshold: np.ndarray
    signatures: Sequence[Signature]
    latch: bool = True
    blanking: int = 0
    confirm: int = 0
    evidence: np.ndarray | None = None
    release: int = 0
    overturn: int = 0
    defer: int = 0
    _isolated: list[str] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self):
        self.components = tuple(self.components)
        if not self.components or not all(isinstance(c, str) for c in self.components):
            raise RobofdiError(f"components: expected a non-empty sequence of names, got {self.components!r}")
        dup = sorted({c for c in self.components if self.components.count(c) > 1})
        if dup:
            raise RobofdiError(f"components: expected unique names, got {dup[0]!r} more than once")
        m = len(self.components)
        self.threshold = np.array(self.threshold, dtype=float)
        if self.threshold.shape != (m,):
            raise RobofdiError(f"threshold: expected shape ({m},) for {m} components, got {self.threshold.shape}")
        bad = np.flatnonzero(~np.isfinite(self.threshold) | (self.threshold <= 0))
        if bad.size:
            j = bad[0]
            raise RobofdiError(
                f"threshold: expected finite values > 0, got {self.threshold[j]} for component {self.components[j]!r}"
            )
        if self.evidence is None:
            self.evidence = self.threshold.copy()
        self.evidence = np.array(self.evidence, dtype=float)
        if self.evidence.shape != (m,):
            raise RobofdiError(f"evidence: expected shape ({m},) for {m} components, got {self.evidence.shape}")
        bad = np.flatnonzero(~np.isfinite(self.evidence) | (self.evidence <= 0) | (self.evidence > self.threshold))
        if bad.size:
            j = bad[0]
            raise RobofdiError(f"evidence: expected values in (0, threshold], got {self.evidence[j]} for component "
                               f"{self.components[j]!r} (threshold {self.threshold[j]})")
        self._evidence_ratio = self.evidence / self.threshold
        self.signatures = tuple(self.signatures)
        names = [s.fault for s in self.signatures]
        for sig in self.signatures:
            if not isinstance(sig, Signature):
                raise RobofdiError(f"signatures: expected Signature objects, got {type(sig).__name__}")
            if names.count(sig.fault) > 1:
                raise RobofdiError(f"signatures: expected one signature per fault, got {sig.fault!r} more than once")
            unknown = sorted(sig.explains - set(self.components))
            if unknown:
                raise RobofdiError(
                    f"signature {sig.fault!r}: component {unknown[0]!r} is not a residual component; "
                    f"expected one of {list(self.components)}"
                )
        for name in ("blanking", "confirm", "release", "overturn", "defer"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise RobofdiError(f"{name}: expected an integer number of samples >= 0, got {value!r}")
        self._index = {c: j for j, c in enumerate(self.components)}
        self._by_fault = {s.fault: s for s in self.signatures}
        # the hypotheses that refine each fault: their required components a strict superset of its own (overturn)
        self._refinements = {s.fault: tuple((h.fault, tuple(self._index[c] for c in sorted(h.required)))
                                            for h in self.signatures if s.required < h.required)
                             for s in self.signatures}
        self._tables_of, self._explained_masks = None, {}
        self.reset()

    def reset(self) -> None:
        """Forget everything isolated so far (start of a new run)."""
        self._isolated = []
        self._samples = 0
        self._window = None         # [samples left, peak ratio, alarmed, deferred] while an alarm is being confirmed
        self._quiet_for = None      # the isolated tuple _quiet was made for
        self._since_alarm = 0       # samples since the last alarm (revision: release)
        self._revising = False      # a confirmation window is open to revise an isolation
        self._refining = {}         # samples in a row each refining hypothesis's rows all alarmed (overturn)
        self._refined_at = -1       # the sample those counts were last made at
        self._shape = (len(self.components),)

    @property
    def settled(self) -> bool:
        """No confirmation window is open: a sample without alarm is then quiet (:meth:`skip`)."""
        return self._window is None

    def skip(self, samples: int) -> None:
        """Account for ``samples`` quiet samples at once — samples that raised no alarm (or fell in the start-up
        blanking) while :attr:`settled`, with ``latch``: the counts :meth:`update` keeps for them, which is all
        it changes there (its answer is :meth:`_quiet`'s, the isolation unchanged). The lockstep engine
        (:mod:`robofdi.lockstep`) tests many runs' samples at once and updates a run only when it alarms."""
        if samples:
            start = self._samples
            self._samples += samples
            self._since_alarm += self._samples - max(start, min(self._samples, self.blanking))

    def _quiet(self) -> Alarms:
        """The decision at a sample without alarm and without an open confirmation window: nothing new, the
        isolated faults unchanged (latched) or none — made once per isolation state, its alarm read-only."""
        isolated = tuple(self._isolated) if self.latch else ()
        if self._quiet_for != isolated:
            alarm = np.zeros(self._shape, dtype=bool)
            alarm.flags.writeable = False
            self._quiet_alarms, self._quiet_for = Alarms(alarm=alarm, isolated=isolated), isolated
        if not self.latch:
            self._isolated = []
        return self._quiet_alarms

    def update(self, residual: np.ndarray) -> Alarms:
        """One residual sample (m,) in, alarms and isolation out.

        Array first: one test max |r| / threshold per sample (a compiled kernel, :mod:`robofdi.jit`); a sample
        without alarm (and no confirmation window open) returns at once (:meth:`_quiet`, exactly what the
        isolation logic gives there: nothing new), the ratios and the isolation logic are computed only on samples
        that alarm."""
        r = residual if type(residual) is np.ndarray and residual.dtype == np.float64 else np.asarray(residual, dtype=float)
        m = len(self.components)
        if r.shape != self._shape:
            raise RobofdiError(f"residual: expected shape ({m},), got {r.shape}")
        peak = _peak_ratio(r, self.threshold)
        if not peak < np.inf:       # NaN or ±inf somewhere (the thresholds are finite and > 0)
            j = int(np.flatnonzero(~np.isfinite(r))[0])
            raise RobofdiError(f"residual: expected finite values, got {r[j]} at component {j} ({self.components[j]!r})")
        self._samples += 1
        if self._samples <= self.blanking:
            return Alarms(alarm=np.zeros(m, dtype=bool), isolated=tuple(self._isolated))
        if peak <= 1.0:
            self._since_alarm += 1
            if self._window is None:
                return self._quiet()
        else:
            if (self.release and self.confirm and self._isolated and self._window is None
                    and self._since_alarm >= self.release):
                self._revising = True       # a new alarm episode: decide again over every hypothesis
            self._since_alarm = 0
        ratio = np.abs(r)
        ratio /= self.threshold
        alarm = ratio > 1.0
        if self.confirm and (not self._isolated or self._revising):
            evident = ratio > self._evidence_ratio
            if self._window is None and alarm.any():
                self._window = [self.confirm, ratio.copy(), evident.astype(int), False]
            elif self._window is not None:
                self._window[0] -= 1
                np.maximum(self._window[1], ratio, out=self._window[1])
                self._window[2] += evident
            if self._window is None or self._window[0] > 0:
                return Alarms(alarm=alarm, isolated=tuple(self._isolated) if self._revising else ())
            ratio, persisted = self._window[1], self._window[2] >= 2
            picks = self._isolate(ratio, persisted)
            if self.defer and not self._window[3] and any(self._refinements[f] for f in picks):
                self._window[0], self._window[3] = self.defer, True      # deferral: the refinement gets its time
                return Alarms(alarm=alarm, isolated=tuple(self._isolated) if self._revising else ())
            self._window = None
            previous = list(self._isolated)
            if self._revising:
                self._revising = False
                if not picks:
                    return Alarms(alarm=alarm, isolated=tuple(previous))
                kept = {c for c, p in zip(self.components, persisted) if p}
                still = [f for f in previous if self._by_fault[f].required <= kept or f in picks]
                picks = still + [f for f in picks if f not in still]
            self._isolated = list(picks)
            new = tuple(f for f in self._isolated if f not in previous)
            return Alarms(alarm=alarm, isolated=tuple(self._isolated), new=new)
        previous = list(self._isolated)
        if self.confirm and self.latch and self._isolated:      # a confirmed fault keeps explaining its components
            if self.overturn:
                self._refine(alarm)
            picks = self._isolate(ratio, alarm & ~self._explained_mask())
        else:
            picks = self._isolate(ratio, alarm)
        if self.latch:
            self._isolated = self._isolated + [f for f in picks if f not in self._isolated]
        else:
            self._isolated = picks
        new = tuple(f for f in self._isolated if f not in previous)
        return Alarms(alarm=alarm, isolated=tuple(self._isolated), new=new)

    def _refine(self, alarm: np.ndarray) -> None:
        """Overturn: count, per hypothesis that refines an isolated fault (its required components a strict superset
        of the fault's), the samples in a row its required components all alarmed; at ``overturn`` it replaces the
        fault in place in the isolated faults."""
        if self._refined_at != self._samples - 1:       # a quiet sample, or a revision window, came between
            self._refining = {}
        self._refined_at = self._samples
        counts, replaced = {}, {}
        for f in self._isolated:
            for h, indices in self._refinements[f]:
                if h in self._isolated or h in counts:
                    continue
                counts[h] = self._refining.get(h, 0) + 1 if all(alarm[j] for j in indices) else 0
                if counts[h] >= self.overturn and f not in replaced:
                    replaced[f] = h
        self._refining = counts
        for f, h in replaced.items():
            self._isolated[self._isolated.index(f)] = h
            self._refining.pop(h, None)

    def _explained(self) -> frozenset[str]:
        """Every component the faults isolated so far can account for."""
        return frozenset().union(*(self._by_fault[f].explains for f in self._isolated))

    def _explained_mask(self) -> np.ndarray:
        """(m,) bool: the components of :meth:`_explained` (made once per isolated set)."""
        key = tuple(self._isolated)
        mask = self._explained_masks.get(key)
        if mask is None:
            mask = self._explained_masks[key] = np.isin(self.components, list(self._explained()))
        return mask

    def _tables(self) -> tuple:
        """The signatures as bit masks over the components (required, required ∪ allowed) and required indices."""
        if self._tables_of is not self.signatures:
            bit = {c: 1 << j for j, c in enumerate(self.components)}
            self._signature_tables = [(sum(bit[c] for c in sig.required), sum(bit[c] for c in sig.explains),
                                       tuple(self._index[c] for c in sig.required), len(sig.required))
                                      for sig in self.signatures]
            self._tables_of, self._picks_of = self.signatures, {}
        return self._signature_tables

    def _isolate(self, ratio: np.ndarray, alarm: np.ndarray) -> list[str]:
        """The greedy explanation of the alarmed components (class docstring), on bit masks. When no step of it had
        to choose between candidates the picks depend on the alarm pattern alone: they are kept for that pattern."""
        tables = self._tables()
        alarmed = 0
        for j in np.flatnonzero(alarm).tolist():
            alarmed |= 1 << j
        known = self._picks_of.get(alarmed)
        if known is not None:
            return list(known)
        values = ratio.tolist()
        unexplained, picked, chose = alarmed, [], False
        while unexplained:
            best, best_key, count = -1, None, 0
            for i, (required, explains, indices, size) in enumerate(tables):
                if i in picked or required & ~alarmed or not explains & unexplained:
                    continue
                count += 1
                key = (max(values[j] for j in indices), size)
                if best_key is None or key > best_key:      # the first of equal keys, as max() picks
                    best, best_key = i, key
            if count == 0:
                break
            chose |= count > 1
            picked.append(best)
            unexplained &= ~tables[best][1]
        for i in list(picked):      # parsimony: drop a pick the other picks explain
            others = 0
            for o in picked:
                if o != i:
                    others |= tables[o][1]
            if not tables[i][0] & ~others:
                picked.remove(i)
        faults = [self.signatures[i].fault for i in picked]
        if not chose:
            self._picks_of[alarmed] = tuple(faults)
        return faults
