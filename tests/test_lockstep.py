"""Lockstep diagnosis (robofdi.lockstep): many runs' diagnoses stepped together give every run the traces and the
campaign rows it gets alone, bit for bit. Real MuJoCo arm runs with the book schemes and the momentum observer,
faults injected online, runs of different lengths."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from robofdi import RobofdiError
from robofdi.campaign import load_spec, register_system, run_campaign
from robofdi.campaign.engine import MAX_BATCH, _calibrate, batches
from robofdi.campaign.runs import _draw
from robofdi.decision import Signature, ThresholdDecision
from robofdi.lockstep import diagnose_lockstep, diagnoser_view
from robofdi.lockstep.engine import _ArrayDiagnoses
from robofdi.loop import InputHold, Rates, diagnose_record
from robofdi.record import load
from robofdi.systems.linear import LinearSystem

SPEC = """
seed = 11
fault_free_runs = 2
faulty_runs = 3
diagnosers = ["simple", "time_delayed", "recursive", "adaptive", "position_only", "momentum"]
records = true

[system]
name = "arm"
speed = "fast"
tail = 0.2

[[faults]]
kind = "actuator_additive"
magnitude_fraction = [0.1, 0.3]
onset_fraction = [0.2, 0.4]

[[faults]]
kind = "sensor_bias"
targets = ["joint*_pos"]
magnitude_fraction = [0.002, 0.01]
onset_fraction = [0.2, 0.4]
"""


@pytest.fixture(scope="module")
def built():
    """Five campaign runs (two fault-free, three faulty; different random motions, so different lengths) built twice:
    once run with their diagnoses online, once simulated without them (``diagnose=False``)."""
    spec = load_spec(SPEC)
    system = spec.campaign_system
    _, cal, _, _ = _calibrate(spec, 0)
    online, plants = [], []
    for index in range(spec.runs):
        key, seed, mission, fault, _ = _draw(spec, index)
        faults = [] if fault is None else [fault]
        online.append(system.build(spec.options, cal, key, mission, faults, seed, spec.diagnosers).run())
        parts = system.build(spec.options, cal, key, mission, faults, seed, spec.diagnosers)
        plants.append((parts, parts.run(diagnose=False)))
    return spec, online, plants


def _fresh(spec, index: int) -> dict:
    """Fresh diagnoses of run ``index`` (its robot instance's nominal model and calibrated decisions)."""
    key, seed, mission, fault, _ = _draw(spec, index)
    cal = _calibrate(spec, key)[1]
    return spec.campaign_system.build(spec.options, cal, key, mission, [] if fault is None else [fault], seed,
                                      spec.diagnosers).diagnoses


def _assert_same_traces(a: dict, b: dict) -> None:
    """The same traces bit for bit: dtype, shape and bytes (so also the sign of every zero)."""
    assert list(a) == list(b)
    for name in a:
        for field in ("time", "residual", "threshold", "alarm", "estimate"):
            x, y = np.asarray(getattr(a[name], field)), np.asarray(getattr(b[name], field))
            assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), (name, field)
        assert list(a[name].isolated) == list(b[name].isolated), name


@pytest.mark.parametrize("forms", ["batch forms", "run by run", "runners"])
def test_lockstep_traces_are_each_runs_online_traces_bit_for_bit(built, forms, monkeypatch):
    spec, online, plants = built
    if forms != "batch forms":          # the engine's other paths: every diagnoser stepped run by run …
        monkeypatch.setattr("robofdi.lockstep.observers.batch_form", lambda diagnosers: None)
    if forms == "runners":              # … and every decision by its run's runner, sample by sample
        monkeypatch.setattr(_ArrayDiagnoses, "fits", staticmethod(lambda diagnoses: False))
    records = [record for _, record in plants]
    assert len({len(r.time) for r in records}) > 1          # runs of different lengths: the batch shrinks
    assert all(r.diagnosers == {} for r in records)
    traces = diagnose_lockstep(records, [_fresh(spec, i) for i in range(len(records))], plants[0][0].loop.rates)
    for alone, record, trace in zip(online, records, traces):
        # the plant never saw the diagnoses: the same series with and without them in the loop
        assert np.array_equal(alone.truth_state, record.truth_state)
        assert np.array_equal(alone.signals["y_meas"], record.signals["y_meas"])
        _assert_same_traces(alone.diagnosers, trace)
    # the faulty runs are diagnosed: something alarms after the onset (not a trivially quiet comparison)
    assert any(trace[name].alarm.any() for trace in traces for name in trace)


def test_diagnoser_view_is_what_a_runner_is_handed(built):
    """y at every ratio-th tick and ū as the loop's input hold forms it, tick by tick (mean and first)."""
    _, _, plants = built
    record = plants[2][1]
    for hold in ("mean", "first"):
        rates = Rates(1000.0, 250.0, hold)
        times, y, u = diagnoser_view(record, rates)
        held, k = InputHold(rates), 0
        for j, t in enumerate(record.time):
            u_bar = held.add(j, record.signals["u_diag"][j - 1] if j else np.zeros(u.shape[1]))
            if u_bar is not None:
                assert times[k] == t and np.array_equal(y[k], record.signals["y_meas"][j]) and np.array_equal(u[k], u_bar)
                k += 1
        assert k == len(times) == len(y) == len(u)


def test_a_non_finite_measurement_raises(built):
    _, _, plants = built
    parts, record = plants[0]
    record.signals["y_meas"] = record.signals["y_meas"].copy()
    record.signals["y_meas"][40, 2] = np.nan
    fresh = [_fresh(load_spec(SPEC), i) for i in range(2)]
    with pytest.raises(RobofdiError, match="non-finite|finite"):
        diagnose_lockstep([record, plants[1][1]], fresh, parts.loop.rates)


def test_campaign_rows_and_records_are_the_same_in_lockstep_and_alone(tmp_path):
    spec = load_spec(SPEC)
    lock = run_campaign(spec, tmp_path / "lock", workers=1, progress=False, batch=5, report=False)
    alone = run_campaign(spec, tmp_path / "alone", workers=1, progress=False, batch=1, report=False)
    pd.testing.assert_frame_equal(lock.table.drop(columns="wall_time"), alone.table.drop(columns="wall_time"))
    assert lock.table["error"].isna().all() and lock.table["detected"].fillna(False).any()
    for index in range(spec.runs):
        a, b = (load(tmp_path / k / "records" / f"run-{index:06d}.h5") for k in ("lock", "alone"))
        _assert_same_traces(a.diagnosers, b.diagnosers)
        assert np.array_equal(a.truth_state, b.truth_state)


@pytest.mark.parametrize("runs", [1, 5, 31, 33, 100, 200, 1000])
@pytest.mark.parametrize("workers", [1, 2, 8])
def test_automatic_batches_cover_the_runs_in_order_evenly_as_many_for_every_worker(runs, workers):
    todo = list(range(7, 7 + runs))
    cut = batches(todo, workers)
    sizes = [len(b) for b in cut]
    assert [i for b in cut for i in b] == todo and max(sizes) <= MAX_BATCH and max(sizes) - min(sizes) <= 1
    assert len(cut) % workers == 0 or len(cut) == runs < workers        # as many batches for every worker
    assert len(cut) < workers * (runs / (workers * MAX_BATCH) + 1) or len(cut) == runs   # as few as that allows


def test_a_batch_size_is_taken_as_given_and_a_bad_one_refused():
    todo = list(range(10))
    assert batches(todo, 2, 4) == [todo[:4], todo[4:8], todo[8:]] and batches(todo, 1, 1) == [[i] for i in todo]
    for bad in (0, -1, 2.5, True):
        with pytest.raises(RobofdiError, match="--batch: expected an integer >= 1"):
            batches(todo, 1, bad)


def test_run_without_diagnoses_is_refused_when_the_accommodation_follows_one(ch3):
    from dataclasses import replace

    from robofdi.systems.arm import parts

    sc, cal = ch3
    loop = parts(replace(sc, accommodation="compensation", health_source="adaptive"), cal).loop
    with pytest.raises(RobofdiError, match="field 'diagnose' must be True"):
        loop.run(0.01, diagnose=False)


def test_lockstep_of_one_run_is_diagnose_record(built):
    """One run through the engine is :func:`robofdi.loop.diagnose_record`'s replay of it (the offline path)."""
    spec, _, plants = built
    parts, record = plants[1]
    (trace,) = diagnose_lockstep([record], [_fresh(spec, 1)], parts.loop.rates)
    for name, diagnosis in _fresh(spec, 1).items():
        _assert_same_traces({name: diagnose_record(record, diagnosis, parts.loop.rates)}, {name: trace[name]})


@pytest.mark.parametrize("seed", range(6))
def test_skipping_quiet_samples_is_updating_on_them(seed):
    """A decision told its quiet samples in bulk (:meth:`ThresholdDecision.skip`) and updated only where a residual
    crosses its threshold or a confirmation window is open answers and ends as one updated every sample: bursts of
    alarms with confirmation, revision (release) and overturn, through the start-up blanking."""
    rng = np.random.default_rng(seed)
    components = ["j1", "j2", "j1_kin", "j2_kin", "j1_step"]
    signatures = [Signature("j1", frozenset({"j1"})), Signature("j2", frozenset({"j2"})),
                  Signature("j1_pos", frozenset({"j1_kin"}), frozenset({"j1", "j2"})),
                  Signature("j1_vel", frozenset({"j1_kin", "j1_step"}), frozenset({"j1", "j2"})),
                  Signature("j2_pos", frozenset({"j2_kin"}), frozenset({"j1", "j2"}))]
    settings = dict(blanking=int(rng.integers(0, 6)), confirm=int(rng.integers(0, 4)), release=int(rng.integers(0, 30)),
                    overturn=int(rng.integers(0, 4)))
    every, lazily = (ThresholdDecision(components, np.ones(5), signatures, **settings) for _ in range(2))
    residuals = rng.normal(0, 0.3, (600, 5))
    for start in rng.integers(0, 580, 8):                     # alarm bursts on random components
        residuals[start:start + rng.integers(1, 20), rng.integers(0, 5, rng.integers(1, 3))] += rng.uniform(1, 3)
    skipped, isolated = 0, []
    for r in residuals:
        counts = (every._samples, every._since_alarm)
        alarms = every.update(r)
        if np.max(np.abs(r)) <= 1.0 and lazily.settled:
            skipped += 1
            assert not alarms.alarm.any() and alarms.isolated == tuple(lazily._isolated)
            continue
        lazily.skip(skipped)
        skipped = 0
        assert (lazily._samples, lazily._since_alarm) == counts
        other = lazily.update(r)
        assert np.array_equal(alarms.alarm, other.alarm) and alarms.isolated == other.isolated and alarms.new == other.new
        isolated.append(other.isolated)
    lazily.skip(skipped)
    assert (lazily._samples, lazily._since_alarm, lazily._isolated) == (every._samples, every._since_alarm, every._isolated)
    assert any(isolated)                                     # the bursts did alarm and isolate


LINEAR = """
seed = 5
fault_free_runs = 4
faulty_runs = 4

[system]
name = "{name}"
duration = 3.0
calibration_runs = 2

[[faults]]
kind = "actuator_additive"
magnitude_fraction = [0.05, 0.4]
onset_fraction = [0.4, 0.8]
"""


class BrittleLinear(LinearSystem):
    """The linear plant, but building a run raises when its mission asks for a left-wheel mean above 7.5 rad/s."""

    name = "brittle-linear"

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        if mission.plan.mean[0] > 7.5:
            raise RuntimeError(f"left wheel mean {mission.plan.mean[0]:.2f} rad/s refused")
        return super().build(options, calibration, key, mission, faults, seed, diagnosers)


def _count_lockstep(monkeypatch) -> list[int]:
    """The batch sizes of every lockstep diagnosis from now on (the engine's own, counted)."""
    seen = []

    def spy(records, diagnoses, rates):
        seen.append(len(records))
        return diagnose_lockstep(records, diagnoses, rates)

    monkeypatch.setattr("robofdi.lockstep.diagnose_lockstep", spy)
    return seen


def _table(spec, folder, batch: int):
    """The results table of a one-worker campaign with ``batch`` runs per batch (no report)."""
    return run_campaign(spec, folder, workers=1, progress=False, batch=batch, report=False).table


def test_a_failing_run_or_diagnosis_in_a_batch_gives_the_rows_it_gives_alone(tmp_path, monkeypatch):
    """A run whose build raises is run alone (its error row); a batch whose lockstep diagnosis raises is diagnosed run
    by run: the tables of both equal those of every run alone."""
    register_system(BrittleLinear())
    spec = load_spec(LINEAR.format(name="brittle-linear"))
    alone = _table(spec, tmp_path / "alone", 1)
    seen = _count_lockstep(monkeypatch)
    lock = _table(spec, tmp_path / "lock", 8)
    pd.testing.assert_frame_equal(lock.drop(columns="wall_time"), alone.drop(columns="wall_time"))
    assert 2 <= seen[0] < 8                # the runs that built were diagnosed in lockstep, the others alone
    assert 0 < alone["error"].notna().sum() < len(alone)
    assert alone["error"].dropna().str.contains("RuntimeError: left wheel mean").all()

    def broken(*args):
        raise RobofdiError("lockstep: a residual has non-finite values")

    monkeypatch.setattr("robofdi.lockstep.diagnose_lockstep", broken)
    again = _table(spec, tmp_path / "again", 8)
    pd.testing.assert_frame_equal(again.drop(columns="wall_time"), alone.drop(columns="wall_time"))


def test_a_batch_past_its_memory_budget_is_diagnosed_in_parts_with_the_same_rows(tmp_path, monkeypatch):
    spec = load_spec(LINEAR.format(name="linear"))
    alone = _table(spec, tmp_path / "alone", 1)
    seen = _count_lockstep(monkeypatch)
    monkeypatch.setattr("robofdi.campaign.runs.BATCH_MEMORY", 1)          # every record is past it: parts of one
    parts = _table(spec, tmp_path / "parts", 8)
    pd.testing.assert_frame_equal(parts.drop(columns="wall_time"), alone.drop(columns="wall_time"))
    assert seen == [1] * 8
