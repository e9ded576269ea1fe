"""Bounded memory: columns in preallocated blocks, and the record streamed to HDF5 chunk by chunk as the run goes."""
from __future__ import annotations

import h5py
import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.columns import Column
from robofdi.control import ComputedTorque
from robofdi.decision import ThresholdDecision
from robofdi.experiments.ch3_industrial_robot import scenario
from robofdi.faults import Fault
from robofdi.loop import ClosedLoop, Diagnosis, Rates, Recorder, RunAborted
from robofdi.observers import MomentumObserver
from robofdi.protocols import output_is_state, returns_state
from robofdi.record import load, partial_name
from robofdi.sims import ArmSimulator


def test_a_column_gives_back_exactly_what_was_appended_blocked_or_listed():
    rows = [np.arange(3.0) + k for k in range(10)]
    c = Column(chunk=4)
    for r in rows:
        c.append(r)
    np.testing.assert_array_equal(c.array(), np.asarray(rows))
    np.testing.assert_array_equal(c[-1], rows[-1])
    assert c._count == 8 and len(c._items) == 2          # two chunks converted, two rows still listed
    np.testing.assert_array_equal(c[5], rows[5])
    assert len(c) == 10 and not c.is_list
    first = c.take()
    np.testing.assert_array_equal(first, np.asarray(rows))
    assert len(c) == 0
    c.append(rows[0])
    np.testing.assert_array_equal(c.take(), rows[:1])
    flags = Column(chunk=2)
    for v in (True, False, True):
        flags.append(v)
    assert flags.array().dtype == bool and flags.array().tolist() == [True, False, True]
    words = Column(chunk=1)                  # strings: kept as a list, as appended
    words.append("a+b")
    assert words.is_list and words.take() == ["a+b"]
    mixed = Column(chunk=2)
    mixed.append(np.zeros(2))
    mixed.append(np.ones(3))                 # a row of another shape: the column becomes a list, nothing lost
    assert mixed.is_list and [len(r) for r in mixed.rows] == [2, 3]


def test_a_column_filled_by_its_appender_and_by_blocks_equals_one_filled_row_by_row():
    rows = [np.arange(3.0) + k for k in range(11)]
    slow, fast = Column(chunk=4), Column(chunk=4)
    add = fast.appender
    for k, r in enumerate(rows):
        slow.append(r)
        add(r)
        if (k + 1) % 4 == 0:
            fast.settle()
    assert fast._count == slow._count == 8 and len(fast._items) == 3
    np.testing.assert_array_equal(fast.array(), slow.array())
    fast.take()
    add(rows[0])                                 # the appender survives a take
    np.testing.assert_array_equal(fast.array(), rows[:1])
    blocks = Column(chunk=4)
    blocks.extend(np.asarray(rows[:3]))
    blocks.extend(np.asarray(rows[3:]))
    np.testing.assert_array_equal(blocks.array(), np.asarray(rows))
    np.testing.assert_array_equal(blocks[5], rows[5])
    np.testing.assert_array_equal(blocks[-1], rows[-1])
    mixed = Column(chunk=4)
    mixed.append(rows[0])
    mixed.extend(np.asarray(rows[1:6]))          # rows pending: appended row by row, converted at 4 as before
    assert mixed._count == 4 and len(mixed._items) == 2
    np.testing.assert_array_equal(mixed.array(), np.asarray(rows[:6]))


def test_a_recorder_keeps_a_series_that_is_always_another_once_and_hands_out_copies():
    rec = Recorder(("time", "u_cmd", "u", "u_diag"), chunk=2, same={"u_diag": "u", "u": "u_cmd"})
    assert rec.same == {"u_diag": "u_cmd", "u": "u_cmd"} and list(rec.rows) == ["time", "u_cmd"]
    add_time, add_u = rec.rows["time"].appender, rec.rows["u_cmd"].appender
    for k in range(3):
        add_time(k * 0.1)
        add_u(np.full(2, float(k)))
        rec.settle()
    u_cmd, u = rec.array("u_cmd", 2), rec.array("u", 2)
    np.testing.assert_array_equal(u, u_cmd)
    assert u is not u_cmd and not np.shares_memory(u, u_cmd)
    series, _ = rec.take()
    assert list(series) == ["time", "u_cmd", "u", "u_diag"]      # the order of ``keys``: the file's dataset order
    np.testing.assert_array_equal(series["u_diag"], series["u_cmd"])
    with pytest.raises(RobofdiError, match="field 'same'"):
        Recorder(("u", "v"), same={"u": "v", "v": "u"})


def test_only_a_true_output_marked_as_the_state_is_read_once():
    assert output_is_state(object.__new__(ArmSimulator))

    class OwnOutput(ArmSimulator):
        @property
        def true_output(self):
            return self.state * 2.0

    assert not output_is_state(object.__new__(OwnOutput))

    class Plant:
        state = property(lambda self: np.zeros(2))
        true_output = property(returns_state(lambda self: self.state))

    assert output_is_state(Plant())


def _loop(faults=()):
    sc = scenario("ch3-actuator", seed=0, duration=0.4, schemes=("momentum",), faults=())
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    rates = Rates(1000.0, 500.0)
    d = MomentumObserver(model, 1.0 / rates.diagnosis_hz)
    decision = ThresholdDecision(d.components, np.full(len(d.components), 2.0), d.signatures())
    return ClosedLoop(sim, ComputedTorque(model, torque_limit=model.torque_limit), sc.motion, faults,
                      {"momentum": Diagnosis(d, decision)}, rates), sc


def _same(a, b):
    for attr in ("system", "scenario", "seed", "rates", "meta", "columns", "units"):
        assert getattr(a, attr) == getattr(b, attr), attr
    for x, y in ((a.time, b.time), (a.truth_state, b.truth_state), (a.u_applied, b.u_applied)):
        np.testing.assert_array_equal(x, y)
    assert a.signals.keys() == b.signals.keys() and a.faults.keys() == b.faults.keys()
    for k in a.signals:
        np.testing.assert_array_equal(a.signals[k], b.signals[k])
    for k in a.faults:
        np.testing.assert_array_equal(a.faults[k].active, b.faults[k].active)
        np.testing.assert_array_equal(a.faults[k].value, b.faults[k].value)
        assert a.faults[k].unit == b.faults[k].unit
    for k, tr in a.diagnosers.items():
        other = b.diagnosers[k]
        for name in ("time", "residual", "threshold", "alarm", "estimate"):
            np.testing.assert_array_equal(getattr(tr, name), getattr(other, name))
        assert list(tr.isolated) == list(other.isolated)
        assert (tr.components, tr.estimate_components, tr.units) == (other.components, other.estimate_components,
                                                                      other.units)


def test_a_streamed_record_equals_the_in_memory_one_and_files_repeat_byte_for_byte(tmp_path):
    fault = Fault("tau3", "actuator_additive", "joint3", onset=0.2, magnitude=30.0)
    loop, sc = _loop((fault,))
    q0 = sc.start_pose
    memory = loop.run(0.4, q0, seed=3, scenario="s", meta={"k": 1})
    assert memory.diagnosers["momentum"].alarm.any()          # the fault is seen: isolation strings are streamed
    path = loop.run_to_file(tmp_path / "a" / "record.h5", 0.4, q0, seed=3, scenario="s", meta={"k": 1}, chunk=64)
    assert path == tmp_path / "a" / "record.h5" and not partial_name(path).exists()
    _same(load(path), memory)
    with h5py.File(path) as f:
        assert "partial" not in f.attrs and f["truth/state"].chunks is not None
    again = loop.run_to_file(tmp_path / "b" / "record.h5", 0.4, q0, seed=3, scenario="s", meta={"k": 1}, chunk=64)
    assert again.read_bytes() == path.read_bytes()


def test_a_read_ahead_reference_is_recorded_as_the_reference_called_every_tick(tmp_path):
    fault = Fault("tau3", "actuator_additive", "joint3", onset=0.2, magnitude=30.0)
    loop, sc = _loop((fault,))
    motion = loop.reference
    per_tick, _ = _loop((fault,))
    per_tick.reference = lambda t: motion(t)     # no ``sample``: called and recorded tick by tick
    a, b = loop.run(0.3, sc.start_pose, seed=2), per_tick.run(0.3, sc.start_pose, seed=2)
    assert a.signals["reference"].shape == (301, 18)
    _same(a, b)
    pa = loop.run_to_file(tmp_path / "a.h5", 0.3, sc.start_pose, seed=2, chunk=37)
    pb = per_tick.run_to_file(tmp_path / "b.h5", 0.3, sc.start_pose, seed=2, chunk=37)
    _same(load(pa), a)
    assert pa.read_bytes() == pb.read_bytes()


def test_a_streamed_run_that_fails_keeps_its_chunks_as_a_partial_file(tmp_path):
    loop, sc = _loop()
    d = loop.diagnoses["momentum"].diagnoser
    update, calls = d.update, []

    def failing(y, u):
        calls.append(1)
        if len(calls) > 120:                  # the 121st diagnosis sample, tick 240 (0.239 s the last recorded)
            raise ValueError("boom")
        return update(y, u)

    d.update = failing
    with pytest.raises(RunAborted, match="run failed at t = 0.239 s: boom") as info:
        loop.run_to_file(tmp_path / "record.h5", 0.4, sc.start_pose, seed=1, chunk=50)
    partial = info.value.partial_path
    assert info.value.record is None and partial == tmp_path / "record.partial.h5"
    assert not (tmp_path / "record.h5").exists()
    with h5py.File(partial) as f:
        assert f.attrs["partial"] == 1
    back = load(partial)
    assert back.meta["aborted"] and len(back.time) == len(back.truth_state) == 240
    assert len(back.diagnosers["momentum"].time) == 120
    with pytest.raises(RobofdiError, match="'chunk' must be an integer >= 1"):
        loop.run_to_file(tmp_path / "x.h5", 0.1, chunk=0)
