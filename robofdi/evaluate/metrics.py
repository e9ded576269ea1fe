"""Per-diagnoser metrics computed from a record's ground-truth labels (never guessed)."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from robofdi import RobofdiError
from robofdi.record import DiagnoserTrace, Record

__all__ = ["FaultWindow", "fault_windows", "evaluate_diagnoser", "peak_ratios", "threshold_ratio", "TIME_TOLERANCE"]

#: Absolute slack [s] when comparing time stamps produced by different rates (float round-off).
TIME_TOLERANCE = 1e-9


@dataclass(frozen=True)
class FaultWindow:
    """The part of a fault spec the metrics need: name, kind, target and active window [onset, end)."""

    name: str
    kind: str
    target: str
    onset: float
    end: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise RobofdiError(f"fault name: expected a non-empty string, got {self.name!r}")
        if not np.isfinite(self.onset):
            raise RobofdiError(f"fault {self.name!r} onset: expected a finite time [s], got {self.onset}")
        if self.end is not None and not self.end > self.onset:
            raise RobofdiError(f"fault {self.name!r} end: expected None or a time > onset {self.onset}, got {self.end}")

    @classmethod
    def from_spec(cls, spec: Mapping) -> FaultWindow:
        """Build from a fault-spec dict with at least name, kind, target, onset, end."""
        if not isinstance(spec, Mapping):
            raise RobofdiError(f"faults: expected dicts with name, kind, target, onset, end; got {type(spec).__name__}")
        for key in ("name", "kind", "target", "onset", "end"):
            if key not in spec:
                raise RobofdiError(f"fault spec {spec.get('name', spec)!r}: missing key {key!r}")
        end = spec["end"]
        return cls(
            name=spec["name"],
            kind=str(spec["kind"]),
            target=str(spec["target"]),
            onset=float(spec["onset"]),
            end=None if end is None else float(end),
        )

    def contains(self, t: np.ndarray) -> np.ndarray:
        """Boolean mask of the times inside [onset, end)."""
        t = np.asarray(t, dtype=float)
        inside = t >= self.onset - TIME_TOLERANCE
        if self.end is not None:
            inside &= t < self.end - TIME_TOLERANCE
        return inside

    def as_dict(self) -> dict:
        return {"name": self.name, "kind": self.kind, "target": self.target, "onset": self.onset, "end": self.end}


def fault_windows(faults: Sequence[Mapping]) -> list[FaultWindow]:
    """Validated fault windows from fault-spec dicts (names must be unique)."""
    windows = [FaultWindow.from_spec(f) for f in faults]
    names = [w.name for w in windows]
    for n in names:
        if names.count(n) > 1:
            raise RobofdiError(f"faults: expected unique names, got {n!r} more than once")
    return windows


def _label_index(record_time: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index of the last record time <= t (with tolerance); -1 before the record starts."""
    return np.searchsorted(record_time, np.asarray(t, dtype=float) + TIME_TOLERANCE, side="right") - 1


def _sample_label(record_time: np.ndarray, label: np.ndarray, t: np.ndarray, before) -> np.ndarray:
    """Zero-order-hold look-up of a per-record-step label at times t; ``before`` where t precedes the record."""
    idx = _label_index(record_time, t)
    out = np.asarray(label)[np.clip(idx, 0, None)]
    out = np.where(idx >= 0, out, before)
    return out


def _isolated_sets(trace: DiagnoserTrace) -> list[list[str]]:
    """The isolated hypotheses of every sample (read only: equal strings share one list, split once)."""
    split: dict = {}
    out = []
    for s in trace.isolated:
        names = split.get(s)
        if names is None:
            names = split[s] = [n for n in str(s).split("+") if n]
        out.append(names)
    return out


def _check_trace(trace: DiagnoserTrace, name: str) -> None:
    M = len(trace.time)
    alarm = np.asarray(trace.alarm)
    if alarm.ndim != 2 or alarm.shape[0] != M:
        raise RobofdiError(f"diagnoser {name!r} alarm: expected shape ({M}, m), got {alarm.shape}")
    if len(trace.isolated) != M:
        raise RobofdiError(f"diagnoser {name!r} isolated: expected {M} entries (one per sample), got {len(trace.isolated)}")
    est = np.asarray(trace.estimate)
    if trace.estimate_components and (est.ndim != 2 or est.shape != (M, len(trace.estimate_components))):
        raise RobofdiError(
            f"diagnoser {name!r} estimate: expected shape ({M}, {len(trace.estimate_components)}), got {est.shape}"
        )


def evaluate_diagnoser(record: Record, name: str, faults: Sequence[Mapping]) -> dict:
    """Detection, false-alarm, isolation and identification metrics of one diagnoser in a record.

    Definitions (t are the diagnoser's own sample times):

    * fault activity at t: the label ``record.faults[f].active`` at the last record time <= t (none before
      the record starts); a sample is fault-free when no labelled fault is active.
    * ``false_alarms``: rising edges (False -> True) of the any-component alarm ``alarm.any(axis=1)`` at
      fault-free samples, i.e. alarm episodes that start while no fault is active; ``first_false_alarm_time``
      is the time of the first one (None if there is none).
    * detection of fault F: the first t in [onset_F, end_F) at which some component's alarm rises
      (False -> True on that component; a component already alarmed at onset counts only once it re-rises).
      ``time``, ``delay`` = time - onset, and ``isolated`` are None for a miss.
    * ``isolated`` for F (detected): the first fault name in the trace's ``isolated`` string ("a+b") that is
      present at some t in [onset_F, end_F) but was not at the last sample before onset_F; None if none.
      ``isolation_correct[F]`` is whether it equals F's target; ``time_to_isolation[F]`` = its time - onset.
    * ``time_to_correct_isolation[F]``: the first t in [detection time, end_F) at which F's target is among the
      isolated faults, minus onset (None if never: a revisable isolation may reach the target after a wrong
      first call); ``final_isolation_correct[F]``: whether the target is isolated at the last sample inside
      [onset_F, end_F).
    * ``estimate_rmse[F]``: when isolated correctly and the target is one of ``estimate_components``, the
      RMSE between that estimate column and the true value label over the samples t in [isolation time, end_F);
      None otherwise.
    * ``missed_detections``: number of faults without a detection.
    """
    if name not in record.diagnosers:
        raise RobofdiError(f"diagnoser: {name!r} is not in the record; expected one of {sorted(record.diagnosers)}")
    trace = record.diagnosers[name]
    _check_trace(trace, name)
    windows = fault_windows(faults)
    for w in windows:
        if w.name not in record.faults:
            raise RobofdiError(f"fault {w.name!r}: no ground-truth label in the record; labelled: {sorted(record.faults)}")

    t = np.asarray(trace.time, dtype=float)
    alarm = np.asarray(trace.alarm, dtype=bool)
    M = t.size
    any_active = _any_fault_active(record, t)      # fault activity at the diagnoser's samples, from every label

    previous = np.vstack([np.zeros((1, alarm.shape[1]), dtype=bool), alarm[:-1]]) if M else alarm
    rises = alarm & ~previous                                # per-component rising edges
    any_alarm = alarm.any(axis=1)
    any_rise = any_alarm & ~np.concatenate([[False], any_alarm[:-1]])
    false_rises = np.flatnonzero(any_rise & ~any_active)

    isolated_sets = _isolated_sets(trace)
    detections, isolation_correct, time_to_isolation, estimate_rmse = [], {}, {}, {}
    time_to_correct, final_correct = {}, {}
    for w in windows:
        inside = w.contains(t)
        hits = np.flatnonzero(inside & rises.any(axis=1))
        if hits.size == 0:
            detections.append({"fault": w.name, "time": None, "delay": None, "isolated": None})
            isolation_correct[w.name], time_to_isolation[w.name], estimate_rmse[w.name] = False, None, None
            time_to_correct[w.name], final_correct[w.name] = None, False
            continue
        k_det = int(hits[0])
        iso_name, k_iso = _first_new_isolation(isolated_sets, t, w, inside)
        detections.append({
            "fault": w.name,
            "time": float(t[k_det]),
            "delay": float(t[k_det] - w.onset),
            "isolated": iso_name,
        })
        correct = iso_name == w.target
        isolation_correct[w.name] = correct
        time_to_isolation[w.name] = None if k_iso is None else float(t[k_iso] - w.onset)
        estimate_rmse[w.name] = _estimate_rmse(record, trace, w, inside, k_iso) if correct else None
        window = np.flatnonzero(inside)
        k_right = next((k for k in window if k >= k_det and w.target in isolated_sets[k]), None)
        time_to_correct[w.name] = None if k_right is None else float(t[k_right] - w.onset)
        final_correct[w.name] = w.target in isolated_sets[int(window[-1])]

    return {
        "false_alarms": int(false_rises.size),
        "first_false_alarm_time": float(t[false_rises[0]]) if false_rises.size else None,
        "detections": detections,
        "estimate_rmse": estimate_rmse,
        "missed_detections": sum(d["time"] is None for d in detections),
        "isolation_correct": isolation_correct,
        "time_to_isolation": time_to_isolation,
        "time_to_correct_isolation": time_to_correct,
        "final_isolation_correct": final_correct,
    }


def _any_fault_active(record: Record, t: np.ndarray) -> np.ndarray:
    """Whether some labelled fault of the record is active at each of the diagnoser's sample times ``t``."""
    rtime = np.asarray(record.time, dtype=float)
    active = np.zeros(t.size, dtype=bool)
    for lab in record.faults.values():
        active |= _sample_label(rtime, np.asarray(lab.active, dtype=bool), t, False).astype(bool)
    return active


def peak_ratios(record: Record, name: str, faults: Sequence[Mapping]) -> tuple[float | None, dict]:
    """(peak at the fault-free samples, {fault name: peak inside its window}) of max_j |r_j| / threshold_j of
    diagnoser ``name`` — the threshold scale below which it alarms there. Defined (else None) when every alarm of
    the trace is exactly that test, |r_j| > threshold_j (a fixed-threshold decision: thresholds scaled by s then
    alarm where the ratio exceeds s, how :func:`robofdi.campaign.metrics.at_equal_false_alarms` compares
    diagnosers at one false-alarm count)."""
    trace = record.diagnosers[name]
    t = np.asarray(trace.time, dtype=float)
    ratio = threshold_ratio(trace)
    return _peak(ratio, ~_any_fault_active(record, t)), {w.name: _peak(ratio, w.contains(t)) for w in fault_windows(faults)}


def threshold_ratio(trace: DiagnoserTrace) -> np.ndarray | None:
    """max_j |r_j| / threshold_j per sample (M,), or None unless every alarm of ``trace`` is |r_j| > threshold_j."""
    residual = np.abs(np.asarray(trace.residual, dtype=float))
    threshold = np.asarray(trace.threshold, dtype=float)
    alarm = np.asarray(trace.alarm, dtype=bool)
    if residual.shape != alarm.shape or threshold.shape != alarm.shape[1:] or not np.all(threshold > 0):
        return None
    each = residual / threshold
    if not np.array_equal(each > 1.0, alarm):
        return None
    return each.max(axis=1, initial=0.0)


def _peak(ratio: np.ndarray | None, where: np.ndarray) -> float | None:
    if ratio is None or not where.any():
        return None
    return float(np.max(ratio[where]))


def _first_new_isolation(isolated_sets: list[list[str]], t: np.ndarray, w: FaultWindow, inside: np.ndarray):
    """(name, sample index) of the first fault newly isolated inside the window, or (None, None)."""
    idx = np.flatnonzero(inside)
    if idx.size == 0:
        return None, None
    before = set(isolated_sets[idx[0] - 1]) if idx[0] > 0 else set()
    for k in idx:
        for f in isolated_sets[k]:
            if f not in before:
                return f, int(k)
    return None, None


def _estimate_rmse(record: Record, trace: DiagnoserTrace, w: FaultWindow, inside: np.ndarray, k_iso: int) -> float | None:
    if w.target not in trace.estimate_components:
        return None
    column = trace.estimate_components.index(w.target)
    value = np.asarray(record.faults[w.name].value, dtype=float)
    if value.ndim == 2 and value.shape[1] == 1:
        value = value[:, 0]
    if value.ndim != 1 or value.shape[0] != len(record.time):
        raise RobofdiError(
            f"fault {w.name!r} value: expected one scalar per record step, shape ({len(record.time)},), got {value.shape}"
        )
    t = np.asarray(trace.time, dtype=float)
    use = inside.copy()
    use[:k_iso] = False
    if not use.any():
        return None
    truth = _sample_label(np.asarray(record.time, dtype=float), value, t[use], np.nan)
    err = np.asarray(trace.estimate, dtype=float)[use, column] - truth
    return float(np.sqrt(np.mean(err**2)))
