"""Seed 004 (reconstructed, spec_linear_papers.md C.3): the adaptive fault-estimation observer's structural checks."""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.experiments.adaptive_fe import PRINTED_RATE, analyse
from robofdi.models.linear_examples import f16_vertical
from robofdi.models.linear import LinearModel, discretize
from robofdi.observers.adaptive import (
    first_step_estimate,
    AdaptiveFaultEstimator, adaptive_fe_gains, adaptive_fe_lmi_gains, augmented_error_matrix, is_spd,
    lyapunov_certificate,
)
from robofdi.observers.linear import observer_gain_poles
from robofdi.systems.f16 import F16Scenario, build_loop, calibrate, run_f16


def test_printed_learning_rate_is_spd_and_the_typo_is_the_only_asymmetry():
    assert is_spd(PRINTED_RATE)
    asym = np.argwhere(np.abs(PRINTED_RATE - PRINTED_RATE.T) > 1e-12)
    assert {tuple(x) for x in asym} == {(1, 3), (3, 1)}


def test_gains_place_the_augmented_poles_and_the_certificate_holds():
    md = discretize(f16_vertical(), 0.1)
    poles = np.linspace(0.5, 0.85, 8)
    L, G = adaptive_fe_gains(md, md.B, poles)
    M = augmented_error_matrix(md.A, md.C, md.B, L, G)
    assert np.allclose(np.sort(np.abs(np.linalg.eigvals(M))), poles, atol=1e-6)
    P = lyapunov_certificate(M)
    assert is_spd(P) and np.allclose(M.T @ P @ M - P, -np.eye(8), atol=1e-8)
    # the paper's (F, Γ) form: F = G/γ, Γ = γ I gives the same observer
    fe = AdaptiveFaultEstimator(md, L, F=G / 0.5, Gamma=0.5)
    assert fe.spectral_radius == pytest.approx(0.85, abs=1e-6)


@pytest.mark.skipif(importlib.util.find_spec("cvxpy") is None, reason="cvxpy is not installed (the LMI needs it)")
def test_lmi_gains_meet_the_decay_rate_with_their_certificate():
    """Remark 3 (reconstructed): the LMI in (P, W = P K_a) gives gains whose augmented error matrix decays at the
    asked rate, P > 0 certifying Mᵀ P M < decay² P in the augmented-state coordinates; an impossible rate is refused."""
    md = discretize(f16_vertical(), 0.1)
    L, G, P = adaptive_fe_lmi_gains(md, md.B, decay=0.9)
    M = augmented_error_matrix(md.A, md.C, md.B, L, G)
    assert np.max(np.abs(np.linalg.eigvals(M))) < 0.9
    n, q = md.n, md.B.shape[1]
    Aa = np.block([[md.A, md.B], [np.zeros((q, n)), np.eye(q)]])
    Ka = np.vstack([L + md.B @ G, G])
    Acl = Aa - Ka @ np.hstack([md.C, np.zeros((md.p, q))])
    assert is_spd(P) and np.linalg.eigvalsh(Acl.T @ P @ Acl - 0.81 * P).max() < 0
    assert AdaptiveFaultEstimator(md, L, G=G).spectral_radius < 0.9
    with pytest.raises(RobofdiError, match="infeasible"):
        adaptive_fe_lmi_gains(md, md.B, decay=1e-3)


def test_unstable_designs_and_bad_input_are_rejected():
    md = discretize(f16_vertical(), 0.1)
    L = observer_gain_poles(md, [0.5, 0.55, 0.6, 0.65, 0.7])
    F = np.linalg.pinv(md.C @ md.B)
    with pytest.raises(RobofdiError, match="spectral radius .* >= 1"):
        AdaptiveFaultEstimator(md, L, F=F, Gamma=1.0)              # the naive F = (CE)⁺ design diverges here
    with pytest.raises(RobofdiError, match="full column rank"):
        AdaptiveFaultEstimator(md, L, G=np.zeros((2, 3)), E=np.ones((5, 2)))
    with pytest.raises(RobofdiError, match="symmetric positive definite"):
        AdaptiveFaultEstimator(md, L, F=F, Gamma=-np.eye(3))
    with pytest.raises(RobofdiError, match="'L' must be a finite 5x3"):
        AdaptiveFaultEstimator(md, np.zeros((3, 5)), G=np.zeros((3, 3)))
    with pytest.raises(RobofdiError, match="inside the unit circle"):
        adaptive_fe_gains(md, md.B, [1.2] * 8)


def test_constant_fault_converges_at_the_reported_rate_and_ramp_error_stays_bounded():
    sc = F16Scenario()
    loop = build_loop(sc)
    rho = loop.diagnoses["adaptive_fe"].diagnoser.spectral_radius
    stats = analyse(loop.run(sc.duration, seed=0), sc, rho)
    assert stats["decay_rate_per_sample"] <= rho + 0.01
    assert abs(stats["e_const_at_14.9s"]) < 1e-5
    assert stats["ramp_error_max_20_30s"] < 0.05 and stats["ramp_error_spread_20_30s"] < 1e-3


def test_closed_loop_detects_and_isolates_the_elevator_bias():
    record, summary = run_f16(seed=1, sensor_noise=0.005, threshold=calibrate(F16Scenario(seed=1, sensor_noise=0.005)))
    d = {x["fault"]: x for x in summary["diagnosers"]["adaptive_fe"]["detections"]}
    assert d["elevator_bias"]["isolated"] == "elevator" and d["elevator_bias"]["delay"] < 1.0


def test_remark2_first_step_estimate_is_exact_and_validates():
    # noise-free 2-state plant, constant actuator fault from k = 0: x(0) and f from 3 stacked outputs
    A = np.array([[0.9, 0.1], [0.0, 0.8]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    x, f = np.array([0.3, -0.2]), np.array([0.5])
    us = np.array([[0.1], [-0.2], [0.05]])
    ys = []
    for k in range(4):
        ys.append(C @ x)
        if k < 3:
            x = A @ x + B @ (us[k] + f)
    x_last, f_hat = first_step_estimate(A, B, C, B, np.array(ys), us)
    np.testing.assert_allclose(f_hat, f, atol=1e-12)
    np.testing.assert_allclose(x_last, x, atol=1e-12)
    with pytest.raises(RobofdiError, match="rank"):
        first_step_estimate(A, B, C, B, np.array(ys[:2]), us[:1])          # 2 outputs for 3 unknowns
    model = LinearModel(A, B, C, dt=0.1)
    with pytest.raises(RobofdiError, match="first_step"):
        AdaptiveFaultEstimator(model, np.zeros((2, 1)), G=np.zeros((1, 1)), first_step=1)


def test_remark2_lipschitz_output_variant_is_exact_and_refuses_without_contraction():
    # y = C x + δ sin(x₁) (Lipschitz δ): x and a constant fault from 6 stacked outputs by the contraction
    from robofdi.observers.first_step import first_step_estimate_lipschitz

    A = np.array([[0.9, 0.1], [0.0, 0.8]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    delta = 0.02
    g = lambda v: np.array([delta * np.sin(v[0])])                        # noqa: E731
    x, f = np.array([0.3, -0.2]), np.array([0.5])
    us = np.array([[0.1], [-0.2], [0.05], [0.3], [-0.1]])
    ys = []
    for k in range(6):
        ys.append(C @ x + g(x))
        if k < 5:
            x = A @ x + B @ (us[k] + f)
    x_last, f_hat, iterations = first_step_estimate_lipschitz(A, B, C, B, np.array(ys), us, g, delta)
    np.testing.assert_allclose(f_hat, f, atol=1e-10)
    np.testing.assert_allclose(x_last, x, atol=1e-10)
    assert 2 <= iterations < 50
    f_lin = first_step_estimate(A, B, C, B, np.array(ys), us)[1]
    assert abs(f_lin[0] - f[0]) > 1e-3                                   # the linear remark is biased here
    with pytest.raises(RobofdiError, match="contraction factor"):
        first_step_estimate_lipschitz(A, B, C, B, np.array(ys), us, g, 10.0)
    with pytest.raises(RobofdiError, match="lipschitz"):
        first_step_estimate_lipschitz(A, B, C, B, np.array(ys), us, g, -1.0)
