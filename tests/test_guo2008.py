"""Guo, Jiang, Zhang & Wang (2008): UIO design with its existence conditions, the adaptive multiple-model bank and
the switching index on the (reconstructed) aircraft model — the checks of spec_linear_papers.md B.4."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.decision import SwitchingIndexDecision
from robofdi.experiments.guo2008 import NONSQUARE_POLES, lock_estimates
from robofdi.models.linear_examples import aircraft_lateral, aircraft_three_surfaces
from robofdi.observers.spr import spr_lyapunov_weight
from robofdi.models.linear import LinearModel, discretize
from robofdi.observers.uio import LockInPlaceBank, UnknownInputObserver, uio_design
from robofdi.systems.aircraft import (
    AircraftScenario, build_loop, calibrate, residual_vectors, run_aircraft, switching_index,
)


def test_reconstructed_model_is_the_digests():
    m = aircraft_lateral()
    eig = np.sort_complex(np.linalg.eigvals(m.A))
    assert np.allclose(sorted(eig.real), sorted([-0.453, -0.453, -3.2474, -1.7859, -0.1893, -0.0211]), atol=2e-3)
    assert np.linalg.matrix_rank(m.C) == 6 and np.linalg.matrix_rank(m.C @ m.E) == 1


def test_uio_algebra_and_poles():
    d = uio_design(discretize(aircraft_lateral(), 1e-3), [-3.0] * 6)
    assert d.decoupling < 1e-12
    assert np.max(np.abs(d.F - np.exp(-3e-3) * np.eye(6))) < 1e-10
    assert np.max(np.abs(d.T @ discretize(aircraft_lateral(), 1e-3).E)) < 1e-12


@pytest.fixture(scope="module")
def fine():
    """The digest's harness at dt = 1 ms (30 s): one faulty run with the gust, one without."""
    sc = AircraftScenario()
    thr = calibrate(replace(sc, duration=20.0))
    return sc, build_loop(sc, thr).run(sc.duration, seed=0), build_loop(replace(sc, gust=False), thr).run(sc.duration, seed=0)


def test_disturbance_is_decoupled_to_numerical_precision(fine):
    sc, rec, calm = fine
    assert np.max(np.abs(residual_vectors(rec, sc) - residual_vectors(calm, sc))) < 1e-9


def test_matched_model_wins_and_estimates_the_lock(fine):
    sc, rec, _ = fine
    tr = rec.diagnosers["amm"]
    t = tr.time
    J = switching_index(rec, sc.dt)
    assert np.all(np.argmin(J[t >= 15.5], axis=1) == 1)                 # input 2: the right elevator
    assert J[np.argmin(np.abs(t - 15.5))] == pytest.approx([6.55, 1.38, 5.03, 4.45, 5.05], rel=0.02)
    assert np.all(np.abs(tr.estimate[t >= 17.4, 1] - 1.0) < 0.01)
    assert tr.estimate[np.argmin(np.abs(t - 20.0)), 1] == pytest.approx(1.0, abs=0.02)
    # pre-fault caveat (spec B.4 item 5): on [14, 15) s the rudder model adapts slowest, every ‖rᵢ‖ stays < 0.4
    pre = tr.residual[(t >= 14.0) & (t < 15.0), 1:].max(axis=0)
    assert np.argmax(pre) == 4 and pre.max() < 0.4 and pre[:2].max() < 1e-6
    norms = tr.residual[t >= 20.0, 1:]
    assert norms[:, 1].max() < 1e-2
    assert np.delete(norms, 1, axis=1).min() > 1.0
    # the decision: no alarm under the gust alone, detection and the right isolation right after the lock
    assert not tr.alarm[t < 15.0, 0].any()
    first = np.flatnonzero(tr.alarm[:, 0])[0]
    assert 15.0 <= t[first] < 15.05
    assert set(tr.isolated[t >= 15.5]) == {"elevator_right"}


def test_scenario_runner_for_campaigns():
    record, summary = run_aircraft(seed=0, dt=1e-2, duration=20.0)
    d = summary["diagnosers"]["amm"]
    assert d["false_alarms"] == 0
    assert d["detections"][0]["isolated"] == "elevator_right"
    assert record.diagnosers["amm"].estimate[-1, 1] == pytest.approx(1.0, abs=0.02)


def test_switching_index_decision_validates_and_isolates_after_detection():
    dec = SwitchingIndexDecision(["nominal", "a", "b"], [1.0, 1e9, 1e9], ["A", "B"], 0.1)
    assert dec.update(np.array([0.5, 0.0, 1.0])).isolated == ()            # no detection, no isolation
    out = dec.update(np.array([2.0, 3.0, 0.1]))
    assert out.isolated == ("B",) and out.alarm[0]
    with pytest.raises(RobofdiError, match="models"):
        SwitchingIndexDecision(["nominal", "a"], [1.0, 1.0], ["A", "B"], 0.1)
    with pytest.raises(RobofdiError, match="'c'"):
        SwitchingIndexDecision(["nominal", "a"], [1.0, 1.0], ["A"], 0.1, c=(1.0, 0.0, 1.0))


def test_existence_conditions_raise():
    m = discretize(aircraft_lateral(), 1e-2)
    with pytest.raises(RobofdiError, match=r"rank\(CE\) = rank\(E\)"):        # E invisible to C
        uio_design(LinearModel(np.diag([0.5, 0.6]), [[1.0], [0.0]], [[1.0, 0.0]], dt=0.1), [-1.0, -2.0], E=[[0.0], [1.0]])
    blind = LinearModel([[1.01, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.4]], np.eye(3)[:, :1], [[0.0, 1.0, 0.0],
                        [0.0, 0.0, 1.0]], dt=0.1)
    with pytest.raises(RobofdiError, match="detectable"):
        uio_design(blind, [-1.0, -2.0, -3.0], E=[[0.0], [1.0], [0.0]])
    with pytest.raises(RobofdiError, match="Re < 0"):
        uio_design(m, [3.0] * 6)
    with pytest.raises(RobofdiError, match="6xq"):
        uio_design(m, [-3.0] * 6, E=np.ones((5, 1)))
    with pytest.raises(RobofdiError, match="full column rank"):
        uio_design(m, [-3.0] * 6, E=np.ones((6, 2)))
    with pytest.raises(RobofdiError, match="u_min"):
        LockInPlaceBank(m, [-3.0] * 6, u_min=2.0, u_max=-2.0)
    obs = UnknownInputObserver(m, [-3.0] * 6)
    with pytest.raises(RobofdiError, match="'u' must be a vector of 5"):
        obs.update(np.zeros(6), np.zeros(4))


def test_spr_output_form_equals_pinv_for_square_C_and_refuses_when_the_condition_fails():
    # the adaptive law's output form for a non-square C (spec B.2 [ERRATUM]): P T bᵢ = Cᵀ Gᵢ
    m = discretize(aircraft_lateral(), 1e-3)
    pinv = LockInPlaceBank(m, [-3] * 6)
    spr = LockInPlaceBank(m, [-3] * 6, output_form="spr")
    np.testing.assert_allclose(spr._adapt, pinv._adapt, atol=1e-12)           # square C: the same law
    keep = [0, 1, 2, 4, 5]                                                      # drop the α output: C is 5×6
    short = LinearModel(m.A, m.B, m.C[keep], E=m.E, dt=m.dt, input_names=m.input_names,
                        output_names=[m.output_names[i] for i in keep], state_names=m.state_names)
    with pytest.raises(RobofdiError, match="range of Cᵀ; actuator 'elevator_left'"):
        LockInPlaceBank(short, [-3, -3.5, -4, -4.5, -5, -5.5], output_form="spr")
    with pytest.raises(RobofdiError, match="output_form"):
        LockInPlaceBank(m, [-3] * 6, output_form="other")


def test_spr_output_form_converges_on_a_non_square_C_with_the_designed_lyapunov_weight():
    # the reduced aircraft (5×6 C, three surfaces): Q_lyap from spr_lyapunov_weight meets P T bᵢ = Cᵀ Gᵢ; the
    # SPR-form law then drives û of the locked elevator to the lock value; all five surfaces: refused by rank
    model = discretize(aircraft_three_surfaces(), 1e-3)
    assert model.C.shape == (5, 6)
    Q = spr_lyapunov_weight(model, NONSQUARE_POLES)
    bank = LockInPlaceBank(model, NONSQUARE_POLES, Q_lyap=Q, output_form="spr")
    N = np.linalg.svd(model.C)[2][-1]                                 # ker C
    assert np.abs(N @ bank.P @ bank._Tb).max() < 1e-9 * np.abs(bank.P @ bank._Tb).max()
    est = lock_estimates(bank, model, 0, duration=2.5, onset=0.5, gust_onset=0.25)
    assert abs(est[0, 0]) < 1e-12 and abs(est[-1, 0] - 1.0) < 0.02                 # 2 s after the lock
    with pytest.raises(RobofdiError, match="range of Cᵀ"):
        LockInPlaceBank(model, NONSQUARE_POLES, output_form="spr")              # Q_lyap = I misses the condition
    full = discretize(aircraft_lateral(), 1e-3)
    with pytest.raises(RobofdiError, match=r"rank\(C T B\) = 4 < rank\(T B\) = 5"):
        spr_lyapunov_weight(LinearModel(full.A, full.B, full.C[1:], E=full.E, dt=full.dt), NONSQUARE_POLES)
