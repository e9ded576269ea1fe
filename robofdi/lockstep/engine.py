"""Many runs' diagnoses stepped in lockstep: sample k of every run, each diagnoser once for all runs.

A run's diagnoses read the record's diagnoser view only (``y_meas`` and ``u_diag``, as :func:`robofdi.loop.
diagnose_record` replays it), so once the runs are simulated (:meth:`robofdi.loop.ClosedLoop.run` with
``diagnose=False``) their diagnoses can be stepped together. At each diagnosis sample a diagnoser with a batch form
(:func:`robofdi.lockstep.observers.batch_form`) updates every run still going in one call; the others are stepped
run by run. Decisions are array first: the residuals of all runs are tested against their thresholds at once, and a
run's own :class:`~robofdi.decision.ThresholdDecision` and :class:`~robofdi.decision.Identification` step only on
the samples where it alarms, a confirmation window is open, or an isolated fault is being identified; the other
samples only count (:meth:`~robofdi.decision.ThresholdDecision.skip`), and the trace rows are written as arrays.
Any other decision steps with its run's :class:`~robofdi.loop.DiagnosisRunner`. Each run's trace is the one its own
loop records, bit for bit (tests/test_lockstep.py).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from robofdi.decision import Identification, ThresholdDecision
from robofdi.decision import isolation
from robofdi.errors import RobofdiError
from robofdi.loop import Diagnosis, DiagnosisRunner, Rates
from robofdi.record import DiagnoserTrace, Record

__all__ = ["diagnoser_view", "diagnose_lockstep"]


def diagnoser_view(record: Record, rates: Rates) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times (K,) [s], y (K, ny), ū (K, nu)) of the record's K diagnosis samples — what a
    :class:`~robofdi.loop.DiagnosisRunner` stepped over the record is handed: y at tick j = k·ratio, ū the input
    held over the ``ratio`` ticks before it (:class:`~robofdi.loop.InputHold`: their mean, summed in order and
    divided, or the first; zeros at sample 0), the same bits."""
    ratio = rates.ratio
    y, u = record.signals["y_meas"], record.signals["u_diag"]
    ticks = np.arange(0, len(record.time), ratio)
    u_bar = np.zeros((len(ticks), u.shape[1]))
    later = ticks[1:]
    if len(later):
        if rates.input_hold == "mean":          # the hold's sums tick by tick, then its quotient
            held = u[later - ratio].copy()
            for c in range(1, ratio):
                held += u[later - ratio + c]
            held /= ratio
        else:
            held = u[later - ratio]
        u_bar[1:] = held
    return np.asarray(record.time, dtype=float)[ticks], np.asarray(y, dtype=float)[ticks], u_bar


class _Diagnoses:
    """One diagnosis name over the batch's runs (slots: longest run first): the residuals of a sample, from the
    batch form or run by run; the trace from the runners."""

    def __init__(self, diagnoses: Sequence[Diagnosis], rates: Rates):
        from robofdi.lockstep.observers import batch_form

        self.diagnoses = list(diagnoses)
        self.diagnosers = [d.diagnoser for d in self.diagnoses]
        self.batch = batch_form(self.diagnosers)
        self.runners = [DiagnosisRunner(d, rates) for d in self.diagnoses]     # each resets its diagnosis
        if self.batch is not None:
            self.batch.reset()

    def residuals(self, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R (a, m), E (a, e)) of the sample for the a runs going; run by run each diagnoser is handed its own ū."""
        if self.batch is not None:
            return self.batch.update(y, u)
        out = [d.update(y[slot], u[slot].copy()) for slot, d in enumerate(self.diagnosers[:len(y)])]
        return np.array([res.r for res in out], dtype=float), np.array([res.estimate for res in out], dtype=float)

    def decide(self, k: int, times: list, r: np.ndarray, estimate: np.ndarray) -> None:
        for slot in range(len(r)):
            self.runners[slot].decide(times[slot], r[slot], estimate[slot])

    def trace(self, slot: int, samples: int, times: np.ndarray) -> DiagnoserTrace:
        return self.runners[slot].trace()


class _ArrayDiagnoses(_Diagnoses):
    """:class:`_Diagnoses` whose decisions are latched :class:`~robofdi.decision.ThresholdDecision`\\ s and
    identifications plain :class:`~robofdi.decision.Identification`\\ s: one stacked threshold test a sample
    (:func:`robofdi.decision.isolation._peak_ratio_each`), each run's decision stepped only where it alarms or a
    confirmation window is open (else :meth:`~robofdi.decision.ThresholdDecision.skip`, counted and applied
    before its next step), its identification only once it is active; trace rows into (samples, runs, …) arrays."""

    @staticmethod
    def fits(diagnoses: Sequence[Diagnosis]) -> bool:
        return all(type(d.decision) is ThresholdDecision and d.decision.latch
                   and (d.identification is None or type(d.identification) is Identification) for d in diagnoses)

    def __init__(self, diagnoses: Sequence[Diagnosis], rates: Rates, samples: int):
        super().__init__(diagnoses, rates)
        n, first = len(self.diagnoses), self.diagnosers[0]
        m, e = len(first.components), len(first.estimate_components)
        self.decisions = [d.decision for d in self.diagnoses]
        self.identifications = [runner.identification for runner in self.runners]
        self.thresholds = np.array([d.threshold for d in self.decisions])
        self.residual, self.alarm = np.zeros((samples, n, m)), np.zeros((samples, n, m), dtype=bool)
        self.estimate, self.isolated = np.zeros((samples, n, e)), np.empty((samples, n), dtype=object)
        self.joined = np.full(n, "", dtype=object)        # each run's isolated faults joined by "+", as its runner's
        self.current: list[tuple] = [()] * n                # … and as the tuple its decision answers while quiet
        self.skipped = np.zeros(n, dtype=np.int64)          # quiet samples not yet told to each decision
        self.open = np.zeros(n, dtype=bool)                 # a confirmation window is open (not settled)
        self.identifying = np.zeros(n, dtype=bool)          # the identification is active

    def decide(self, k: int, times: list, r: np.ndarray, estimate: np.ndarray) -> None:
        a = len(r)
        peaks = np.empty(a)
        isolation._peak_ratio_each(r, self.thresholds[:a], peaks)
        if not (peaks < np.inf).all():          # NaN or ±inf: the run's own decision names it (run alone)
            raise RobofdiError("lockstep: a residual has non-finite values")
        self.residual[k, :a] = r
        quiet = (peaks <= 1.0) & ~self.open[:a]
        self.skipped[:a][quiet] += 1
        for slot in np.flatnonzero(~quiet).tolist():
            decision = self.decisions[slot]
            decision.skip(int(self.skipped[slot]))
            self.skipped[slot] = 0
            alarms = decision.update(r[slot])
            self.open[slot] = not decision.settled
            self.alarm[k, slot] = alarms.alarm
            if alarms.isolated != self.current[slot]:
                self.current[slot], self.joined[slot] = alarms.isolated, "+".join(alarms.isolated)
            identification = self.identifications[slot]
            self.estimate[k, slot] = identification.update(estimate[slot], alarms.isolated)
            self.identifying[slot] = identification.active
        self.isolated[k, :a] = self.joined[:a]
        # a quiet run's identification answers zeros until it is active (as the row already is); it becomes active
        # only on a sample its decision stepped (a new isolation)
        for slot in np.flatnonzero(quiet & self.identifying[:a]).tolist():
            self.estimate[k, slot] = self.identifications[slot].update(estimate[slot], self.current[slot])

    def trace(self, slot: int, samples: int, times: np.ndarray) -> DiagnoserTrace:
        self.decisions[slot].skip(int(self.skipped[slot]))
        self.skipped[slot] = 0
        d = self.diagnosers[slot]
        return DiagnoserTrace(
            time=np.array(times, dtype=float),
            residual=self.residual[:samples, slot].copy(),
            threshold=np.asarray(self.decisions[slot].threshold, dtype=float),
            alarm=self.alarm[:samples, slot].copy(),
            isolated=self.isolated[:samples, slot].copy(),
            estimate=self.estimate[:samples, slot].copy(),
            components=list(d.components),
            estimate_components=list(d.estimate_components),
            units={key: list(v) for key, v in d.units.items()},
        )


def diagnose_lockstep(records: Sequence[Record], diagnoses: Sequence[Mapping[str, Diagnosis]],
                      rates: Rates) -> list[dict[str, DiagnoserTrace]]:
    """The traces of every run's diagnoses (``diagnoses[i]`` for ``records[i]``, the same names in the same order
    for every run), stepped in lockstep over the records' diagnoser views at ``rates``: each run's traces are those
    its own :class:`~robofdi.loop.DiagnosisBank` records online, bit for bit. A diagnosis that fails (e.g. a
    non-finite measurement) raises; the caller then diagnoses run by run, where the failing run says why."""
    n = len(records)
    if n != len(diagnoses):
        raise RobofdiError(f"diagnose_lockstep: {n} records but {len(diagnoses)} diagnosis sets; expected one each")
    if n == 0:
        return []
    names = list(diagnoses[0])
    for i, d in enumerate(diagnoses):
        if list(d) != names:
            raise RobofdiError(f"diagnose_lockstep: run {i} has diagnoses {list(d)}, run 0 {names}; expected the same")
    views = [diagnoser_view(r, rates) for r in records]
    order = sorted(range(n), key=lambda i: -len(views[i][0]))    # longest first: the runs still going are a prefix
    lengths = [len(views[i][0]) for i in order]
    longest = lengths[0]
    ny, nu = views[order[0]][1].shape[1], views[order[0]][2].shape[1]
    times, ys, us = np.zeros((longest, n)), np.zeros((longest, n, ny)), np.zeros((longest, n, nu))
    for slot, i in enumerate(order):
        t, y, u = views[i]
        times[:len(t), slot], ys[:len(t), slot], us[:len(t), slot] = t, y, u
    ys.flags.writeable = us.flags.writeable = False       # every diagnoser of a sample is handed the same rows
    steps = {}
    for name in names:
        own = [diagnoses[i][name] for i in order]
        steps[name] = _ArrayDiagnoses(own, rates, longest) if _ArrayDiagnoses.fits(own) else _Diagnoses(own, rates)
    active = n
    for k in range(longest):
        while lengths[active - 1] <= k:
            active -= 1
        y_k, u_k, t_k = ys[k, :active], us[k, :active], times[k, :active].tolist()
        for step in steps.values():
            step.decide(k, t_k, *step.residuals(y_k, u_k))
    traces = [None] * n
    for slot, i in enumerate(order):
        traces[i] = {name: step.trace(slot, lengths[slot], times[:lengths[slot], slot]) for name, step in steps.items()}
    return traces
