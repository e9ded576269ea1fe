"""Linear plants, models, observer residuals and state feedback on a documented small example.

Example: the wheel speeds of a differential-drive robot (2 states, 2 inputs, 3 outputs). Mass M = 10 kg, yaw
inertia J = 0.5 kg·m², wheel radius ρ = 0.05 m, half track b = 0.2 m, wheel + gear inertia J_w = 0.002 kg·m², viscous
wheel friction c = 0.05 N·m·s/rad. With the wheel speeds ω = (ω_L, ω_R) and motor torques τ = (τ_L, τ_R):

    M_w ω̇ = τ − c ω,   M_w = J_w I + (M ρ²/4) [[1, 1], [1, 1]] + (J ρ²/4b²) [[1, −1], [−1, 1]]
    y = (encoder L, encoder R, gyro) = (ω_L, ω_R, ρ (ω_R − ω_L) / 2b)          [rad/s]

Sampled at T = 0.01 s. Sensor noise std 0.05, 0.05, 0.01 rad/s; process noise std 0.001 rad/s per sample; torque
limits ±2 N·m. The diagnoser's belief has 5 % seeded parameter errors (LinearMismatch(0.05, seed 0)); the controller
(LQR + Kalman predictor on the same belief) tracks wheel-speed setpoints 8 + 4 sin(0.5 t + φ) rad/s.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from robofdi import RobofdiError
from robofdi.control.linear import StateFeedback, lqr_gain
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.models.linear import LinearMismatch, LinearModel, discretize, perturbed
from robofdi.observers.linear import ObserverResidual, observer_gain_kalman, observer_gain_poles, spectral_radius
from robofdi.protocols import Simulator
from robofdi.seeding import stream
from robofdi.sims.linear import LinearPlant

T = 0.01
SENSOR_VAR = np.array([0.05, 0.05, 0.01]) ** 2
PROCESS_VAR = np.full(2, 0.001**2)
LIMIT = 2.0
BLANKING = 100                     # samples (1 s): the observers' start-up transient, skipped by calibration too
ONSET = 10.0


def wheels(E=None) -> LinearModel:
    M, J, rho, b, Jw, c = 10.0, 0.5, 0.05, 0.2, 0.002, 0.05
    Mw = Jw * np.eye(2) + M * rho**2 / 4 * np.ones((2, 2)) + J * rho**2 / (4 * b**2) * np.array([[1, -1], [-1, 1]])
    A = -np.linalg.solve(Mw, c * np.eye(2))
    B = np.linalg.inv(Mw)
    C = np.array([[1.0, 0.0], [0.0, 1.0], [-rho / (2 * b), rho / (2 * b)]])
    return LinearModel(A, B, C, E=E, state_names=["omega_L", "omega_R"], input_names=["tau_L", "tau_R"],
                       output_names=["encL", "encR", "gyro"],
                       units={"state": ["rad/s"] * 2, "u": ["N*m"] * 2, "y": ["rad/s"] * 3})


def reference(t: float) -> np.ndarray:
    return np.array([8.0 + 4.0 * np.sin(0.5 * t), 8.0 + 4.0 * np.sin(0.5 * t + 1.0)])


class Setup:
    def __init__(self, mismatch=0.05, sensor_var=SENSOR_VAR, process_var=PROCESS_VAR):
        self.plant = LinearPlant(wheels(), T, process_noise=process_var, measurement_noise=sensor_var,
                                 u_min=-LIMIT, u_max=LIMIT, system="diff-drive")
        self.belief = discretize(self.plant.nominal_model(LinearMismatch(mismatch, 0) if mismatch else None), T)
        self.L = observer_gain_kalman(self.belief, PROCESS_VAR, SENSOR_VAR)   # designed for the nominal noise
        self.K = lqr_gain(self.belief, [1.0, 1.0], [0.1, 0.1])
        self.controller = StateFeedback(self.belief, self.K, self.L, tracked=["encL", "encR"], u_min=-LIMIT, u_max=LIMIT)
        self.observer = ObserverResidual(self.belief, self.L)

    def run(self, seed, duration=20.0, fault=None, decision=None):
        """Our own loop with the ClosedLoop convention: the diagnoser gets y(k) and the input held over [k−1, k].
        fault: ("actuator" | "sensor", index, magnitude), a step at ONSET. Returns (r, estimates, isolated per sample)."""
        plant, ctrl, obs = self.plant, self.controller, self.observer
        y = plant.reset(seed=seed)
        ctrl.reset()
        obs.reset()
        if decision is not None:
            decision.reset()
        u_prev = np.zeros(2)
        rs, es, iso = [], [], []
        for k in range(int(round(duration / T)) + 1):
            t = k * T
            on = fault is not None and t >= ONSET
            y_meas = y.copy()
            if on and fault[0] == "sensor":
                y_meas[fault[1]] += fault[2]
            res = obs.update(y_meas, u_prev)
            rs.append(res.r)
            es.append(res.estimate)
            if decision is not None:
                iso.append(decision.update(res.r).isolated)
            u = ctrl.update(y_meas, reference(t))
            u_plant = u.copy()
            if on and fault[0] == "actuator":
                u_plant[fault[1]] += fault[2]
            y = plant.step(u_plant)
            u_prev = u
        return np.array(rs), np.array(es), iso


@pytest.fixture(scope="module")
def setup():
    return Setup()


@pytest.fixture(scope="module")
def calibrated(setup):
    """Thresholds from fault-free runs with seeds 1..5; signatures with gains compared in threshold units."""
    threshold = calibrate_thresholds([setup.run(seed)[0] for seed in range(1, 6)], margin=1.2, skip=BLANKING)
    signatures = setup.observer.signatures(scale=threshold)
    return threshold, signatures


def _decision(setup, calibrated):
    threshold, signatures = calibrated
    return ThresholdDecision(setup.observer.components, threshold, signatures, blanking=BLANKING)


# ---------------------------------------------------------------- models


def test_exact_discretisation_matches_scipy_cont2discrete():
    E = np.array([[1.0], [-0.5]])
    m = wheels(E=E)
    for dt in (0.001, 0.01, 0.37):
        md = discretize(m, dt)
        A, BE, C, D, _ = scipy.signal.cont2discrete((m.A, np.hstack([m.B, m.E]), m.C, np.zeros((3, 3))), dt, method="zoh")
        np.testing.assert_allclose(md.A, A, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(np.hstack([md.B, md.E]), BE, rtol=1e-11, atol=1e-14)
        np.testing.assert_array_equal(md.C, m.C)
        assert md.dt == dt and md.output_names == m.output_names and md.units == m.units
    # a discrete model passes unchanged at its own dt, and refuses another one
    md = discretize(m, 0.01)
    assert discretize(md, 0.01) is md
    with pytest.raises(RobofdiError, match="'dt' must equal the discrete model's dt=0.01"):
        discretize(md, 0.02)


def test_model_validation_names_the_field():
    m = wheels()
    with pytest.raises(RobofdiError, match="field 'B' must be a 2xany matrix, got shape \\(3, 2\\)"):
        LinearModel(m.A, np.ones((3, 2)), m.C)
    A = m.A.copy()
    A[1, 0] = np.nan
    with pytest.raises(RobofdiError, match="field 'A' must be finite, got nan at \\[1, 0\\]"):
        LinearModel(A, m.B, m.C)
    with pytest.raises(RobofdiError, match="field 'D' must be a 3x2 matrix"):
        LinearModel(m.A, m.B, m.C, D=np.zeros((2, 2)))
    with pytest.raises(RobofdiError, match="field 'output_names' must hold 3 names"):
        LinearModel(m.A, m.B, m.C, output_names=["a", "b"])
    with pytest.raises(RobofdiError, match="field 'state_names' must hold unique names, got 'w'"):
        LinearModel(m.A, m.B, m.C, state_names=["w", "w"])
    with pytest.raises(RobofdiError, match="'input_names' and 'output_names' must differ.*'y1'"):
        LinearModel(m.A, m.B, m.C, input_names=["y1", "u2"])
    with pytest.raises(RobofdiError, match="field 'units\\['y'\\]' must hold 3 unit strings"):
        LinearModel(m.A, m.B, m.C, units={"y": ["m"]})
    with pytest.raises(RobofdiError, match="field 'dt' must be None \\(continuous\\) or a sampling period > 0 s"):
        LinearModel(m.A, m.B, m.C, dt=0.0)


def test_perturbed_is_seeded_keeps_structure_and_bounds():
    m = discretize(wheels(), T)
    a, b, c = perturbed(m, 0.05, seed=3), perturbed(m, 0.05, seed=3), perturbed(m, 0.05, seed=4)
    np.testing.assert_array_equal(a.A, b.A)
    assert not np.allclose(a.A, c.A)
    assert perturbed(m, 0.0) is m
    # discrete: the errors act on A − I (≈ T·A_c), bounded by 2σ per entry; C, D, E kept
    rel = (a.A - np.eye(2)) / (m.A - np.eye(2)) - 1
    assert 0 < np.abs(rel).max() <= 0.1 + 1e-12
    assert np.abs(a.B / m.B - 1).max() <= 0.1 + 1e-12
    np.testing.assert_array_equal(a.C, m.C)
    z = LinearModel(np.array([[0.9, 0.0], [0.1, 0.8]]), np.array([[1.0], [0.0]]), np.eye(2), dt=T)
    assert perturbed(z, 0.2, seed=1).A[0, 1] == 0 and perturbed(z, 0.2, seed=1).B[1, 0] == 0
    with pytest.raises(RobofdiError, match="field 'relative' must be a relative error in \\[0, 0.5\\), got 0.7"):
        perturbed(m, 0.7)


# ---------------------------------------------------------------- plant


def test_noise_streams_are_seeded_independent_and_per_sensor():
    plant = LinearPlant(wheels(), T, process_noise=PROCESS_VAR, measurement_noise=SENSOR_VAR)
    N = 4000
    def record(seed):
        ys = [plant.reset(seed=seed)] + [plant.step(np.zeros(2)) for _ in range(N)]
        return np.array(ys), plant.state
    y1, x1 = record(7)
    y2, x2 = record(7)
    y3, _ = record(8)
    np.testing.assert_array_equal(y1, y2)
    np.testing.assert_array_equal(x1, x2)
    assert not np.allclose(y1, y3)
    # each sensor's noise is exactly its own named stream, and the process noise its own
    quiet = LinearPlant(wheels(), T, measurement_noise=SENSOR_VAR)
    yq = np.array([quiet.reset(seed=7)] + [quiet.step(np.zeros(2)) for _ in range(N)])
    for j, name in enumerate(["encL", "encR", "gyro"]):
        own = np.sqrt(SENSOR_VAR[j]) * np.random.default_rng(stream(7, "sensor", name)).standard_normal(N + 1)
        np.testing.assert_allclose(yq[:, j], own, rtol=0, atol=1e-15)
    # uncorrelated sensors, with the configured variance (N = 4001 samples: |ρ| < 4/√N ≈ 0.063)
    corr = np.corrcoef(yq.T)
    assert np.abs(corr[np.triu_indices(3, 1)]).max() < 4 / np.sqrt(N)
    np.testing.assert_allclose(yq.std(axis=0), np.sqrt(SENSOR_VAR), rtol=0.05)
    # the process noise moves the state: x(1) = G w(0), w from stream(seed, "process")
    plant.reset(seed=7)
    plant.step(np.zeros(2))
    w = np.sqrt(PROCESS_VAR) * np.random.default_rng(stream(7, "process")).standard_normal(2)
    np.testing.assert_allclose(plant.state, w, atol=1e-15)


def test_saturation_and_state_update():
    plant = LinearPlant(wheels(), T, u_min=[-1.0, -2.0], u_max=[1.0, 0.5], x0=[1.0, -1.0])
    md = plant.discrete_model
    y0 = plant.reset()
    np.testing.assert_allclose(y0, md.C @ [1.0, -1.0])
    y = plant.step([5.0, -7.0])
    np.testing.assert_array_equal(plant.u_applied, [1.0, -2.0])
    np.testing.assert_allclose(plant.state, md.A @ [1.0, -1.0] + md.B @ [1.0, -2.0], rtol=1e-14)
    np.testing.assert_allclose(y, md.C @ plant.state, rtol=1e-14)     # y at the end of the period, on the new state
    np.testing.assert_array_equal(plant.saturate([0.3, 3.0]), [0.3, 0.5])
    assert plant.time == pytest.approx(T) and plant.physics_dt == T
    assert plant.actuators == ["tau_L", "tau_R"] and plant.sensor_channels == ["encL", "encR", "gyro"]
    assert plant.units["y"] == ["rad/s"] * 3 and plant.components == [] and plant.component_kinds == {}
    assert isinstance(plant, Simulator)


def test_plant_errors_name_the_field():
    with pytest.raises(RobofdiError, match="input 'u' must be finite, got nan for 'tau_R'"):
        LinearPlant(wheels(), T).step([0.0, np.nan])
    with pytest.raises(RobofdiError, match="input 'u' must be a vector of 2 values"):
        LinearPlant(wheels(), T).step([0.0])
    with pytest.raises(RobofdiError, match="'control_dt' must equal the discrete model's dt=0.01 s, got 0.02"):
        LinearPlant(discretize(wheels(), T), 0.02)
    with pytest.raises(RobofdiError, match="field 'measurement_noise' must be a 3x3 covariance or 3 variances"):
        LinearPlant(wheels(), T, measurement_noise=[1.0, 1.0])
    with pytest.raises(RobofdiError, match="field 'process_noise' must be positive semi-definite"):
        LinearPlant(wheels(), T, process_noise=[1.0, -1.0])
    with pytest.raises(RobofdiError, match="'u_min' must be <= u_max for input 'tau_L'"):
        LinearPlant(wheels(), T, u_min=[1.0, 0.0], u_max=[0.0, 1.0])
    with pytest.raises(RobofdiError, match="field 'initial_state' must be a finite vector of 2 values"):
        LinearPlant(wheels(), T).reset([0.0, np.inf])
    with pytest.raises(RobofdiError, match="linear plant has no components"):
        LinearPlant(wheels(), T).apply_component_fault("damage", "omega_L", 0.1)
    LinearPlant(wheels(), T).apply_component_fault("damage", "omega_L", 0.0)   # restoring is a no-op


# ---------------------------------------------------------------- design functions


def test_observer_gains_place_poles_and_solve_the_kalman_riccati_equation():
    md = discretize(wheels(), T)
    L = observer_gain_poles(md, [0.5, 0.6])
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(md.A - L @ md.C).real), [0.5, 0.6], atol=1e-9)
    L = observer_gain_kalman(md, PROCESS_VAR, SENSOR_VAR)
    P = np.eye(2)                                       # the Riccati recursion converges to the same predictor gain
    Q, R, A, C = np.diag(PROCESS_VAR), np.diag(SENSOR_VAR), md.A, md.C
    for _ in range(5000):
        Lk = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
        P = A @ P @ A.T + Q - Lk @ (C @ P @ C.T + R) @ Lk.T
    np.testing.assert_allclose(L, Lk, rtol=1e-6)
    assert spectral_radius(A - L @ C) < 1


def test_non_detectable_or_non_stabilizable_designs_raise():
    # mode 1.1 is invisible to the output: not detectable
    m = LinearModel(np.diag([1.1, 0.5]), np.eye(2), np.array([[0.0, 1.0]]), dt=T)
    for design in (lambda: observer_gain_kalman(m, [1.0, 1.0], [1.0]), lambda: observer_gain_poles(m, [0.1, 0.2])):
        with pytest.raises(RobofdiError, match="\\(A, C\\) is not detectable: mode λ=1.1 \\(|λ|=1.1\\) unobservable"):
            design()
    # a stable unobservable mode is detectable (Kalman works) but cannot be placed
    m = LinearModel(np.diag([0.9, 0.5]), np.eye(2), np.array([[0.0, 1.0]]), dt=T)
    assert observer_gain_kalman(m, [1.0, 1.0], [1.0]).shape == (2, 1)
    with pytest.raises(RobofdiError, match="\\(A, C\\) is not observable: mode λ=0.9"):
        observer_gain_poles(m, [0.1, 0.2])
    m = LinearModel(np.diag([1.2, 0.5]), np.array([[0.0], [1.0]]), np.eye(2), dt=T)
    with pytest.raises(RobofdiError, match="\\(A, B\\) is not stabilizable: mode λ=1.2"):
        lqr_gain(m, [1.0, 1.0], [1.0])
    with pytest.raises(RobofdiError, match="field 'model' must be discrete"):
        observer_gain_kalman(wheels(), PROCESS_VAR, SENSOR_VAR)
    with pytest.raises(RobofdiError, match="field 'poles' must lie inside the unit circle"):
        observer_gain_poles(discretize(wheels(), T), [0.5, 1.0])


def test_state_feedback_tracks_the_setpoints_on_the_nominal_plant():
    s = Setup(mismatch=0.0)
    plant, ctrl = s.plant, s.controller
    assert spectral_radius(s.belief.A - s.belief.B @ s.K) < 1
    y = plant.reset(seed=1)
    ctrl.reset()
    for _ in range(1500):
        y = plant.step(ctrl.update(y, np.array([6.0, 9.0])))
    np.testing.assert_allclose(plant.state, [6.0, 9.0], atol=0.05)
    with pytest.raises(RobofdiError, match="input 'reference' must be 2 finite setpoints for \\['encL', 'encR'\\]"):
        ctrl.update(y, [1.0, 2.0, 3.0])


# ---------------------------------------------------------------- observer residual


def test_observer_residual_protocol_and_input_checks(setup):
    obs = setup.observer
    assert obs.inputs == ["tau_L", "tau_R"] and obs.measurements == obs.components == ["encL", "encR", "gyro"]
    assert obs.estimate_components == ["tau_L", "tau_R", "encL", "encR", "gyro"]
    assert obs.estimate_modes == ["level"] * 5
    assert obs.units == {"residual": ["rad/s"] * 3, "estimate": ["N*m", "N*m", "rad/s", "rad/s", "rad/s"]}
    obs.reset()
    first = obs.update([1.0, 2.0, 0.1], [0.0, 0.0])           # the first call only initialises
    np.testing.assert_array_equal(first.r, np.zeros(3))
    with pytest.raises(RobofdiError, match="diagnoser input 'y' has non-finite values at indices \\[2\\]"):
        obs.update([1.0, 2.0, np.nan], [0.0, 0.0])
    with pytest.raises(RobofdiError, match="diagnoser input 'u' must be a vector of 2 values"):
        obs.update([1.0, 2.0, 0.1], [0.0])
    with pytest.raises(RobofdiError, match="field 'L' must be a finite 2x3 matrix"):
        ObserverResidual(setup.belief, np.zeros((3, 2)))
    with pytest.raises(RobofdiError, match="the observer A − L C is not stable"):
        ObserverResidual(setup.belief, np.vstack([[300.0, 0, 0], [0, 300.0, 0]]))


def test_signatures_from_dc_gains_are_isolable(setup, calibrated):
    _, signatures = calibrated
    got = {s.fault: (set(s.required), set(s.allowed)) for s in signatures}
    assert got["tau_L"][0] == {"encL", "gyro"} and got["tau_R"][0] == {"encR", "gyro"}
    assert got["encL"][0] == {"encL"} and got["encR"][0] == {"encR"} and got["gyro"][0] == {"gyro"}
    threshold = calibrated[0]
    assert setup.observer.ambiguity_groups(scale=threshold) == []
    # in raw rad/s (no scale) the gyro's weak DC gain drops out of the actuator signatures: τ_L and encL collide
    assert ("tau_L", "encL") in setup.observer.ambiguity_groups()


def test_fault_free_residual_stays_below_thresholds_from_other_seeds(setup, calibrated):
    threshold, _ = calibrated
    for seed in (10, 11, 12):                        # calibration used seeds 1..5
        r = setup.run(seed)[0]
        assert np.abs(r[BLANKING:]).max(axis=0).max() > 0
        assert np.all(np.abs(r[BLANKING:]) < threshold), (seed, np.abs(r[BLANKING:]).max(axis=0) / threshold)


@pytest.mark.parametrize("index, magnitude", [(0, 0.15), (1, -0.15)])
def test_actuator_bias_is_detected_after_onset_and_never_before(setup, calibrated, index, magnitude):
    threshold, _ = calibrated
    decision = _decision(setup, calibrated)
    r, est, iso = setup.run(20, fault=("actuator", index, magnitude), decision=decision)
    alarm = np.abs(r) > threshold
    alarm[:BLANKING] = False
    k_onset = int(round(ONSET / T))
    assert not alarm[:k_onset + 1].any()             # the first sample affected by the fault is k_onset + 1
    delay = (np.flatnonzero(alarm.any(axis=1))[0] - k_onset) * T
    assert 0 < delay <= 0.2
    target = setup.observer.inputs[index]
    assert target in iso[-1]                          # eventually isolated (see the module notes on the race)
    h = setup.observer.estimate_components.index(target)
    assert est[-500:, h].mean() == pytest.approx(magnitude, rel=0.2)   # 5 % model error biases the estimate


@pytest.mark.parametrize("index, magnitude", [(0, 1.0), (1, -1.5), (2, 0.3)])
def test_sensor_bias_is_isolated_to_its_output(setup, calibrated, index, magnitude):
    decision = _decision(setup, calibrated)
    _, _, iso = setup.run(21, fault=("sensor", index, magnitude), decision=decision)
    k_onset = int(round(ONSET / T))
    assert not any(iso[:k_onset])                     # the sample at the onset is the first one biased
    first = next(s for s in iso if s)
    assert first == (setup.observer.components[index],)


def test_actuator_estimate_is_exact_in_steady_state_on_the_nominal_model():
    s = Setup(mismatch=0.0, sensor_var=np.zeros(3), process_var=np.zeros(2))
    for index, magnitude in ((0, 0.2), (1, -0.3)):
        _, est, _ = s.run(0, duration=30.0, fault=("actuator", index, magnitude))
        h = s.observer.estimate_components.index(s.observer.inputs[index])
        assert est[-1, h] == pytest.approx(magnitude, rel=1e-3)


# ---------------------------------------------------------------- the shared closed loop


def test_closed_loop_sensor_bias_detected_isolated_no_false_alarm(tmp_path):
    """LinearPlant + StateFeedback + ObserverResidual + ThresholdDecision through robofdi.loop.ClosedLoop with a
    robofdi.faults.Fault; the record is written, read back and summarised."""
    from robofdi.evaluate import summarize
    from robofdi.faults import Fault
    from robofdi.loop import ClosedLoop, Diagnosis
    from robofdi.record import load

    s = Setup()

    def loop(faults=(), decision=None):
        return ClosedLoop(s.plant, s.controller, reference, faults=faults,
                          diagnoses={"observer": Diagnosis(s.observer, decision)},
                          reference_columns=["encL_setpoint", "encR_setpoint"], reference_units=["rad/s", "rad/s"])

    residuals = []
    for seed in (1, 2, 3):                            # calibration runs: their own run key, never the test's noise
        s.controller.reset()                          # ClosedLoop resets diagnosers, not the controller
        rec = loop().run(20.0, seed=seed, run_key="calibration")
        residuals.append(rec.diagnosers["observer"].residual)
    threshold = calibrate_thresholds(residuals, margin=1.2, skip=BLANKING)
    decision = ThresholdDecision(s.observer.components, threshold, s.observer.signatures(scale=threshold),
                                 blanking=BLANKING)
    fault = Fault(name="encR_bias", kind="sensor_bias", target="encR", onset=ONSET, magnitude=-1.5)
    s.controller.reset()
    rec = loop([fault], decision).run(20.0, seed=0, scenario="diff-drive-sensor")
    back = load(rec.save(tmp_path / "run.h5"))
    assert back.system == "diff-drive" and back.units["signals/y_meas"] == ["rad/s"] * 3
    summary = summarize(back, "linear-sensor-bias")
    d = summary["diagnosers"]["observer"]
    assert d["false_alarms"] == 0 and d["missed_detections"] == 0
    detection = d["detections"][0]
    assert detection["isolated"] == "encR" and d["isolation_correct"]["encR_bias"]
    assert 0 <= detection["delay"] <= 0.05
    assert d["estimate_rmse"]["encR_bias"] < 0.75       # 5 % model error biases the level estimate (0.48 rad/s here)
