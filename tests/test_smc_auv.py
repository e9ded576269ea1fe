"""Edwards, Alwi & Tan §6 on the chapter-4 AUV (robofdi.ftc.smc_auv, allocation "smc_ca" of robofdi.systems.auv):
the W-weighted on-line allocation (57)/(60), the design-time (66) check with B1 = 0, and a short MuJoCo closed loop."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from robofdi.errors import RobofdiError
from robofdi.ftc.smc_auv import HealthWeightedAllocation, SmcAuvSettings, SlidingModeAuvControl, auv_smc_ca_check
from robofdi.protocols import Health


@functools.cache
def _model():
    from robofdi.models.auv import AuvModel

    return AuvModel.from_mjcf()


def test_allocation_realises_the_wrench_with_the_diagnosed_weights():
    """(57)/(60): u = W Bᵀ(B W² Bᵀ)⁻¹ τ gives B W u = τ for the believed W; an isolated thruster gets k̂ = 1
    (w = w_min, erratum 11), so with the truth w = 0 the wrench error is O(w_min²); healthy: u = B⁺ τ."""
    m = _model()
    alloc = HealthWeightedAllocation(m.B, m.thrusters, limit=1e3, w_min=0.05)
    tau = np.array([5.0, -3.0, 8.0, 0.4, -0.2, 0.6])
    u_cmd = np.linalg.pinv(m.B) @ tau
    u = alloc.update(u_cmd, Health())
    np.testing.assert_allclose(u, u_cmd, atol=1e-10)
    u = alloc.update(u_cmd, Health(isolated=("thruster2", "thruster6")))
    w = alloc.weights
    assert w[1] == w[5] == 0.05 and np.all(np.delete(w, [1, 5]) == 1.0)
    np.testing.assert_allclose(m.B @ (w * u), tau, atol=1e-9)
    w_true = w.copy()
    w_true[[1, 5]] = 0.0
    assert np.linalg.norm(m.B @ (w_true * u) - tau) < 0.05 * np.linalg.norm(tau)


def test_allocation_honours_the_thrust_bound():
    m = _model()
    alloc = HealthWeightedAllocation(m.B, m.thrusters, limit=10.0)
    tau = np.array([60.0, 0.0, 30.0, 0.0, 0.0, 5.0])
    u = alloc.update(np.linalg.pinv(m.B) @ tau, Health(isolated=("thruster2",)))
    assert np.abs(u).max() <= 10.0 + 1e-9
    np.testing.assert_allclose(alloc.last_unattained, tau - m.B @ (alloc.weights * u), atol=1e-9)
    with pytest.raises(RobofdiError, match="field 'limit' must be a thrust > 0 N"):
        HealthWeightedAllocation(m.B, m.thrusters, limit=0.0)


def test_design_check_b1_zero_and_redundancy():
    """Digest §8: B1 = 0 ⇒ γ1 = γ2 = 0 and (66) = 0 for every W; the 12 singular double failures are the pairs in
    one group of four (the ch4 mission's pair 2 + 6 is not one)."""
    d = auv_smc_ca_check(_model(), samples=50)
    assert d["gamma1"] == 0.0 and d["gamma2"] == 0.0 and d["condition_66"] == 0.0
    assert d["gamma0"] >= 1.0
    assert d["sliding_poles"] == pytest.approx([-2, -2, -2, -1, -1, -1])
    assert len(d["singular_double_failures"]) == 12
    assert ["thruster2", "thruster6"] not in d["singular_double_failures"]


def test_bad_settings_and_scenario_option():
    from robofdi.systems.auv import AuvScenario

    with pytest.raises(RobofdiError, match="field 'surface' must be six rates > 0"):
        SmcAuvSettings(surface=(1.0, 1.0))
    with pytest.raises(RobofdiError, match="field 'w_min' must be in"):
        SmcAuvSettings(w_min=0.0)
    with pytest.raises(RobofdiError, match="field 'allocation' must be one of .*smc_ca"):
        AuvScenario(allocation="smc")
    assert AuvScenario(allocation="smc_ca").allocation == "smc_ca"


def test_smc_ca_closed_loop_keeps_tracking_after_a_thruster_failure():
    """[HARNESS] 12 s of the ODIN mission in MuJoCo, thruster 2 off at 4 s, oracle health: the SMC-CA loop keeps
    the position error small (measured on the 40 s version: 0.014 m RMS after both ch4 failures, 0.015 m
    fault-free) and the adaptive gain stays bounded."""
    from robofdi.faults import Fault
    from robofdi.loop import ORACLE, ClosedLoop
    from robofdi.systems.auv import AuvScenario, _allocation, _controller, _reference_columns, tracking_rms

    faults = (Fault("thruster2_off", "actuator_float", "thruster2", onset=4.0),)
    sc = AuvScenario(duration=12.0, faults=faults, allocation="smc_ca", diagnosers=(), variant="oracle")
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    ctl = _controller(model, "smc_ca")
    assert isinstance(ctl, SlidingModeAuvControl)
    cols, units = _reference_columns()
    loop = ClosedLoop(sim, ctl, sc.reference(), faults, {}, accommodation=_allocation(sc, model),
                      health_source=ORACLE, reference_columns=cols, reference_units=units)
    rec = loop.run(sc.duration, sc.start_pose, seed=0)
    assert tracking_rms(rec, 4.0) < 0.05
    assert np.isfinite(ctl.gain) and ctl.gain < 10.0
    assert np.abs(rec.u_applied[rec.time > 4.1, 1]).max() < 1e-9          # the failed thruster gives nothing
