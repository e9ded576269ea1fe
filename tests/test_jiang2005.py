"""Jiang & Chowdhury (2005): the reduced-order Kalman fault estimator, LOE accommodation and the unknown-input filter
on the paper's helicopter — every check of spec_linear_papers.md A.7 that the digest marks as checkable."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.control.linear import StateFeedback, lqr_gain
from robofdi.faults import Fault, Oscillation
from robofdi.models.linear_examples import HELICOPTER_NOISE, helicopter
from robofdi.models.linear import LinearModel
from robofdi.observers.kalman import (
    ParameterFaultEKF,
    KalmanFaultEstimator, reduced_order_covariances, reduced_order_design, steady_state_gain,
)
from robofdi.systems.helicopter import (
    FAULT_OUTPUTS, UNKNOWN_INPUT_FAULTS, HelicopterScenario, build_loop, calibrate, fault_estimates, run_helicopter,
)

S, Q = HELICOPTER_NOISE["process"], HELICOPTER_NOISE["sensor"]


def test_partition_reproduces_the_papers_numbers():
    m = helicopter()
    d = reduced_order_design(m, -m.B, FAULT_OUTPUTS)
    assert d.Abar11[0, 0] == pytest.approx(1.0521, abs=1e-4)
    assert d.Abar21[0, 0] == pytest.approx(10.5091, abs=1e-4)
    assert d.rank_CE == 2
    # digest A.6: E₃ in the paper's coordinates, det 3.957e-4; the −1 in C flips y₂'s second row
    assert np.linalg.det(d.E[2:]) == pytest.approx(3.957e-4, rel=1e-3)
    # other partitions give the digest's other values (y₁ = u: 0.98952, 1.58867)
    other = reduced_order_design(m, -m.B, ["y_minus_w", "y_pitch_rate"])
    assert other.Abar11[0, 0] == pytest.approx(0.98952, abs=1e-5)
    assert abs(other.Abar21[0, 0]) == pytest.approx(1.58867, abs=1e-5)


@pytest.mark.parametrize("mode, innovation, process, gain, pole", [
    ("as_printed", 1.2e-4, 0.61097, 0.10011, 0.0),
    ("swapped", 0.61097, 1.2e-4, 0.01838, 0.85898),
    ("corrected", 4.07324, 2.4e-4, 0.01352, 0.91005),
])
def test_covariance_modes_and_stationary_filter_match_the_digest_table(mode, innovation, process, gain, pole):
    m = helicopter()
    d = reduced_order_design(m, -m.B, FAULT_OUTPUTS)
    Qb, Sb = reduced_order_covariances(d, S, Q, mode)
    assert Sb[0, 0] == pytest.approx(innovation, rel=0.03)
    assert Qb[0, 0] == pytest.approx(process, rel=0.03)
    K, _ = steady_state_gain(d.Abar11, d.Abar21, Qb, Sb)
    assert K[0, 0] == pytest.approx(gain, rel=1e-3)
    assert (d.Abar11 - K @ d.Abar21)[0, 0] == pytest.approx(pole, abs=1e-4)


def _noise_free(**kw):
    sc = HelicopterScenario(noise=False, **kw)
    return sc, build_loop(sc, calibrate(sc)).run(sc.duration, seed=0)


def test_noise_free_estimate_is_exact_after_the_one_step_delay():
    sc, rec = _noise_free(accommodation=False)
    rec0 = build_loop(replace(sc, faults=())).run(sc.duration, seed=0)
    # θ(0) ≠ 0 exercises the convergence of x̂₁ (x̂₁(0) = 0)
    theta0 = build_loop(sc).run(2.0, initial_state=[1.0, 0.5, 0.0, 0.05], seed=0)
    f, _ = fault_estimates(theta0, sc)
    assert abs(f[5, 0]) < 1e-9 < abs(f[1, 0])          # converged within a few samples, wrong before
    f, _ = fault_estimates(rec, sc)
    truth = -np.stack([rec.faults["r1"].value, rec.faults["r2"].value], axis=1)   # f = R u (label = −R u)
    assert np.max(np.abs(f[1:] - truth[:-1])) < 1e-9
    u = rec.signals["u_diag"][:-1]
    r_hat = rec.diagnosers["kalman_fe"].residual[1:]
    r_true = np.where(rec.time[:-1, None] >= [4.0, 2.0], [0.4, 0.0], 0.0)
    r_true[:, 1] = np.where(rec.time[:-1] >= 2.0, 0.5 + 0.3 * np.sin(np.pi * rec.time[:-1]), 0.0)
    ok = np.abs(u) > 1e-6
    assert np.max(np.abs(r_hat - r_true)[ok]) < 1e-9
    # no fault, no estimate
    assert np.max(np.abs(rec0.diagnosers["kalman_fe"].residual)) < 1e-9


@pytest.mark.parametrize("mode", ["swapped", "corrected"])
def test_noise_free_exactness_holds_in_every_covariance_mode(mode):
    sc, rec = _noise_free(accommodation=False, covariance_mode=mode)
    f, _ = fault_estimates(rec, sc)
    truth = -np.stack([rec.faults["r1"].value, rec.faults["r2"].value], axis=1)
    assert np.max(np.abs(f[1:] - truth[:-1])) < 1e-9


def test_same_seed_gives_a_byte_identical_record(tmp_path):
    a, _ = run_helicopter(seed=3, threshold=np.ones(2))
    b, _ = run_helicopter(seed=3, threshold=np.ones(2))
    assert a.save(tmp_path / "a.h5").read_bytes() == b.save(tmp_path / "b.h5").read_bytes()


def test_accommodation_keeps_the_loop_near_the_fault_free_one():
    sc, with_ftc = _noise_free()
    free = build_loop(replace(sc, faults=(), accommodation=False)).run(sc.duration, seed=0)
    without = build_loop(replace(sc, accommodation=False)).run(sc.duration, seed=0)
    dev = lambda r: np.sqrt(np.mean((r.truth_state - free.truth_state) ** 2, axis=0))  # noqa: E731
    assert np.all(dev(with_ftc) < 0.01)
    assert np.all(dev(without)[:3] > 0.04)
    assert with_ftc.meta["health_source"] == "kalman_fe"      # diagnosed health, not the oracle


def test_noisy_estimate_is_unbiased_and_the_ls_effectiveness_is_near_the_paper():
    for seed in (1, 2, 3):
        sc = HelicopterScenario(seed=seed, accommodation=False, covariance_mode="corrected")
        rec = build_loop(sc).run(sc.duration, seed=seed, run_key="ls_estimate")
        f, _ = fault_estimates(rec, sc)
        err = f[1:] - (-np.stack([rec.faults["r1"].value, rec.faults["r2"].value], axis=1))[:-1]
        sd = err.std(axis=0)
        assert np.all(np.abs(err.mean(axis=0)) < 0.05 * sd)
        assert sd == pytest.approx([56.1, 26.4], rel=0.2)          # sensor noise through E₃⁻¹
        u, t = rec.signals["u_diag"][:-1], rec.time[:-1]
        sel = t >= 5.0
        r1 = np.sum(f[1:][sel, 0] * u[sel, 0]) / np.sum(u[sel, 0] ** 2)
        assert abs(r1 - 0.4) < 0.03


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_digest_harness_meets_every_noisy_check_of_item_4(seed):
    """Spec A.7 item 4 on its [HARNESS]: as-printed filter, paper's S and Q, accommodation fed by the ungated
    element-wise R̂ (clipped to [0, 0.95]); the windowed LS (25 samples) is the evaluated estimate."""
    sc = HelicopterScenario(seed=seed, harness="digest")
    assert sc.covariance_mode == "as_printed" and sc.samples == 25 and sc.accommodation
    rec = build_loop(sc).run(sc.duration, seed=seed)
    assert rec.meta["health_source"] == "elementwise"
    f, _ = fault_estimates(rec, sc)
    err = f[1:] - (-np.stack([rec.faults["r1"].value, rec.faults["r2"].value], axis=1))[:-1]
    sd = err.std(axis=0)
    assert np.all(np.abs(err.mean(axis=0)) < 0.05 * sd)
    assert sd == pytest.approx([56.1, 26.4], rel=0.2)
    u, t = rec.signals["u_diag"][:-1], rec.time[:-1]
    sel = t >= 5.0
    assert abs(np.sum(f[1:][sel, 0] * u[sel, 0]) / np.sum(u[sel, 0] ** 2) - 0.4) < 0.03
    # r̂(k) (window of f̂ up to k−1) against r(k−1), once the whole window lies after the onset
    r = np.stack([np.where(t >= 4.0, 0.4, 0.0), np.where(t >= 2.0, 0.5 + 0.3 * np.sin(np.pi * t), 0.0)], axis=1)
    e = rec.diagnosers["kalman_fe"].residual[1:] - r
    assert np.sqrt(np.mean(e[t >= 4.25, 0] ** 2)) <= 0.025
    assert np.sqrt(np.mean(e[t >= 2.25, 1] ** 2)) < 0.12
    # the accommodation saw R̂ at the clip on some samples: the amplification the digest's caveat describes
    ratio = rec.signals["u"] / rec.signals["u_cmd"]
    assert np.max(ratio) == pytest.approx(20.0, rel=1e-9) and np.sqrt(np.mean(rec.signals["u"] ** 2)) > 300


def test_default_loop_gates_the_accommodation_by_the_decision():
    sc = HelicopterScenario(seed=1)
    rec = build_loop(sc, np.full(2, 1e6)).run(sc.duration, seed=1)     # nothing isolated, nothing compensated
    assert np.array_equal(rec.signals["u"], rec.signals["u_cmd"])
    assert set(rec.diagnosers) == {"kalman_fe"}
    with pytest.raises(RobofdiError, match="'harness' must be one of"):
        HelicopterScenario(harness="paper")


def test_noisy_closed_loop_detects_isolates_without_false_alarms():
    record, summary = run_helicopter(seed=4)
    d = summary["diagnosers"]["kalman_fe"]
    assert d["false_alarms"] == 0
    assert {x["fault"]: x["isolated"] for x in d["detections"]} == {"r1": "collective", "r2": "cyclic"}
    assert all(0 < x["delay"] < 1.0 for x in d["detections"])


@pytest.mark.parametrize("mode", ["swapped", "corrected"])
def test_unknown_input_filter_learns_zeta(mode):
    sc = HelicopterScenario(noise=False, faults=UNKNOWN_INPUT_FAULTS, unknown_input=0.1, covariance_mode=mode,
                            accommodation=False)
    rec = build_loop(sc).run(sc.duration, seed=0)
    f, zeta = fault_estimates(rec, sc)
    assert 0.098 <= zeta[-1, 0] <= 0.102
    assert abs(f[-1, 0] - (-rec.faults["r3"].value[-2])) < 1e-4


def test_state_feedback_uses_an_external_estimator():
    m = helicopter()
    fe = KalmanFaultEstimator(m, S, Q, fault_outputs=FAULT_OUTPUTS)
    ctrl = StateFeedback(m, lqr_gain(m, np.ones(4), np.ones(2)), None, estimator=fe)
    y = m.C @ np.array([1.0, 0.5, 0.2, 0.0])
    ctrl.update(y)
    assert np.allclose(fe.state_estimate, [1.0, 0.5, 0.2, 0.0])
    with pytest.raises(RobofdiError, match="estimator"):
        StateFeedback(m, ctrl.K, None, estimator=object())


def test_oscillation_profile_is_a_unit_profile_only_inside_0_1():
    Fault("r", "actuator_loss_of_effectiveness", "u1", onset=0.0, profile=Oscillation(0.5, 0.3, 0.5))
    with pytest.raises(RobofdiError, match="stay in"):
        Fault("r", "actuator_loss_of_effectiveness", "u1", onset=0.0, profile=Oscillation(0.5, 0.6, 0.5))


def test_bad_input_names_the_condition():
    m = helicopter()
    with pytest.raises(RobofdiError, match="'E' must be a finite 4xq"):
        reduced_order_design(m, np.ones((3, 2)))
    with pytest.raises(RobofdiError, match=r"Assumption 1 violated: rank\(CE\) = 1"):
        reduced_order_design(m, np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 2.0], [0.0, 0.0]]))
    with pytest.raises(RobofdiError, match="E₃ .* is singular"):       # fault only reaches y_pitch_rate and y_u
        reduced_order_design(m, np.array([[1.0], [0.0], [0.0], [0.0]]), ["y_minus_w"])
    d = reduced_order_design(m, -m.B, FAULT_OUTPUTS)
    with pytest.raises(RobofdiError, match="positive definite"):
        reduced_order_covariances(d, np.diag([0.01, 0.01, 0.0, 1e-4]), Q)
    with pytest.raises(RobofdiError, match="symmetric"):
        reduced_order_covariances(d, np.triu(np.ones((4, 4))), Q)
    with pytest.raises(RobofdiError, match="covariance_mode"):
        reduced_order_covariances(d, S, Q, "bogus")
    # Theorem 1: x₁ invisible in the derived measurement
    A = np.diag([0.5, 0.9, 0.8])
    blind = LinearModel(A, np.eye(3)[:, 1:], np.eye(3)[1:], dt=0.1)
    with pytest.raises(RobofdiError, match="Theorem 1 needs"):
        KalmanFaultEstimator(blind, np.eye(3), np.eye(2), E=[[0.0], [0.0], [1.0]])
    with pytest.raises(RobofdiError, match="discrete"):
        KalmanFaultEstimator(replace(m, dt=None), S, Q)
    fe = KalmanFaultEstimator(m, S, Q, fault_outputs=FAULT_OUTPUTS)
    with pytest.raises(RobofdiError, match="'y' must be a vector of 3"):
        fe.update(np.zeros(2), np.zeros(2))


def test_parameter_fault_ekf_is_exact_noise_free_on_a_scalar_plant_and_validates():
    # x⁺ = (a + θ a_θ) x + b (1 − r) u, y = x, noise-free: the EKF recovers θ and r (Remark 5) — a 1-state check
    from robofdi.models.linear import LinearModel

    model = LinearModel([[0.9]], [[1.0]], [[1.0]], dt=0.1)
    theta, r = 0.5, 0.3
    ekf = ParameterFaultEKF(model, [[[0.1]]], [[1e-12]], [[1e-10]], parameter_drift=0.0, fault_drift=0.0,
                            P0=np.diag([1.0, 1.0, 1.0]))
    x, u_prev = 1.0, 0.0
    gen = np.random.default_rng(0)
    for _ in range(200):
        ekf.update(np.array([x]), np.array([u_prev]))
        u_prev = float(gen.normal())
        x = (0.9 + theta * 0.1) * x + (1 - r) * u_prev
    assert ekf.parameter_estimate[0] == pytest.approx(theta, abs=1e-4)
    assert ekf.fault_estimate[0] == pytest.approx(r, abs=1e-4)
    with pytest.raises(RobofdiError, match="parameter_directions"):
        ParameterFaultEKF(model, [[[0.1, 0.2]]], [[1.0]], [[1.0]])
    with pytest.raises(RobofdiError, match="fault_drift"):
        ParameterFaultEKF(model, [], [[1.0]], [[1.0]], fault_drift=-1.0)


def test_augmented_error_estimator_is_exact_noise_free_and_refuses_unmeasured_directions():
    # Remark 5's alternative: x⁺ = (A + θ A_θ) x + B (1 − r) u with y = x₁ (x₂ unmeasured), noise-free; θ acts on
    # the measured x₁, so the regressor is measurable and the least squares on the augmented error is exact
    from robofdi.observers.augmented_error import AugmentedErrorEstimator

    A = np.array([[0.9, 0.1], [-0.05, 0.8]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    model = LinearModel(A, B, C, dt=0.1)
    A_th = np.array([[0.0, 0.0], [0.1, 0.0]])
    theta, r = 0.5, 0.3
    est = AugmentedErrorEstimator(model, [A_th], poles=(0.3, 0.4), forgetting=1.0, R0=1e8)
    x, u_prev = np.array([1.0, 0.0]), np.zeros(1)
    gen = np.random.default_rng(0)
    for _ in range(300):
        est.update(C @ x, u_prev)
        u_prev = gen.normal(size=1)
        x = (A + theta * A_th) @ x + B @ ((1 - r) * u_prev)
    assert est.parameter_estimate[0] == pytest.approx(theta, abs=1e-6)
    assert est.fault_estimate[0] == pytest.approx(r, abs=1e-6)
    with pytest.raises(RobofdiError, match="unmeasured state"):
        AugmentedErrorEstimator(model, [np.array([[0.0, 0.1], [0.0, 0.0]])])
    with pytest.raises(RobofdiError, match="forgetting"):
        AugmentedErrorEstimator(model, [A_th], forgetting=0.0)
