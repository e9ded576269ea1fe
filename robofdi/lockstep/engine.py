"""Many runs' diagnoses stepped in lockstep: sample k of every run, each diagnoser once for all runs.

A run's diagnoses read the record's diagnoser view only (``y_meas`` and ``u_diag``, as :func:`robofdi.loop.
diagnose_record` replays it), so once the runs are simulated (:meth:`robofdi.loop.ClosedLoop.run` with
``diagnose=False``) their diagnoses can be stepped together: at each diagnosis sample, a diagnoser with a batch
form (:func:`robofdi.lockstep.observers.batch_form`) updates every run still going in one call; the others are
stepped run by run. The decision, identification and trace of each run are its own
:class:`~robofdi.loop.DiagnosisRunner`'s (:meth:`~robofdi.loop.DiagnosisRunner.decide`), so each run's trace is
the one its own loop would have recorded, bit for bit (tests/test_lockstep.py).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

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


def diagnose_lockstep(records: Sequence[Record], diagnoses: Sequence[Mapping[str, Diagnosis]],
                      rates: Rates) -> list[dict[str, DiagnoserTrace]]:
    """The traces of every run's diagnoses (``diagnoses[i]`` for ``records[i]``, the same names in the same order
    for every run, each diagnosis fresh), stepped in lockstep over the records' diagnoser views at ``rates``:
    each run's traces are those its own :class:`~robofdi.loop.DiagnosisBank` records online, bit for bit. A
    diagnoser that fails (e.g. a non-finite measurement) raises; the caller then diagnoses run by run."""
    from robofdi.lockstep.observers import batch_form

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
    runners = {name: [DiagnosisRunner(diagnoses[i][name], rates, name) for i in order] for name in names}
    batches = {name: batch_form([diagnoses[i][name].diagnoser for i in order]) for name in names}
    for batch in batches.values():
        if batch is not None:
            batch.reset()
    active = n
    for k in range(longest):
        while lengths[active - 1] <= k:
            active -= 1
        y_k, u_k, t_k = ys[k, :active], us[k, :active], times[k, :active].tolist()
        for name in names:
            batch, own = batches[name], runners[name]
            if batch is not None:
                r, estimate = batch.update(y_k, u_k)
                for slot in range(active):
                    own[slot].decide(t_k[slot], r[slot], estimate[slot])
            else:                                 # stepped run by run, each handed its own ū (as the bank does)
                for slot in range(active):
                    own[slot].sample(t_k[slot], y_k[slot], u_k[slot].copy())
    traces = [None] * n
    for slot, i in enumerate(order):
        traces[i] = {name: runners[name][slot].trace() for name in names}
    return traces
