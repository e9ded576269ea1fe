"""The Hall-voltage residual through a hard manoeuvre: the supply's drop at high motor current is part of the
expected voltage, so ch4-depth-sensor's hard dive raises no false thruster isolation (real MuJoCo loop)."""
from dataclasses import replace

import numpy as np
import pytest

from robofdi.experiments.ch4_auv import ch4_depth_sensor_scenario
from robofdi.systems.auv import calibrate, run_scenario
from robofdi.sims.auv import AuvSimulator

pytestmark = pytest.mark.slow


def test_the_depth_sensor_dive_raises_no_false_thruster_isolation():
    sc = replace(ch4_depth_sensor_scenario(), duration=36.0, calibration_runs=2, calibration_duration=120.0,
                 diagnosers=("voltage_residual", "depth_vote"))
    cal = calibrate(sc)
    # the identified supply resistance is the plant's (a few per cent: the drive map differs from the plant's)
    assert cal.supply_resistance == pytest.approx(AuvSimulator().supply_resistance, rel=0.25)
    record = run_scenario(sc, cal)
    current = record.signals["y_meas"][:, 21:29]
    after = record.time >= 30.0
    assert np.abs(current[after]).max() > 30.0              # the hard dive happened: tens of amperes drawn
    tr = record.diagnosers["voltage_residual"]
    assert not any(str(s) for s in tr.isolated), sorted({str(s) for s in tr.isolated})
    assert not tr.alarm.any()
    assert "depth" in str(record.diagnosers["depth_vote"].isolated[-1]).split("+")     # the sensor fault is seen
