"""Tests of robofdi.observers: the algebra of the diagnostic observers of Caccavale & Villani (spec ch. 3, §3 and
the acceptance checks of §7) on synthetic "model == plant" data, the adaptive gain, the momentum observer on a
plant integrated with the nominal model, and the input checks."""
import numpy as np
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.models.manipulator import ManipulatorModel
from robofdi.observers import (
    Adaptive,
    DiagnosticObserver,
    EulerArmModel,
    MomentumObserver,
    Recursive,
    RippleModel,
    TimeDelayed,
)
from robofdi.observers.arm_schemes import BOOK_SCHEMES as SCHEMES, ArmSchemeSettings, arm_schemes

T = 0.002
N_JOINTS = 6
Q0 = np.array([np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0])  # the book's q0
GAMMA = ArmSchemeSettings().gamma_eta(N_JOINTS)  # experimental diag(Γ_η)


@pytest.fixture(scope="module")
def model():
    return ManipulatorModel(ASSETS / "arm6.xml")


# ---------------------------------------------------------------------------------------------------------------
# Synthetic "model == plant" data: x(k+1) = A x + h(x) + B(x) u(k) + η + f(k)  (eq. (17) with a constant η)
# ---------------------------------------------------------------------------------------------------------------
N_STEPS = 200
ETA = np.concatenate([[2e-5, -1e-5, 3e-5, -2e-5, 1e-5, 4e-6], [1e-3, -2e-3, 1.5e-3, -5e-4, 2e-3, -1e-3]])
STEP_K, STEP_ROW, STEP_SIZE = 20, N_JOINTS + 2, 0.005         # step on the joint-3 velocity row at k = 20
RAMP_K, RAMP_ROW, RAMP_SLOPE = 40, N_JOINTS + 4, 5e-5          # ramp on the joint-5 velocity row from k = 40
PRAMP_K, PRAMP_ROW, PRAMP_SLOPE = 60, 1, 3e-6                   # ramp on the joint-2 position row from k = 60


def fault(k: int) -> np.ndarray:
    f = np.zeros(2 * N_JOINTS)
    if k >= STEP_K:
        f[STEP_ROW] = STEP_SIZE
    if k >= RAMP_K:
        f[RAMP_ROW] = RAMP_SLOPE * (k - RAMP_K + 1)
    if k >= PRAMP_K:
        f[PRAMP_ROW] = PRAMP_SLOPE * (k - PRAMP_K + 1)
    return f


@pytest.fixture(scope="module")
def plant(model):
    """States x(0..N) and inputs u(0..N−1) of the synthetic plant (smooth torques around gravity compensation)."""
    euler = EulerArmModel(model, T)
    g0 = model.gravity(Q0)
    amp = np.array([20.0, 30.0, 15.0, 3.0, 3.0, 1.0])
    phase = np.linspace(0.0, 2.0, N_JOINTS)
    x = np.concatenate([Q0, np.zeros(N_JOINTS)])
    xs, us = [x], []
    for k in range(N_STEPS):
        u = g0 + amp * np.sin(2 * np.pi * 1.5 * k * T + phase)
        us.append(u)
        x = euler.predict(x, u) + ETA + fault(k)
        xs.append(x)
    xs = np.array(xs)
    assert np.all(np.isfinite(xs)) and np.max(np.abs(xs[:, N_JOINTS:])) < 5.0  # stays a sane trajectory
    return xs, np.array(us)


def run(observer, xs, us):
    """Feed y = x(k), u = u(k−1); return the returned residuals r(k), k = 0..N (r(0) is the start-up zero)."""
    out = []
    for k in range(len(xs)):
        u = us[k - 1] if k >= 1 else np.zeros(observer.n)
        out.append(observer.update(xs[k], u).r.copy())
    return np.array(out)


def state_observer(model, estimator=None, **kw):
    return DiagnosticObserver(model, T, estimator, residual_space="state", **kw)


def test_simple_residual_is_eta_plus_previous_fault(model, plant):
    xs, us = plant
    r = run(state_observer(model), xs, us)
    expected = np.array([ETA + fault(k - 1) for k in range(1, len(xs))])
    np.testing.assert_allclose(r[1:], expected, rtol=1e-9, atol=1e-12)     # eq. (21): r(k) = η + f(k−1)
    np.testing.assert_array_equal(r[0], np.zeros(2 * N_JOINTS))


def test_time_delayed_residual_is_fault_difference(model, plant):
    xs, us = plant
    r = run(state_observer(model, TimeDelayed()), xs, us)
    for k in range(2, len(xs)):                                              # eq. (31) with η constant
        np.testing.assert_allclose(r[k], fault(k - 1) - fault(k - 2), rtol=1e-9, atol=1e-12)
    # a step gives a one-sample pulse, a ramp a constant equal to the slope
    assert r[STEP_K + 1, STEP_ROW] == pytest.approx(STEP_SIZE, rel=1e-9)
    assert abs(r[STEP_K + 2, STEP_ROW]) < 1e-12
    np.testing.assert_allclose(r[RAMP_K + 2 :, RAMP_ROW], RAMP_SLOPE, rtol=1e-8)
    # start-up: the first residual still carries η (no estimate yet), r_TD(1) = η + f(0)
    np.testing.assert_allclose(r[1], ETA + fault(0), rtol=1e-9, atol=1e-12)


def test_time_delayed_is_first_difference_of_simple(model, plant):
    xs, us = plant
    r20 = run(state_observer(model), xs, us)
    rtd = run(state_observer(model, TimeDelayed()), xs, us)
    np.testing.assert_allclose(rtd[1:], r20[1:] - r20[:-1], rtol=1e-9, atol=1e-12)


def test_recursive_is_low_pass_of_time_delayed(model, plant):
    xs, us = plant
    gain = GAMMA.copy()
    gain[N_JOINTS + 1] = 1.5   # a gain above 1 (eig(I − Γ) = −0.5, still stable) on one row
    rtd = run(state_observer(model, TimeDelayed()), xs, us)
    rrec = run(state_observer(model, Recursive(gain)), xs, us)
    np.testing.assert_array_equal(rrec[0], 0.0)
    # eq. (35), exact from the start with r_rec(0) = 0
    np.testing.assert_allclose(rrec[1:], (1 - gain) * rrec[:-1] + rtd[1:], rtol=1e-9, atol=1e-12)
    # closed forms, a = 1 − γ: r_TD(1) = η, then f(k−1) − f(k−2), so r_rec(k) = η a^(k−1) + (fault part)
    k = np.arange(1, len(xs))
    # fault-free row with γ = 1.5: the start-up η alternates in sign and decays ×0.5 per step
    row = N_JOINTS + 1
    np.testing.assert_allclose(rrec[1:, row], ETA[row] * (-0.5) ** (k - 1), rtol=1e-9, atol=1e-15)
    # step of size s at k₀ (first seen at k₀ + 1): jump s, then decay a^j
    a = 1 - gain[STEP_ROW]
    step = np.where(k >= STEP_K + 1, STEP_SIZE * a ** np.maximum(k - STEP_K - 1, 0), 0.0)
    np.testing.assert_allclose(rrec[1:, STEP_ROW], ETA[STEP_ROW] * a ** (k - 1) + step, rtol=1e-9, atol=1e-15)
    # ramp of slope s: r_TD = s from k₀ + 1, so r_rec = s (1 − a^(k−k₀)) / γ → steady state Γ⁻¹ s (gain 1/γ)
    a = 1 - gain[RAMP_ROW]
    ramp = np.where(k >= RAMP_K + 1, RAMP_SLOPE * (1 - a ** np.maximum(k - RAMP_K, 0)) / gain[RAMP_ROW], 0.0)
    np.testing.assert_allclose(rrec[1:, RAMP_ROW], ETA[RAMP_ROW] * a ** (k - 1) + ramp, rtol=1e-9, atol=1e-15)
    assert rrec[-1, RAMP_ROW] == pytest.approx(RAMP_SLOPE / gain[RAMP_ROW], rel=1e-6)


def eta_eq50(theta, x1, tau, torque_scale):
    """Eq. (50) written out: θ_i on the position rows; a + b sin(c x₁ + d) + (τ/τ_scale) e sin(f x₁ + g) on the
    velocity rows, with the 7 parameters of joint i at θ[n + 7i … n + 7i + 6]."""
    n = len(x1)
    out = np.empty(2 * n)
    out[:n] = theta[:n]
    for i in range(n):
        a, b, c, d, e, f, g = theta[n + 7 * i : n + 7 * i + 7]
        out[n + i] = a + b * np.sin(c * x1[i] + d) + tau[i] / torque_scale[i] * e * np.sin(f * x1[i] + g)
    return out


def test_adaptive_residual_is_simple_minus_ripple_estimate(model, plant):
    """r(k+1) = r₂₀(k+1) − η(x̄(k), ū(k), θ̂(k)) and θ̂(k+1) = θ̂(k) + Zᵀ Γ_θ r(k+1) (eqs. (37)–(39))."""
    xs, us = plant
    ripple = RippleModel(N_JOINTS, model.torque_limit)
    theta0 = np.zeros(ripple.p)
    blocks = theta0[N_JOINTS:].reshape(N_JOINTS, 7)
    blocks[:, 1] = 1e-4                      # b: amplitude
    blocks[:, 2] = np.arange(1, 7) * 3.0     # c: spatial frequency
    blocks[:, 4] = 1e-3                      # e: torque-proportional amplitude
    blocks[:, 5] = 5.0                       # f
    est = Adaptive(ripple, 2.0 / GAMMA, theta0, step=2.0)
    obs = state_observer(model, est)
    r20 = run(state_observer(model), xs, us)
    obs.update(xs[0], np.zeros(N_JOINTS))
    moved = False
    for k in range(1, len(xs)):
        theta = est.theta.copy()
        r = obs.update(xs[k], us[k - 1]).r
        eta_hat = eta_eq50(theta, xs[k - 1][:N_JOINTS], us[k - 1], model.torque_limit)
        np.testing.assert_allclose(r, r20[k] - eta_hat, rtol=1e-9, atol=1e-12)
        Z = ripple.jacobian(theta, xs[k - 1][:N_JOINTS], us[k - 1])     # checked against finite differences below
        gamma_theta = 2.0 * np.linalg.inv(Z @ Z.T + np.diag(2.0 / GAMMA))  # eq. (39) with Q = 2 Γ_η⁻¹
        np.testing.assert_allclose(est.theta, theta + Z.T @ gamma_theta @ r, rtol=1e-9, atol=1e-12)
        moved |= not np.allclose(est.theta, theta0)
    assert moved


def test_freeze_threshold_stops_the_adaptation_after_the_first_crossing(model, plant):
    """freeze_on_detect (the digest's ch3 option): θ̂ stops at the sample whose residual crosses the threshold."""
    xs, us = plant
    ripple = RippleModel(N_JOINTS, model.torque_limit)
    est = Adaptive(ripple, 2.0 / GAMMA, None, step=2.0)
    r = run(state_observer(model), xs, us)
    k_cross = STEP_K + 1                                     # the joint-3 velocity step shows at k = 21
    threshold = np.full(2 * N_JOINTS, np.inf)
    threshold[STEP_ROW] = 0.5 * STEP_SIZE
    obs = state_observer(model, est, freeze_threshold=np.where(np.isfinite(threshold), threshold, 1e9))
    obs.update(xs[0], np.zeros(N_JOINTS))
    thetas = []
    for k in range(1, len(xs)):
        obs.update(xs[k], us[k - 1])
        thetas.append(est.theta.copy())
    assert abs(r[k_cross, STEP_ROW]) > 0.5 * STEP_SIZE and est.frozen
    assert not np.allclose(thetas[k_cross - 2], thetas[k_cross - 1])        # it still adapted at the crossing
    assert all(np.array_equal(thetas[k_cross - 1], th) for th in thetas[k_cross:])
    obs.reset()
    assert not est.frozen
    with pytest.raises(RobofdiError, match="freeze_threshold"):
        state_observer(model, est, freeze_threshold=np.ones(3))


def test_residual_does_not_depend_on_observer_gains(model, plant):
    xs, us = plant
    obs_a = state_observer(model, Recursive(GAMMA), K1=0.1, K2=0.1)
    obs_b = state_observer(model, Recursive(GAMMA), K1=np.linspace(0.2, 1.9, 6), K2=1.7)
    ra, rb, xa, xb = [], [], [], []
    for k in range(len(xs)):
        u = us[k - 1] if k else np.zeros(N_JOINTS)
        ra.append(obs_a.update(xs[k], u).r.copy())
        rb.append(obs_b.update(xs[k], u).r.copy())
        xa.append(obs_a.x_hat.copy())
        xb.append(obs_b.x_hat.copy())
    np.testing.assert_allclose(np.array(ra), np.array(rb), rtol=1e-9, atol=1e-12)
    assert np.max(np.abs(np.array(xa) - np.array(xb))) > 1e-6      # the gains do shape x̂
    # with h, B evaluated at the estimate (eq. (23) as printed) the residual is no longer gain-independent
    obs_c = state_observer(model, Recursive(GAMMA), K1=0.1, K2=0.1, eval_at="estimate")
    obs_d = state_observer(model, Recursive(GAMMA), K1=1.5, K2=1.5, eval_at="estimate")
    rc, rd = run(obs_c, xs, us), run(obs_d, xs, us)
    assert np.max(np.abs(rc - rd)) > 1e-9


def test_observer_matrices(model):
    K1, K2 = np.array([0.1, 0.3, 0.5, 0.7, 1.1, 1.9]), np.array([0.05, 0.2, 0.4, 0.6, 0.8, 1.0])
    obs = DiagnosticObserver(model, T, None, K1=K1, K2=K2)
    np.testing.assert_array_equal(obs.euler.A - obs.Ko, np.diag(obs.F))     # A − K_o = F exactly
    np.testing.assert_array_equal(obs.F, np.r_[1 - K1, 1 - K2])
    n = N_JOINTS
    np.testing.assert_array_equal(obs.euler.A, np.block([[np.eye(n), T * np.eye(n)], [np.zeros((n, n)), np.eye(n)]]))


def test_euler_model_predict_matches_nominal_dynamics(model):
    rng = np.random.default_rng(3)
    q, v, u = Q0 + 0.2 * rng.standard_normal(6), rng.standard_normal(6), 20 * rng.standard_normal(6)
    x_next = EulerArmModel(model, T).predict(np.r_[q, v], u)
    qdd = np.linalg.solve(model.mass_matrix(q), u - model.bias(q, v))
    np.testing.assert_allclose(x_next, np.r_[q + T * v, v + T * qdd], rtol=1e-10, atol=1e-12)


def test_position_only_residual_ignores_measured_velocities(model, plant):
    """velocity="backward_difference" (Sec. 5): velocities are rebuilt from positions; z1(k+1) = z1(k) + T z2(k+1)
    makes the position rows of the simple residual equal T (z2(k) − z2(k−1))."""
    xs, us = plant
    garbage = xs.copy()
    garbage[:, N_JOINTS:] = np.random.default_rng(0).normal(size=(len(xs), N_JOINTS)) * 100
    r1 = run(state_observer(model, velocity="backward_difference"), xs, us)
    r2 = run(state_observer(model, velocity="backward_difference"), garbage, us)
    np.testing.assert_array_equal(r1, r2)
    q = xs[:, :N_JOINTS]
    z2 = np.diff(q, axis=0) / T                      # z2(k) for k = 1..N, at index k − 1
    for k in range(3, len(xs)):
        np.testing.assert_allclose(r1[k, :N_JOINTS], T * (z2[k - 1] - z2[k - 2]), rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(r1[:2], 0.0)       # two samples to start


def test_measured_state_observer_is_robust_to_a_reused_input_buffer(model, plant):
    xs, us = plant
    ref = run(state_observer(model, Recursive(GAMMA)), xs, us)
    obs, ybuf, ubuf = state_observer(model, Recursive(GAMMA)), np.zeros(12), np.zeros(6)
    out = []
    for k in range(len(xs)):
        ybuf[:] = xs[k]
        ubuf[:] = us[k - 1] if k else 0.0
        out.append(obs.update(ybuf, ubuf).r.copy())
    np.testing.assert_array_equal(np.array(out), ref)


# ---------------------------------------------------------------------------------------------------------------
# Fault-only numbers of spec §7.3 through the library's estimators (torque units)
# ---------------------------------------------------------------------------------------------------------------
def stationary_actuator_run(model, observer, joint, dtau, n_steps):
    """Arm at rest at Q0; the commanded torque is ū(k) = g(Q0) − δτ(k) e_joint while the actuator delivers
    u = ū + δτ = g(Q0) (eq. (14)), so f(k) = T M̂⁻¹ δτ(k) e_joint (eq. (18)) and M̂ stays constant."""
    euler = EulerArmModel(model, T)
    g0, Minv = model.gravity(Q0), np.linalg.inv(model.mass_matrix(Q0))
    x = np.r_[Q0, np.zeros(N_JOINTS)]
    out, u_prev = [], np.zeros(N_JOINTS)
    for k in range(n_steps):
        out.append(observer.update(x, u_prev).r.copy())
        e = np.zeros(N_JOINTS)
        e[joint] = dtau(k)
        u_bar = g0 - e
        x = euler.predict(x, u_bar) + np.r_[np.zeros(N_JOINTS), T * Minv @ e]
        u_prev = u_bar
    return np.array(out)


def exp_rise(amplitude, tau, k0):
    return lambda k: amplitude * (1 - np.exp(-(k - k0) * T / tau)) if k >= k0 else 0.0


K0 = 10


def increments(amplitude, tau, n_steps, delay):
    """Closed form of the first difference of the sampled book profile A(1 − e^{−(k−K0)T/τ}), seen ``delay``
    samples late: with b = e^{−T/τ}, the j-th increment (j ≥ 1) is A(1 − b) b^{j−1}, at sample K0 + delay + j − 1."""
    b = np.exp(-T / tau)
    j = np.arange(n_steps) - (K0 + delay) + 1
    return np.where(j >= 1, amplitude * (1 - b) * b ** np.maximum(j - 1, 0), 0.0), b


def low_passed_increments(amplitude, tau, gamma, n_steps, delay):
    """Closed form of r(k) = (1 − γ) r(k−1) + (those increments), eq. (35): with a = 1 − γ,
    Σ_{i=1..j} a^{j−i} A(1 − b) b^{i−1} = A(1 − b)(a^j − b^j)/(a − b)."""
    a, b = 1 - gamma, np.exp(-T / tau)
    j = np.arange(n_steps) - (K0 + delay) + 1
    return np.where(j >= 1, amplitude * (1 - b) * (a ** np.maximum(j, 0) - b ** np.maximum(j, 0)) / (a - b), 0.0)


def test_time_delayed_torque_response_to_abrupt_actuator_fault(model):
    obs = DiagnosticObserver(model, T, TimeDelayed(), residual_space="torque")
    r = stationary_actuator_run(model, obs, 2, exp_rise(60.0, 0.002, K0), 40)
    tau3 = r[:, N_JOINTS + 2]
    # the arm stays at rest, so r_τ = (M̂/T)·T M̂⁻¹(δτ(k−1) − δτ(k−2)): the increments of the profile, two samples
    # late (δτ(K0) = 0; δτ(K0+1) − δτ(K0) = 60(1 − e⁻¹) = 37.927 enters x(K0+2), as u is ū(k−1))
    expected, _ = increments(60.0, 0.002, 40, delay=2)
    np.testing.assert_allclose(tau3, expected, rtol=1e-9, atol=1e-9)
    assert tau3.max() == pytest.approx(60 * (1 - np.exp(-1)), abs=1e-9) and int(np.argmax(tau3)) == K0 + 2
    others = np.delete(r, N_JOINTS + 2, axis=1)
    np.testing.assert_allclose(others, 0.0, atol=1e-9)           # isolates joint 3 in torque space


@pytest.mark.parametrize("gamma", [0.2, 0.3])
def test_recursive_torque_response_to_abrupt_actuator_fault(model, gamma):
    gain = np.r_[np.full(N_JOINTS, 0.01), np.full(N_JOINTS, gamma)]   # uniform on velocity rows: commutes with M̂
    obs = DiagnosticObserver(model, T, Recursive(gain), residual_space="torque")
    r = stationary_actuator_run(model, obs, 2, exp_rise(60.0, 0.002, K0), 40)
    tau3 = r[:, N_JOINTS + 2]
    np.testing.assert_allclose(tau3, low_passed_increments(60.0, 0.002, gamma, 40, delay=2), rtol=1e-9, atol=1e-9)
    # peak 2 samples after the first increment (spec: 4 ms after onset): (1 − γ)·37.927 + 13.953 > 37.927
    d1 = 60 * (1 - np.exp(-1))
    assert int(np.argmax(tau3)) == K0 + 3
    assert tau3.max() == pytest.approx((1 - gamma) * d1 + d1 * np.exp(-1), abs=1e-9)
    np.testing.assert_allclose(np.delete(r, N_JOINTS + 2, axis=1), 0.0, atol=1e-9)


@pytest.mark.parametrize("gamma, samples", [(0.2, 11), (0.3, 8)])
def test_recursive_torque_response_to_incipient_actuator_fault(model, gamma, samples):
    gain = np.r_[np.full(N_JOINTS, 0.01), np.full(N_JOINTS, gamma)]
    td = DiagnosticObserver(model, T, TimeDelayed(), residual_space="torque")
    rec = DiagnosticObserver(model, T, Recursive(gain), residual_space="torque")
    rtd = stationary_actuator_run(model, td, 4, exp_rise(40.0, 0.08, K0), 60)[:, N_JOINTS + 4]
    rrec = stationary_actuator_run(model, rec, 4, exp_rise(40.0, 0.08, K0), 60)[:, N_JOINTS + 4]
    expected_td, b = increments(40.0, 0.08, 60, delay=2)
    np.testing.assert_allclose(rtd, expected_td, rtol=1e-9, atol=1e-9)
    assert rtd.max() == pytest.approx(40 * (1 - np.exp(-0.025)), abs=1e-9)   # 0.98760 N·m: TD barely sees it
    np.testing.assert_allclose(rrec, low_passed_increments(40.0, 0.08, gamma, 60, delay=2), rtol=1e-9, atol=1e-9)
    # peak where b^j − a^j is largest (a = 1 − γ): the continuous maximiser j* = ln(ln a / ln b) / ln(b / a) is
    # 11.05 for γ = 0.2 and 8.01 for γ = 0.3, and the sampled peak at j = 11 resp. 8 (22 ms resp. 16 ms in the spec)
    assert int(np.argmax(rrec)) == K0 + 1 + samples
    assert rrec.max() > 2.5 * rtd.max()          # the low-pass gain is what makes incipient faults visible


def test_position_sensor_fault_numbers(model):
    """δx_{1,3} = 0.006(1 − e^{−(kT−t0)/0.002}) on the measured position of a resting arm (spec §7.3): the position
    row of r₂₀ is x̄₁(k) − x̄₁(k−1) − T x̄₂(k−1) = δx(k) − δx(k−1) (measured velocity 0), the time-delayed one its
    first difference, the recursive one that low-passed with γ = 0.01 (eq. (35))."""
    from scipy.signal import lfilter

    dx = exp_rise(0.006, 0.002, K0)
    g0 = model.gravity(Q0)
    obs = {name: DiagnosticObserver(model, T, est, residual_space="state")
           for name, est in (("simple", None), ("td", TimeDelayed()), ("rec", Recursive(GAMMA)))}
    out = {name: [] for name in obs}
    for k in range(60):
        y = np.r_[Q0, np.zeros(N_JOINTS)]
        y[2] += dx(k)
        for name, o in obs.items():
            out[name].append(o.update(y, g0 if k else np.zeros(N_JOINTS)).r[2])
    simple, td, rec = (np.array(out[n]) for n in ("simple", "td", "rec"))
    delta = np.array([dx(k) for k in range(60)])
    exp_simple = np.r_[0.0, np.diff(delta)]
    exp_td = np.r_[0.0, np.diff(exp_simple)]
    exp_rec = lfilter([1.0], [1.0, -(1 - GAMMA[2])], exp_td)
    np.testing.assert_allclose(simple, exp_simple, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(td, exp_td, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(rec, exp_rec, rtol=1e-9, atol=1e-12)
    # the spec's numbers: peak 0.006(1 − e⁻¹) = 3.7927 mrad, then the TD second difference 0.006(e⁻¹ − e⁻²) − 3.7927
    assert simple.max() == pytest.approx(0.0037927, abs=1e-7) and td.max() == pytest.approx(0.0037927, abs=1e-7)
    assert td[K0 + 2] == pytest.approx(-0.0023975, abs=1e-7)
    assert int(np.argmax(rec)) == K0 + 1 and rec[-1] < 0    # slow undershoot (×0.99 per step)


# ---------------------------------------------------------------------------------------------------------------
# Adaptive gain and the ripple model (spec §3.5, §7.4)
# ---------------------------------------------------------------------------------------------------------------
def test_adaptive_gain_contracts_parameter_error():
    rng = np.random.default_rng(42)
    est = Adaptive(RippleModel(N_JOINTS), 2.0 / GAMMA, step=2.0)
    lo, hi = np.inf, -np.inf
    for scale in (1e-3, 1.0, 10.0, 300.0):
        for _ in range(10):
            Z = scale * rng.standard_normal((12, 48))
            G = est.gain(Z)
            np.testing.assert_allclose(G, G.T, rtol=1e-10, atol=1e-14)
            eig = np.linalg.eigvalsh(np.eye(48) - Z.T @ G @ Z)
            lo, hi = min(lo, eig.min()), max(hi, eig.max())
    assert lo > -1.0 and hi <= 1.0 + 1e-9
    assert lo < -0.9          # factor 2 puts the strong directions near the edge
    np.testing.assert_allclose(est.gain(np.zeros((12, 48))), np.diag(GAMMA), rtol=1e-12)   # Γ_θ(0) = Γ_η


def test_ripple_model_size_and_jacobian():
    rm = RippleModel(6, torque_scale=np.array([400, 400, 250, 80, 80, 50.0]))
    assert RippleModel(6).p == 48 and rm.p == 48
    rng = np.random.default_rng(7)
    theta, x1, tau = rng.normal(size=48), rng.uniform(-2, 2, 6), rng.uniform(-100, 100, 6)
    Z = rm.jacobian(theta, x1, tau)
    assert Z.shape == (12, 48)
    h = 1e-6
    Zfd = np.column_stack([(rm.eta(theta + h * e, x1, tau) - rm.eta(theta - h * e, x1, tau)) / (2 * h)
                           for e in np.eye(48)])
    np.testing.assert_allclose(Z, Zfd, atol=1e-8)
    eta = rm.eta(theta, x1, tau)
    np.testing.assert_array_equal(eta[:6], theta[:6])
    a, b, c, d, e, f, g = theta[6:].reshape(6, 7).T
    np.testing.assert_allclose(eta[6:], a + b * np.sin(c * x1 + d) + tau / rm.torque_scale * e * np.sin(f * x1 + g))


@pytest.mark.parametrize("kwargs, field", [
    (dict(Q=-np.ones(12)), "Q"),
    (dict(Q=np.ones(11)), "Q"),
    (dict(Q=np.ones(12), step=2.5), "step"),
    (dict(Q=np.ones(12), theta0=np.zeros(47)), "theta0"),
])
def test_adaptive_rejects_bad_settings(kwargs, field):
    with pytest.raises(RobofdiError, match=field):
        Adaptive(RippleModel(6), **kwargs)


def test_recursive_rejects_unstable_gain(model):
    with pytest.raises(RobofdiError, match="gain"):
        DiagnosticObserver(model, T, Recursive(np.full(12, 2.0)))
    with pytest.raises(RobofdiError, match="gain"):
        DiagnosticObserver(model, T, Recursive(np.full(11, 0.1)))
    with pytest.raises(RobofdiError, match="K2"):
        DiagnosticObserver(model, T, None, K2=0.0)


# ---------------------------------------------------------------------------------------------------------------
# Momentum observer on a plant integrated with the nominal model
# ---------------------------------------------------------------------------------------------------------------
def rk4_plant(model, n_samples, substeps, torque_fault, fault_from):
    """Nominal dynamics integrated with RK4 at T/substeps; PD + gravity control computed at the samples and held."""
    dt = T / substeps
    q, v = Q0.copy(), np.zeros(N_JOINTS)
    ys, us = [], []
    for k in range(n_samples):
        ys.append(np.r_[q, v])
        u = model.gravity(q) + 500.0 * (Q0 - q) - 50.0 * v + np.array([10, 10, 8, 2, 2, 1.0]) * np.sin(2 * np.pi * 2 * k * T)
        us.append(u)
        tau = u + (torque_fault if k * T >= fault_from else 0.0)

        def deriv(q_, v_, tau=tau):
            return v_, model.acceleration(q_, v_, tau)

        for _ in range(substeps):
            k1q, k1v = deriv(q, v)
            k2q, k2v = deriv(q + dt / 2 * k1q, v + dt / 2 * k1v)
            k3q, k3v = deriv(q + dt / 2 * k2q, v + dt / 2 * k2v)
            k4q, k4v = deriv(q + dt * k3q, v + dt * k3v)
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return np.array(ys), np.array(us)


def test_momentum_observer_estimates_actuator_torque(model):
    dtau = np.array([0, 0, 25.0, 0, 0, 0])
    ys, us = rk4_plant(model, 300, 8, dtau, fault_from=0.1)
    obs = MomentumObserver(model, T, gain=50.0)
    r = np.array([obs.update(ys[k], us[k - 1] if k else np.zeros(6)).r for k in range(len(ys))])
    assert np.max(np.abs(r[:51])) < 0.1                     # fault-free: model == plant up to discretisation
    tail = r[-50:]
    np.testing.assert_allclose(tail[:, 2], 25.0, rtol=0.01)
    assert np.max(np.abs(np.delete(tail, 2, axis=1))) < 0.1
    # discrete first-order response from the first faulty interval (k = 50): r(50 + j) ≈ δτ (1 − (1 − K_O T)^j)
    j = np.array([1, 5, 11, 20])
    np.testing.assert_allclose(r[50 + j, 2], 25.0 * (1 - 0.9 ** j), rtol=0.02)


def test_momentum_observer_is_robust_to_a_reused_input_buffer(model):
    ys, us = rk4_plant(model, 30, 2, np.zeros(6), fault_from=1.0)
    ys = ys + np.r_[np.zeros(6), np.linspace(0.1, 0.6, 6)]     # moving arm, so consecutive samples differ
    ref_obs, buf_obs, buf = MomentumObserver(model, T), MomentumObserver(model, T), np.zeros(12)
    for k in range(len(ys)):
        u = us[k - 1] if k else np.zeros(6)
        ref = ref_obs.update(ys[k].copy(), u).r
        buf[:] = ys[k]
        got = buf_obs.update(buf, u).r
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)


def test_momentum_observer_rejects_bad_settings(model):
    with pytest.raises(RobofdiError, match="gain"):
        MomentumObserver(model, T, gain=1 / T)
    with pytest.raises(RobofdiError, match="'T'"):
        MomentumObserver(model, 0.0)


# ---------------------------------------------------------------------------------------------------------------
# Input checks: every diagnoser names the offending input
# ---------------------------------------------------------------------------------------------------------------
BAD_Y = [
    ("nan", lambda y: np.where(np.arange(12) == 3, np.nan, y)),
    ("inf", lambda y: np.where(np.arange(12) == 8, np.inf, y)),
    ("short", lambda y: y[:11]),
    ("column", lambda y: y.reshape(12, 1)),
]
BAD_U = [
    ("nan", lambda u: np.where(np.arange(6) == 0, np.nan, u)),
    ("-inf", lambda u: np.where(np.arange(6) == 5, -np.inf, u)),
    ("long", lambda u: np.r_[u, 0.0]),
]


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("space", ["state", "torque"])
@pytest.mark.parametrize("started", [False, True])
def test_bad_measurement_or_input_names_the_field(model, scheme, space, started):
    def make():
        return arm_schemes(model, ArmSchemeSettings(residual_space=space), schemes=[scheme])[scheme]

    y, u = np.r_[Q0, 0.1 * np.ones(6)], model.gravity(Q0)
    for _label, bad in BAD_Y:
        obs = make()
        if started:
            for _ in range(3):
                obs.update(y, u)
        with pytest.raises(RobofdiError, match="'y'"):
            obs.update(bad(y), u)
    for _label, bad in BAD_U:
        obs = make()
        if started:
            for _ in range(3):
                obs.update(y, u)
        with pytest.raises(RobofdiError, match="'u'"):
            obs.update(y, bad(u))


def test_adaptive_diagonal_fast_path_equals_the_printed_update():
    """With a diagonal Q the row-by-row update is eqs. (37)–(39) exactly (Z Zᵀ is diagonal for eq. (50))."""
    rng = np.random.default_rng(5)
    model = RippleModel(6, torque_scale=rng.uniform(50, 400, 6))
    theta0 = rng.normal(size=48)
    q = rng.uniform(5, 200, 12)
    fast, full = Adaptive(model, q, theta0), Adaptive(model, np.diag(q) + 1e-300 * np.eye(12)[::-1], theta0)
    assert fast._q is not None and full._q is None
    for est in (fast, full):
        est.reset(12)
    for _ in range(20):
        x, u, r = rng.normal(size=12), rng.normal(size=6) * 100, rng.normal(size=12) * 1e-3
        for est in (fast, full):
            est.prepare(x, u)
            est.update(r, r, x, u)
        np.testing.assert_allclose(fast.eta_hat, full.eta_hat, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(fast.theta, full.theta, rtol=1e-10, atol=1e-14)


def test_huge_finite_measurements_are_not_taken_for_nan():
    """The hot-path finiteness test sums the vector; a finite overflow of that sum must not count as NaN."""
    import warnings

    from robofdi.observers import check_measurement

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        np.testing.assert_array_equal(check_measurement(np.full(12, 1e308), 12, "y"), np.full(12, 1e308))
    with pytest.raises(RobofdiError, match=r"indices \[11\]"):
        check_measurement(np.r_[np.ones(11), np.inf], 12, "y")


def test_shared_measurement_is_one_read_only_copy_per_values():
    """The arm diagnosers' input check: the same values checked again under the same field give the same read-only
    copy; new values (the caller's buffer changed in place) a new copy; bad input raises as check_measurement."""
    from robofdi.observers.residual import shared_measurement

    buf = np.arange(12.0)
    a = shared_measurement(buf, 12, "y")
    assert not a.flags.writeable and a is not buf
    np.testing.assert_array_equal(a, buf)
    assert shared_measurement(buf.copy(), 12, "y") is a
    buf[3] = -1.0
    b = shared_measurement(buf, 12, "y")
    assert b is not a and b[3] == -1.0 and a[3] == 3.0
    assert shared_measurement([1.0, 2.0], 2, "u").tolist() == [1.0, 2.0]
    with pytest.raises(RobofdiError, match=r"indices \[11\]"):
        shared_measurement(np.r_[np.ones(11), np.nan], 12, "y")
    with pytest.raises(RobofdiError, match="must be a vector of 12"):
        shared_measurement(np.ones(6), 12, "y")
