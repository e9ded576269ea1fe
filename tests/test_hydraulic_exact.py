"""The exact-model wheel actuator (plant == model, eqs. (5)-(6) by RK4): the digest's nominal run and bad input."""
from __future__ import annotations

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.control.speed import RPM
from robofdi.models.hydraulic import CATALOGUE
from robofdi.sims.hydraulic_exact import ExactRun, exact_model_run, leak_area_for_share


@pytest.mark.parametrize("area, p_bar", [(1.2e-6, 11.93), (None, 0.22)])
def test_nominal_ramp_within_0_01_rpm_from_3_s(area, p_bar):
    """Digest §6.2 table and §6.5 item 2: 5 rpm to 0.01 rpm from 3 s, overshoot < 1 %, both load cases."""
    out = exact_model_run(ExactRun(throttle_area=area, duration=4.0))
    rpm = out["true_speed"] / RPM
    assert np.max(np.abs(rpm[out["time"] >= 3.0] - 5.0)) < 0.01
    assert rpm.max() < 5.0 * 1.01
    assert out["load_pressure"][-1] / 1e5 == pytest.approx(p_bar, abs=0.05)


def test_faults_act_as_the_chapter_emulates_them():
    out = exact_model_run(ExactRun(fault="tachometer_loss", onset=3.0, duration=3.5))
    late = out["time"] >= 3.0
    assert np.all(out["shaft_speed"][late] == 0.0) and out["true_speed"][-1] > 2 * 5.0 * RPM    # runaway
    stuck = exact_model_run(ExactRun(fault="sticking_valve", duration=1.5))
    assert stuck["active"][(stuck["time"] >= 0.5) & (stuck["time"] < 0.7)].all()
    assert not stuck["active"][(stuck["time"] >= 0.7) & (stuck["time"] < 1.1)].any()


def test_leak_area_for_share_and_bad_input():
    area = leak_area_for_share(0.02, 1.193e6)
    assert area == pytest.approx(2.4e-8, rel=0.02)                      # the digest's 2 % orifice
    flow = area * np.sqrt(2 * 1.193e6 / CATALOGUE.rho)
    assert flow / (CATALOGUE.d_m * 5 * RPM) == pytest.approx(0.02)
    with pytest.raises(RobofdiError, match="'fault'"):
        ExactRun(fault="flood")
    with pytest.raises(RobofdiError, match="'onset'"):
        ExactRun(fault="leak", onset=9.0)
