"""AUV diagnosers and fault-tolerant allocation on the real MuJoCo closed loop (short missions, calibrated once)."""
import pickle
from dataclasses import replace

import numpy as np
import pytest

from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.faults import Fault
from robofdi.models.auv import AuvModel
from robofdi.observers.auv import VoltageResidual, effectiveness_identifiability
from robofdi.systems.auv import (
    ALL_DIAGNOSERS, AuvScenario, calibrate, check_scenario, current_map_regions, depth_switch_time, fault_targets,
    run_scenario, tracking_rms,
)
from robofdi.sims.auv import AuvSimulator

pytestmark = pytest.mark.slow

# Every diagnoser but the EKF bank, whose process-noise search and per-sample filters would double this module's
# time; the bank has its own missions, calibration and no-alarm-before-onset checks in tests/test_auv_ekf_bank.py.
BASE = AuvScenario(name="test-auv", duration=40.0, calibration_runs=2, calibration_duration=180.0,
                   diagnosers=tuple(d for d in ALL_DIAGNOSERS if d != "ekf_bank"))


@pytest.fixture(scope="module")
def cal():
    return calibrate(BASE)


def _first_isolation(record, diagnoser, target, onset):
    tr = record.diagnosers[diagnoser]
    hit = np.flatnonzero((tr.time >= onset) & np.array([target in str(s).split("+") for s in tr.isolated]))
    return float(tr.time[hit[0]]) if hit.size else None


def test_calibration_is_picklable_and_the_characteristic_is_physical(cal):
    again = pickle.loads(pickle.dumps(cal))
    np.testing.assert_array_equal(again.characteristic, cal.characteristic)
    # θ of i = θ1|Ω|Ω + θ2 Ω̇ + θ3 Ω against the motor's K_q/K_t and J/K_t (4e-4 A·s², 0.02 A·s²): same order
    assert 2e-4 < cal.characteristic[0] < 8e-4 and 0.005 < cal.characteristic[1] < 0.05


def test_fault_free_random_mission_in_a_current_raises_no_alarm(cal):
    sc = replace(BASE, mission="random", seed=3, duration=90.0, variant="diagnosed")
    record = run_scenario(sc, cal)
    summary = summarize(record, record.scenario)
    for name, metrics in summary["diagnosers"].items():
        assert metrics["false_alarms"] == 0, name
    assert tracking_rms(record, 5.0) < 0.15
    assert np.all(np.abs(record.u_applied) <= sc.plant.thrust_limit + 1e-9)


@pytest.mark.parametrize("target, onset", [("thruster2", 20.0), ("thruster6", 8.0)])
def test_rotor_failure_is_isolated_within_half_a_second_by_the_telemetry_schemes(cal, target, onset):
    sc = replace(BASE, variant="no_ftc", duration=onset + 5.0,
                 faults=(Fault(f"{target}_off", "actuator_float", target, onset=onset),))
    record = run_scenario(sc, cal)
    summary = summarize(record, record.scenario)
    i = record.columns["signals/u"].index(target)
    k = (record.time >= onset) & (record.time < onset + 0.5)
    # precondition: the failed thruster is commanded (the Hall residual cannot see a zeroed drive otherwise)
    v_cmd = np.abs(AuvModel.from_mjcf("auv.xml").thruster.voltage_for_thrust(record.signals["u_cmd"][k, i]))
    assert v_cmd.max() > 2 * cal.thresholds["voltage_residual"][i]
    for scheme in ("voltage_residual", "current_map"):
        metrics = summary["diagnosers"][scheme]
        assert metrics["false_alarms"] == 0, scheme
        t_iso = _first_isolation(record, scheme, target, onset)
        assert t_iso is not None and t_iso - onset <= 0.5, (scheme, t_iso)
        assert metrics["detections"][0]["isolated"] == target


def test_flooding_and_blocking_are_told_apart_from_rotor_failure_by_the_current_map(cal):
    faults = (Fault("t3_flooded", "component_thruster_flooding", "thruster3", onset=10.0, magnitude=0.3),
              Fault("t5_blocked", "component_thruster_blocking", "thruster5", onset=20.0, magnitude=1.0),
              Fault("t1_off", "actuator_float", "thruster1", onset=30.0))
    record = run_scenario(replace(BASE, variant="no_ftc", duration=36.0, faults=faults), cal)
    regions = current_map_regions(record, faults)
    assert regions["t3_flooded"]["region"] == "flooding"
    assert regions["t5_blocked"]["region"] == "blocking"
    assert regions["t1_off"]["region"] == "rotor_failure"
    for f in faults:
        assert regions[f.name]["time"] - f.onset < 2.0


def test_diagnosed_health_allocation_keeps_tracking_after_two_failures(cal):
    faults = (Fault("thruster2_off", "actuator_float", "thruster2", onset=26.0),
              Fault("thruster6_off", "actuator_float", "thruster6", onset=30.0))
    sc = replace(BASE, duration=60.0, faults=faults)
    rms = {}
    for variant in ("oracle", "diagnosed"):
        record = run_scenario(replace(sc, variant=variant), cal)
        rms[variant] = tracking_rms(record, 30.0)
        assert np.all(np.abs(record.u_applied) <= sc.plant.thrust_limit + 1e-9)
        if variant == "diagnosed":
            assert record.meta["health_source"] == "voltage_residual"
            after = record.time > 31.0         # health one sample late; then the failed drives get no demand
            assert np.abs(record.signals["u"][after][:, [1, 5]]).max() < 1e-9
    free = run_scenario(replace(sc, faults=(), variant="no_ftc"), cal)
    rms["fault_free"] = tracking_rms(free, 30.0)
    assert rms["diagnosed"] <= 2.0 * rms["fault_free"], rms
    assert rms["diagnosed"] <= 1.2 * rms["oracle"], rms


def test_zeroed_depth_sensor_is_switched_out_after_one_second_and_depth_control_goes_on(cal):
    sc = replace(BASE, variant="no_ftc", duration=30.0, depth_redundancy=True,
                 faults=(Fault("depth_zero", "sensor_dropout", "depth", onset=15.0),))
    record = run_scenario(sc, cal)
    summary = summarize(record, record.scenario)
    detection = summary["diagnosers"]["depth_vote"]["detections"][0]
    assert detection["isolated"] == "depth" and detection["delay"] <= 0.1
    r = record.diagnosers["depth_vote"]
    k = np.searchsorted(r.time, 15.5)
    # the isolation table: R1 = z_p − z_s and R2 = z_p − z_ARX large (≈ −depth), R3 = z_s − z_ARX small
    assert abs(r.residual[k, 0]) > 3.0 and abs(r.residual[k, 1]) > 3.0 and abs(r.residual[k, 2]) < 1.0
    switch = depth_switch_time(record)
    assert switch is not None and abs(switch - 16.0) <= 0.1
    error = np.abs(record.truth_state[:, 2] - record.signals["reference"][:, 2])
    assert error[record.time > 22.0].max() < 0.1


def test_same_seed_same_record(cal):
    sc = replace(BASE, duration=3.0)
    a = run_scenario(sc, cal)
    b = run_scenario(sc, cal)
    np.testing.assert_array_equal(a.signals["y_meas"], b.signals["y_meas"])
    np.testing.assert_array_equal(a.truth_state, b.truth_state)
    c = run_scenario(replace(sc, seed=1), cal)
    assert not np.array_equal(a.signals["y_meas"], c.signals["y_meas"])


def test_voltage_residual_detectability_depends_on_the_command():
    sim = AuvSimulator()
    model = sim.nominal_model()
    d = VoltageResidual(model, sim.sensor_channels, 0.02)
    y = np.zeros(len(sim.sensor_channels))               # every drive reads 0 V: all zeroed
    threshold = np.full(8, 1.0)
    u = np.array([0.0, 0.1, 2.0, 10.0, -10.0, 0.0, 0.0, 0.0])
    for _ in range(d.samples):
        r = d.update(y, u).r
    seen = np.abs(r) > threshold
    np.testing.assert_array_equal(seen, d.detectable(u, threshold))
    assert list(seen[:5]) == [False, False, True, True, True]


def test_motion_alone_cannot_identify_eight_effectivenesses_at_one_instant():
    B = AuvModel.from_mjcf("auv.xml").B
    g = np.random.default_rng(0)
    assert effectiveness_identifiability(B, g.normal(0, 5, (1, 8)))[0] == 6
    assert effectiveness_identifiability(B, g.normal(0, 5, (20, 8)))[0] == 8


def test_bad_inputs_are_clear_errors(cal):
    with pytest.raises(RobofdiError, match="unknown target 'thruster9'"):
        check_scenario(replace(BASE, faults=(Fault("x", "actuator_float", "thruster9", onset=1.0),)))
    with pytest.raises(RobofdiError, match="health_source"):
        AuvScenario(health_source="nobody")
    with pytest.raises(RobofdiError, match="not used on the AUV"):
        fault_targets("component_friction")
    sim = AuvSimulator()
    d = VoltageResidual(sim.nominal_model(), sim.sensor_channels, 0.02)
    y = np.zeros(len(sim.sensor_channels))
    y[2] = np.nan
    with pytest.raises(RobofdiError, match="NaN"):
        d.update(y, np.zeros(8))
    from robofdi.control.auv import TaskSpaceAuvControl

    ref = (np.zeros(6), np.zeros(6), np.zeros(6))
    with pytest.raises(RobofdiError, match="NaN sensor reading"):
        TaskSpaceAuvControl(sim.nominal_model()).update(y, ref)
