"""Bošković & Mehra, chapter 5: every exact unit check of the digest's C.1(a) (no plant data needed) — failure
injectors, the IDCL allocation (5)/(39), the reconfigured allocations Θᵢ (42), the estimator dynamics (49) and
its settling time, the projection, the generalised sensor law (26) against (10)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from robofdi.faults import ExponentialGrowth, Fault, FaultInjector, profile_from_dict
from robofdi.ftc.idcl import allocate, allocation_matrix, check_weights
from robofdi.models.flight import flight_surrogate
from robofdi.observers.effector_bank import HybridEffectorFDI, design_gains, foh_discretize, settling_time
from robofdi.observers.sensor_adaptive import (
    SensorBiasEstimator, bias_rate, box_projection, generalised_rate, generalised_regressor,
)
from robofdi.sims.flight import FlightPlant

S = flight_surrogate()
ACT = list(S.effectors)
SENS = ["s0", "s1", "s2"]


def _inject(fault, t, u=None, y=None):
    inj = FaultInjector([fault], ACT, SENS, 0)
    out = []
    for tk in t:
        out.append(inj.actuate(tk, u(tk)) if u is not None else inj.sense(tk, y(tk)))
    return np.array(out)


# ------------------------------------------------------------------ 1. failure injectors (table A3, A2)
def test_lock_in_place_holds_the_command_at_failure():
    t = np.arange(0, 2, 0.01)
    u = _inject(Fault("lip", "actuator_lock_in_place", "lef_right", onset=1.0), t, u=lambda tk: np.full(8, np.sin(tk)))
    held = u[t >= 1.0, 1]
    assert np.allclose(held, np.sin(1.0), atol=1e-12)
    assert np.allclose(u[t < 1.0, 1], np.sin(t[t < 1.0]))


def test_float_gives_zero_and_loss_of_effectiveness_scales():
    t = np.arange(0, 2, 0.01)
    u = _inject(Fault("f", "actuator_float", "ail_left", onset=1.0), t, u=lambda tk: np.full(8, 0.3))
    assert np.all(u[t >= 1.0, 4] == 0.0)
    k = 0.4                                               # effectiveness k = 1 − m, k in [ε, 1)
    u = _inject(Fault("loe", "actuator_loss_of_effectiveness", "ail_left", onset=1.0, magnitude=1 - k), t,
                u=lambda tk: np.full(8, 0.3))
    assert np.allclose(u[t >= 1.0, 4], k * 0.3)


def test_hard_over_ramps_at_the_rate_limit_to_the_limit_and_stays():
    plant = FlightPlant(noise=0.0, servo_tau=0.0)
    plant.reset(seed=0)
    inj = FaultInjector([Fault("hof", "actuator_hard_over", "rud_left", onset=0.0,
                               params={"limit": float(S.u_max[6])})], ACT, plant.sensor_channels, 0)
    pos = []
    for k in range(60):
        plant.step(inj.actuate(k * 0.01, np.zeros(8)))
        pos.append(plant.u_applied[6])
    pos = np.array(pos)
    rate = S.rate_limit[6]
    reach = int(np.ceil(S.u_max[6] / (rate * 0.01)))
    assert np.allclose(np.diff(pos[:reach - 1]), rate * 0.01, rtol=1e-9)
    assert np.allclose(pos[reach:], S.u_max[6])


def test_sensor_failures_match_the_table():
    t = np.arange(0, 3, 0.01)
    y = lambda tk: np.array([tk, 2 * tk, 1.0])   # noqa: E731
    b = _inject(Fault("b", "sensor_bias", "s0", onset=1.0, magnitude=0.2), t, y=y)
    assert np.allclose(b[t >= 1.0, 0] - t[t >= 1.0], 0.2) and np.allclose(b[t < 1.0, 0], t[t < 1.0])
    d = _inject(Fault("d", "sensor_drift", "s1", onset=1.0, magnitude=0.1), t, y=y)   # λ(t − t_F), the fix of "λt"
    assert np.allclose(d[t >= 1.0, 1] - 2 * t[t >= 1.0], 0.1 * (t[t >= 1.0] - 1.0))
    f = _inject(Fault("f", "sensor_freeze", "s0", onset=1.0), t, y=y)
    assert np.allclose(f[t >= 1.0, 0], 1.0)
    c = _inject(Fault("c", "sensor_scale", "s1", onset=1.0, magnitude=-0.3), t, y=y)  # calibration c = 0.7
    assert np.allclose(c[t >= 1.0, 1], 0.7 * 2 * t[t >= 1.0])
    n = _inject(Fault("n", "sensor_noise", "s2", onset=1.0, magnitude=0.05), t, y=y)  # loss of accuracy
    assert np.all(n[t < 1.0, 2] == 1.0) and 0.03 < np.std(n[t >= 1.0, 2]) < 0.07


def test_sim2_growing_exponential_profile():
    c = np.array([0.0175, 0.045, -0.0525])
    faults = [Fault(f"d{i}", "sensor_bias", s, onset=3.0, magnitude=float(ci), profile=ExponentialGrowth(0.05))
              for i, (s, ci) in enumerate(zip(SENS, c))]
    inj = FaultInjector(faults, ACT, SENS, 0)
    assert np.all(inj.sense(2.99, np.zeros(3)) == 0.0)
    assert np.allclose(inj.sense(3.0, np.zeros(3)), c, atol=1e-12, rtol=0)
    assert np.allclose(inj.sense(10.0, np.zeros(3)), math.exp(0.35) * c, atol=1e-12, rtol=0)
    assert profile_from_dict({"type": "exponential_growth", "rate": 0.05}) == ExponentialGrowth(0.05)


# ------------------------------------------------------------------ 2. IDCL
@pytest.mark.parametrize("seed", range(3))
def test_idcl_meets_eta_and_is_the_minimum_effort_solution(seed):
    g = np.random.default_rng(seed)
    B, W = S.B2(), S.weights()
    eta = g.normal(size=3)
    u = allocate(B, W, eta)
    assert np.max(np.abs(B @ u - eta)) < 1e-10
    # KKT solve of min uᵀWu s.t. Bu = η, and a generic optimiser
    K = np.block([[2 * np.diag(W), B.T], [B, np.zeros((3, 3))]])
    kkt = np.linalg.solve(K, np.concatenate([np.zeros(8), eta]))[:8]
    assert np.allclose(u, kkt, atol=1e-10)
    opt = minimize(lambda v: v @ (W * v), np.zeros(8), constraints={"type": "eq", "fun": lambda v: B @ v - eta},
                   method="SLSQP", options={"ftol": 1e-14})
    assert u @ (W * u) <= opt.fun + 1e-9


# ------------------------------------------------------------------ 3. Θᵢ
@pytest.mark.parametrize("i", range(8))
def test_reconfigured_allocation_theta_i(i):
    B, W = S.B2(), S.weights()
    Th = allocation_matrix(B, W, [i])
    Bb = B.copy()
    Bb[:, i] = 0.0
    assert np.allclose(Bb @ Th, np.eye(3), atol=1e-10)
    v = np.random.default_rng(i).normal(size=3)
    assert abs((Th @ v)[i]) == 0.0
    eta, ubar = v, 0.2
    stuck = np.zeros(8)
    stuck[i] = ubar
    uc = allocate(B, W, eta, [i], stuck)
    with_stuck = uc.copy()
    with_stuck[i] = ubar                                   # the plant: effector i held at ū
    assert np.allclose(B @ with_stuck, eta, atol=1e-10)


# ------------------------------------------------------------------ 4. estimator dynamics (47)–(49)
@pytest.mark.parametrize("bb", [0.1, 1.0, 16.0, 25.0])
def test_stuck_estimator_settles_like_eq_49(bb):
    lam, gamma, dt = 40.0, 5000.0, 1e-4
    b = np.array([np.sqrt(bb), 0.0, 0.0])
    # error system of (47)–(48): ė = −λe + b φ, φ̇ = −γ bᵀe (ū constant), sampled exactly
    M = np.zeros((4, 4))
    M[:3, :3], M[:3, 3], M[3, :3] = -lam * np.eye(3), b, -gamma * b
    Phi = foh_discretize(M, np.zeros((4, 1)), np.zeros((4, 1)), dt)[0]
    z = np.array([0, 0, 0, 1.0])
    phi = [1.0]
    for _ in range(int(0.4 / dt)):
        z = Phi @ z
        phi.append(z[3])
    phi = np.abs(np.array(phi))
    t = np.arange(len(phi)) * dt
    assert phi[t >= 0.25].max() <= 0.02
    ts = settling_time(lam, gamma, b)
    # 2 % settling of the envelope e^{−λt/2}: the last time |φ| exceeds 2 % can fall at a zero crossing, so compare
    # the envelope's settling time with the formula
    env = np.exp(-lam / 2 * t)
    sim = t[np.flatnonzero(env > 0.02)[-1]]
    assert abs(ts - sim) <= 0.1 * ts + dt


def test_design_gains_inverts_settling_time():
    b = S.B2()[:, 6]
    lam, gamma = design_gains(0.2, 0.3, b)
    assert lam == pytest.approx(40.0)
    assert settling_time(lam, gamma, b) == pytest.approx(0.2)


# ------------------------------------------------------------------ 5. projection
def test_projection_keeps_the_estimate_in_its_box():
    v = box_projection([1.0, -1.0, 0.0], [2.0, -3.0, 5.0], -1.0, 1.0)
    assert v.tolist() == [0.0, 0.0, 5.0]
    v = box_projection([1.0, -1.0], [-2.0, 3.0], -1.0, 1.0)           # pointing inward: unchanged
    assert v.tolist() == [-2.0, 3.0]
    # a bias far outside the bound: the estimate saturates at d̄ and never leaves
    A, B = S.A(), S.B()
    est = SensorBiasEstimator(A, B, S.state_names, S.effectors, list(S.units), 0.01, gamma=50.0, d_bar=0.05)
    g = np.random.default_rng(0)
    for _ in range(300):
        res = est.update(np.full(8, 0.5) + 1e-3 * g.normal(size=8), np.zeros(8))
        assert np.all(np.abs(res.estimate) <= 0.05 + 1e-15)
    # the hybrid bank's stuck estimates stay inside the position limits
    bank = HybridEffectorFDI(S.A2(), S.B2(), S.effectors, S.state_names, range(5, 8), 0.01, S.u_min, S.u_max)
    for _ in range(100):
        res = bank.update(g.normal(size=8), np.full(8, 5.0))
        assert np.all(res.estimate >= S.u_min - 1e-15) and np.all(res.estimate <= S.u_max + 1e-15)


# ------------------------------------------------------------------ 6. generalised sensor law (26) → (10)
def test_generalised_sensor_law_reduces_to_eq_10_with_identity_calibration():
    g = np.random.default_rng(3)
    A, B = S.A(), S.B()
    y, u, e, d = g.normal(size=8), g.normal(size=8), g.normal(size=8), 0.01 * g.normal(size=8)
    Gamma = np.diag(np.full(16, 7.0))
    rate = generalised_rate(A, B, np.ones(8), d, y, u, e, Gamma)
    assert np.allclose(rate[:8], bias_rate(A, 7.0 * np.eye(8), e, d, np.full(8, 1.0)), atol=1e-12)
    Om = generalised_regressor(A, B, np.ones(8), d, y, u)
    assert np.allclose(Om[:, :8], -A)                                 # the sign-fixed −Ĉ_o block
    # Ω = ∂g/∂c by finite differences at ĉ = 1.3
    c = np.full(8, 1.3)
    gfun = lambda cc: (cc[:, None] * A / cc[None, :]) @ (y - d) + cc * (B @ u)   # noqa: E731
    fd = np.column_stack([(gfun(c + h) - gfun(c - h)) / 2e-6 for h in np.eye(8) * 1e-6])
    assert np.allclose(generalised_regressor(A, B, c, d, y, u)[:, 8:], fd, atol=1e-6)


def test_weights_are_checked():
    assert check_weights(np.diag([1.0, 2.0]), 2).tolist() == [1.0, 2.0]
