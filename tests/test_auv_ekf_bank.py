"""The Roby 2 EKF bank (digest §3.1, acceptance 8) on the real MuJoCo closed loop: short missions, calibrated on
their own fault-free missions."""
from dataclasses import replace

import numpy as np
import pytest

from robofdi.decision import NisBankDecision
from robofdi.errors import RobofdiError
from robofdi.experiments.ch4_auv import ch4_roby2_scenario, ekf_bank_isolation
from robofdi.faults import Fault
from robofdi.models.auv import AuvModel
from robofdi.observers.ekf_bank import EkfBank, horizontal_thrusters, nis_bound
from robofdi.systems.auv import AuvScenario, calibrate, run_scenario

pytestmark = pytest.mark.slow

W = 2.0


def test_the_bank_has_one_filter_per_horizontal_thruster():
    assert horizontal_thrusters(AuvModel.from_mjcf("roby2.xml")) == ["thruster_left", "thruster_right"]
    assert horizontal_thrusters(AuvModel.from_mjcf("auv.xml")) == [f"thruster{i}" for i in range(1, 5)]
    # window mean of 100 samples of χ²(4): mean 4, 99 % bound a little above
    assert 4.5 < nis_bound(4, 100) < 5.0
    with pytest.raises(RobofdiError, match="process_noise"):
        EkfBank(AuvModel.from_mjcf("roby2.xml"), ["u", "v", "r", "yaw"], 0.02, process_noise=0.0)


def test_the_decision_declares_the_smallest_nis_only_after_the_nominal_alarms():
    d = NisBankDecision(["nis_nominal", "nis_a", "nis_b"], [5.0, 5.0, 5.0], ["a", "b"])
    assert d.update(np.array([4.0, 9.0, 2.0])).isolated == ()          # the nominal filter is consistent
    out = d.update(np.array([6.0, 9.0, 3.0]))
    assert out.isolated == ("b",) and out.new == ("b",) and list(out.alarm) == [True, False, True]
    assert d.update(np.array([7.0, 1.0, 8.0])).isolated == ("b",)     # latched


def _check(record, sc):
    out = ekf_bank_isolation(record, sc.faults, W)
    f = out["faults"][sc.faults[0].name]
    assert not out["false_alarm_before_onset"], out
    assert out["peak_nominal_nis_before_onset"] < out["bound"]
    assert f["declared"] == sc.faults[0].target and f["delay"] <= W + 1.0, f
    return f


def test_roby2_bank_isolates_the_failed_horizontal_thruster():
    sc = replace(ch4_roby2_scenario(duration=40.0, onset=28.0), calibration_runs=1, calibration_duration=90.0,
                 diagnosers=("ekf_bank",))
    cal = calibrate(sc)
    assert 1e-3 < cal.ekf_process_noise < 1e4
    _check(run_scenario(sc, cal), sc)
    right = replace(sc, faults=(Fault("thruster_right_off", "actuator_float", "thruster_right", onset=28.0),))
    _check(run_scenario(right, cal), right)


def test_odin_bank_isolates_a_horizontal_thruster_without_accommodation():
    sc = AuvScenario(name="test-ekf", duration=45.0, variant="no_ftc", diagnosers=("ekf_bank",), calibration_runs=1,
                     calibration_duration=120.0,
                     faults=(Fault("thruster2_off", "actuator_float", "thruster2", onset=34.0),))
    cal = calibrate(sc)
    _check(run_scenario(sc, cal), sc)


def test_the_process_noise_search_ends_where_plain_bisection_ends():
    """calibrate_process_noise evaluates the bisection's next steps together (stacked nominal filters, one pass over
    the runs for three steps): on a real fault-free AUV run it must return the q that bisection one level at a time
    returns, and the stacked filters' NIS must be each filter's own to rounding."""
    from robofdi.decision import startup_samples
    from robofdi.loop import diagnoser_inputs
    from robofdi.observers.ekf_bank import _drives, _nominal_nis_of, calibrate_process_noise
    from robofdi.systems.auv import _ekf_bank, calibration_records

    sc = AuvScenario(name="test-ekf-q", duration=20.0, variant="no_ftc", diagnosers=("ekf_bank",), calibration_runs=1,
                     calibration_duration=20.0)
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    runs = [diagnoser_inputs(r) for r in calibration_records(sc)]
    skip = startup_samples(sc.plant.control_dt, sc.blanking)

    def make(q):
        return _ekf_bank(sc, model, sim.sensor_channels, q)

    drives = _drives(make(1.0), *runs[0])
    qs = [1e-2, 0.3, 10.0]
    stacked = _nominal_nis_of(make(qs[0]), drives, np.stack([make(q).Q for q in qs]))
    alone = np.column_stack([_nominal_nis_of(make(q), drives) for q in qs])
    np.testing.assert_allclose(stacked, alone, rtol=1e-12)
    assert not np.allclose(alone[:, 0], alone[:, 2])         # the levels differ: the test sees which is which

    def peak(q):
        bank = make(q)
        return float(_nominal_nis_of(bank, drives)[skip:].max()) / bank.bound

    lo, hi = np.log(1e-3), np.log(1e4)
    for _ in range(8):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if peak(np.exp(mid)) * sc.ekf_margin > 1 else (lo, mid)
    for depth in (1, 3, 8):
        assert calibrate_process_noise(runs, make, skip, sc.ekf_margin, depth=depth) == float(np.exp(hi))
