"""Bošković & Mehra, chapter 5: the calibration-error (§3.2) and generalised y = Cx + d (§4) laws as diagnosers,
and the non-hybrid MMST bank with periodic resets (§5.3) against the hybrid bank (§5.4), on small exactly sampled
linear plants (no closed loop; about 1 s in total)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from robofdi.errors import RobofdiError
from robofdi.observers.effector_bank import HybridEffectorFDI
from robofdi.observers.mmst_bank import MultipleModelEffectorFDI
from robofdi.observers.sensor_adaptive import bias_gains
from robofdi.observers.sensor_calibration import GeneralisedSensorEstimator, calibration_gains

DT = 0.01
A3 = np.array([[-1.0, 0.5, 0.0], [-0.4, -0.8, 0.3], [0.2, 0.0, -1.5]])
B3 = np.array([[1.0, 0.0], [0.3, 1.0], [0.0, 0.8]])


def _simulate(A, B, u_of_t, T, x0=None):
    """x(k) of ẋ = Ax + Bu, u held over each sample (exact)."""
    n, m = B.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = A, B
    E = expm(big * DT)
    Ad, Bd = E[:n, :n], E[:n, n:]
    x = np.zeros(n) if x0 is None else np.asarray(x0, float)
    xs, us = [], []
    for k in range(int(T / DT)):
        u = u_of_t(k * DT)
        xs.append(x.copy())
        us.append(u)
        x = Ad @ x + Bd @ u
    return np.array(xs), np.array(us)


def _excite(t):
    return np.array([np.sin(1.3 * t) + 0.5 * np.sin(3.1 * t), np.cos(0.7 * t) + 0.4 * np.sin(2.3 * t)])


def _run(est, y, u):
    # the diagnoser sees y(k) with ū(k−1), the input applied over the last interval
    ubar = np.vstack([np.zeros(u.shape[1]), u[:-1]])
    return [est.update(yk, uk) for yk, uk in zip(y, ubar)]


def _estimator(estimate, y, u, **kw):
    gc = calibration_gains(A3, B3, y[::10], u[::10], -5.0, 1.0)
    gd = bias_gains(A3, -5.0, 0.5) if "bias" in estimate else 0.0
    return GeneralisedSensorEstimator(A3, B3, ["a", "b", "c"], ["u1", "u2"], ["rad"] * 3, DT, lam=-5.0, gamma_d=gd,
                                      gamma_c=gc, estimate=estimate, **kw)


def test_calibration_law_identifies_a_scale_error():
    x, u = _simulate(A3, B3, _excite, 20.0)
    c = np.array([1.0, 1.3, 0.8])
    est = _estimator(("calibration",), x, u)
    res = _run(est, x * c, u)
    assert np.allclose(est.calibration, c, atol=0.02)
    assert np.allclose(res[-1].estimate, c - 1, atol=0.02)
    est.reset()
    _run(est, x, u)                                          # no calibration error: ĉ stays at 1
    assert np.allclose(est.calibration, 1.0, atol=1e-3)


def test_generalised_law_identifies_bias_and_scale_together():
    x, u = _simulate(A3, B3, _excite, 30.0)
    c, d = np.array([1.25, 1.0, 1.0]), np.array([0.0, 0.05, -0.03])
    est = _estimator(("bias", "calibration"), x, u)
    res = _run(est, x * c + d, u)
    assert np.allclose(est.calibration, c, atol=0.03)
    assert np.allclose(est.bias, d, atol=0.01)
    # the residual is the estimated sensor error y − x̂, x̂ = Ĉ⁻¹(y − d̂)
    assert np.allclose(res[-1].r, (x[-1] * c + d) - x[-1], atol=0.01)


def test_generalised_estimator_refuses_bad_settings():
    good = dict(A=A3, B=B3, states=["a", "b", "c"], inputs=["u1", "u2"], units=["rad"] * 3, dt=DT)
    for bad, field in ((dict(lam=1.0), "lam"), (dict(estimate=("bias",)), "estimate"),
                       (dict(c_bounds=(1.2, 2.0)), "c_bounds"), (dict(weights=[1, 0, 1]), "weights"),
                       (dict(gamma_c=0.0), "gamma")):
        with pytest.raises(RobofdiError, match=field):
            GeneralisedSensorEstimator(**good, **bad)


# ---------------------------------------------------------------------------------------------- MMST vs hybrid
# an x₂-only plant: three rates, five effectors with pairwise non-collinear columns, lock of effector 0 at 1 s and
# of effector 3 at 3 s
A2 = np.array([[-0.8, 0.1, 0.0], [0.0, -1.2, 0.3], [0.05, 0.0, -0.5]])
B2 = np.array([[1.0, 0.8, -0.5, 0.2, 0.0], [0.2, -0.6, 0.9, 1.0, -0.4], [-0.3, 0.4, 0.3, 0.5, 1.0]])
LO, HI = -np.ones(5), np.ones(5)


def _locked_run(bank, locks):
    """Closed in the open: u = commanded sinusoids; the plant holds the locked effectors at their value at onset."""
    n, m = B2.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = A2, B2
    E = expm(big * DT)
    Ad, Bd = E[:n, :n], E[:n, n:]
    x, held = np.zeros(n), {}
    bank.reset()
    u_prev = np.zeros(m)
    for k in range(int(5.0 / DT)):
        t = k * DT
        bank.update(x, u_prev)
        uc = 0.5 * np.sin(np.array([1.1, 1.7, 0.9, 2.3, 1.3]) * t + np.arange(m))
        ua = uc.copy()
        for i, onset in locks.items():
            if t >= onset:
                held.setdefault(i, uc[i])
                ua[i] = held[i]
        x = Ad @ x + Bd @ ua
        u_prev = uc
    return held


def _banks():
    kw = dict(lam=40.0, gamma=5000.0, t_s=0.05, delta=1e-5)
    names = [f"e{i}" for i in range(5)]
    args = (A2, B2, names, ["x", "y", "z"], [0, 1, 2], DT, LO, HI)
    return HybridEffectorFDI(*args, **kw), MultipleModelEffectorFDI(*args, **kw)


def test_mmst_bank_isolates_one_lock_and_misses_the_second_which_the_hybrid_bank_commits():
    hybrid, mmst = _banks()
    for bank in (hybrid, mmst):
        _locked_run(bank, {})
        assert [m for _, m in bank.sequence] == ["nominal"]             # no switch without a failure
    held = _locked_run(hybrid, {0: 1.0, 3: 3.0})
    assert [m for _, m in hybrid.sequence] == ["nominal", "e0", "e3"]
    assert hybrid.frozen[0] == pytest.approx(held[0], abs=0.02)
    assert hybrid.frozen[3] == pytest.approx(held[3], abs=0.02)
    held = _locked_run(mmst, {0: 1.0})
    models = [m for _, m in mmst.sequence]
    assert models[:2] == ["nominal", "e0"] and mmst.active == 0
    assert mmst._z[0, -1] == pytest.approx(held[0], abs=0.02)          # the adaptive û₀ (never frozen)
    _locked_run(mmst, {0: 1.0, 3: 3.0})
    assert not mmst.frozen                                            # nothing is ever committed


def test_the_flight_surrogate_builds_the_diagnosers_it_is_asked_for():
    from robofdi.systems import flight_surrogate as fs

    loop = fs.build_loop(fs.FlightScenario(scheme="baseline", diagnosers=("sensor_calibration", "sensor_generalised")))
    assert set(loop.diagnoses) == {"sensor_calibration", "sensor_generalised"}
    loop = fs.build_loop(fs.FlightScenario(scheme="mmst", diagnosers=("sensor_bias",)))
    assert set(loop.diagnoses) == {"sensor_bias", "mmst"}           # the scheme's health source is always built
    assert isinstance(loop.diagnoses["mmst"].diagnoser, MultipleModelEffectorFDI)
    with pytest.raises(RobofdiError, match="diagnosers"):
        fs.FlightScenario(diagnosers=("kalman",))
