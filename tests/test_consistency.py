"""The consistency residual (issue 10 building blocks) on the real MuJoCo arm with the honest harness:
friction identified from fault-free runs, operating-point bounds, kinematic sensor consistency."""
from dataclasses import replace

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.config import evolve
from robofdi.control import Quintic
from robofdi.decision import ThresholdDecision
from robofdi.faults.spec import parse_fault_spec
from robofdi.loop import Diagnosis, diagnose_record, diagnoser_inputs
from robofdi.models.friction import JointFriction
from robofdi.observers.arm_schemes import ArmSchemeSettings, scheme_calibration
from robofdi.observers.consistency import (
    Q_BEFORE, Q_LAST, STEP_HOLD, STEPPED, ConsistencyDesign, ConsistencyResidual, _step_rows, design_consistency,
    gain_rows,
)
from robofdi.observers.kinematic import (
    NOISE_WALK_SIGMAS, WINDOWS, KinematicConsistency, design_window_scales, identify_noise_walk, identify_ripple,
    identify_skew, kinematic_increments, ripple_orders,
)
from robofdi.systems.arm import arm_scenario, calibration, calibration_records, run_scenario

SKIP = 5


@pytest.fixture(scope="module")
def designed():
    """arm6 (seed 0): design on the calibration suite, as the scheme's calibration does."""
    base = arm_scenario("arm6.xml", faults=["actuator_additive:joint1:1@0.5"], seed=0, schemes=("momentum",))
    sim = base.simulator()
    model = base.nominal_model(sim)
    rates = base.loop_rates(sim)
    records = calibration_records(replace(base, faults=()))
    runs = [diagnoser_inputs(r, rates) for r in records.values()]
    design = design_consistency(model, runs, 1.0 / rates.diagnosis_hz, skip=SKIP,
                                ripple_orders=ripple_orders(model.gear_ratio))
    return base, sim, model, rates, runs, design


MARGIN = 2.0   # the bound's margin for motions the design never saw


def _trace(record, model, design, rates, confirm=0, evidence=False, overturn=0):
    """The scheme with a uniform threshold of MARGIN (and the first alarm isolated at once unless ``confirm``);
    with ``evidence``, its discriminating rows count as evidence from their design maximum (1), as calibrated;
    ``overturn``: the decision's (0: a later alarm never overturns)."""
    d = ConsistencyResidual(model, design)
    threshold = np.full(len(d.components), MARGIN)
    levels = np.where(np.isin(d.components, d.discriminating), 1.0, MARGIN) if evidence else None
    decision = ThresholdDecision(d.components, threshold, d.signatures(), blanking=SKIP, confirm=confirm,
                                 evidence=levels, overturn=overturn)
    return diagnose_record(record, Diagnosis(d, decision), rates)


def _first_isolation(tr):
    k = next((k for k, iso in enumerate(tr.isolated) if iso), None)
    return (None, None) if k is None else (tr.time[k], tr.isolated[k])


def test_identified_coulomb_friction_matches_the_drive(designed):
    _, sim, _, _, _, design = designed
    # the plant's Coulomb friction is the MJCF's frictionloss; the diagnoser never read it
    truth = sim.model.dof_frictionloss[[sim.model.jnt_dofadr[sim.model.joint(j).id] for j in sim.joint_names]]
    np.testing.assert_allclose(design.friction.coulomb, truth, rtol=0.10)


def test_identified_skew_is_what_the_integration_implies_on_every_joint(designed):
    """MuJoCo's semi-implicit Euler step of h moves q by h·q̇_{j+1}: against the trapezoid that is a skew of h/2
    (kinematic.identify_skew). Least squares on e regressed on the noisy Δq̇ is biased towards 0 (0.14–0.2 ms on
    the slow calibration motions); the instrumental-variable estimate must be within 10 % on every joint on this
    two-motion suite (measured: 2 % on the full ten-motion suite of the consistency scheme) and nearer than it."""
    _, sim, _, _, runs, design = designed
    truth = sim.physics_dt / 2
    np.testing.assert_allclose(design.skew, truth, rtol=0.10)
    n = sim.n
    e = [kinematic_increments(Y[:, :n], Y[:, n:], design.T)[SKIP:] for Y, _ in runs]
    dv = [np.diff(Y[:, n:], axis=0)[SKIP - 1:] for Y, _ in runs]
    least_squares = sum((a * b).sum(0) for a, b in zip(e, dv)) / sum((b * b).sum(0) for b in dv)
    assert np.abs(design.skew - truth).max() < np.abs(least_squares - truth).max()


def test_scales_widen_outside_the_designed_envelope_instead_of_extrapolating(designed):
    """With the designed reach halved, the fastest calibration motion is outside it: those samples are counted
    and their ratios only shrink (the tolerance widens); inside the reach nothing changes."""
    _, _, model, _, runs, design = designed
    n = model.n
    Y = max(runs, key=lambda r: np.abs(r[0][:, n:]).max())[0]
    full = KinematicConsistency(design.T, design.skew, design.window_scales, design.windows, design.reach)
    half = KinematicConsistency(design.T, design.skew, design.window_scales, design.windows, design.reach / 2)
    a = np.array([full.update(y[:n], y[n:])[0] for y in Y])
    b = np.array([half.update(y[:n], y[n:])[0] for y in Y])
    assert full.outside_samples.sum() == 0 and half.outside_samples.sum() > 0
    assert np.all(b <= a + 1e-12) and np.any(b < a - 1e-9)


#: arm6's wrist speed [rad/s] at which its ripple fundamental 6G|q̇|/2π (G = 60) is the 500 Hz diagnosis rate
ALIAS = 2 * np.pi * 500 / (6 * 60)


def _wrist_run(base, peak):
    """The diagnoser's (Y, U) of arm6 moving its wrist alone on a 1 s quintic that peaks at ``peak`` [rad/s]."""
    q0 = (np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, -2.4)
    sc = replace(base, motion=Quintic(q0, (0, 0, 0, 0, 0, peak / 1.875), 1.0), faults=(), duration=1.1)
    return diagnoser_inputs(run_scenario(sc, calibration(sc)[0]), base.loop_rates(base.simulator()))


def test_an_aliased_ripple_is_identified_and_its_coherent_sum_covered(designed):
    """The wrist cruising where its ripple fundamental aliases to 0 Hz: the trapezoid integrates the sampled
    ripple as a velocity bias and the kinematic row leaves its bound (the plant effect is outside the design).
    The amplitude identified from another run, one that only passes the alias, brings it back inside the margin of
    unseen motions (measured: 5.0 → 1.35 of a design from normal-speed motions); it only ever widens."""
    base, _, model, _, _, design = designed
    n = model.n
    sweep, _ = _wrist_run(base, 1.3 * ALIAS)        # passes the alias twice, dwells above it
    cruise, _ = _wrist_run(base, ALIAS)             # its peak dwells on it
    assert np.abs(cruise[:, 2 * n - 1]).max() == pytest.approx(ALIAS, rel=0.03)
    orders = ripple_orders(model.gear_ratio)
    ripple, _ = identify_ripple([sweep[:, :n]], [sweep[:, n:]], design.T, design.skew, orders, SKIP)
    # the fundamental (1 % of the torque limit, 2 % of the load torque in the plant) dominates its harmonics
    assert ripple[5, 0] > 1e-6 and ripple[5, 0] > 2 * ripple[5, 1:3].max()
    plain = KinematicConsistency(design.T, design.skew, design.window_scales, design.windows)
    guarded = KinematicConsistency(design.T, design.skew, design.window_scales, design.windows, None, orders, ripple)
    a = np.array([plain.update(y[:n], y[n:])[0] for y in cruise])[SKIP:]
    b = np.array([guarded.update(y[:n], y[n:])[0] for y in cruise])[SKIP:]
    assert a[:, 5].max() > 2 * MARGIN and b[:, 5].max() < MARGIN, (a[:, 5].max(), b[:, 5].max())
    assert np.all(b <= a + 1e-12)
    np.testing.assert_array_equal(a[:, :5], b[:, :5])       # the joints at rest never come near an alias


def test_the_design_covers_its_runs_and_its_cache_round_trip(designed):
    _, _, model, _, runs, design = designed
    again = ConsistencyDesign.from_arrays(design.arrays())
    np.testing.assert_array_equal(again.ripple_amplitude, design.ripple_amplitude)
    assert (again.ripple_load is None) == (design.ripple_load is None)
    if design.ripple_load is not None:
        np.testing.assert_array_equal(again.ripple_load, design.ripple_load)
    for Y, U in runs[:1]:
        d, e = ConsistencyResidual(model, design), ConsistencyResidual(model, again)
        z = np.array([d.update(y, u).r for y, u in zip(Y, U)])
        z2 = np.array([e.update(y, u).r for y, u in zip(Y, U)])
        np.testing.assert_array_equal(z, z2)
        assert np.abs(z[SKIP:]).max() <= 1.0 + 1e-6


def test_unseen_fault_free_motion_stays_inside_twice_the_bound(designed):
    base, _, model, rates, _, design = designed
    sc = arm_scenario("arm6.xml", faults=["actuator_additive:joint1:1@0.5"], seed=0, schemes=("momentum",))
    sc = replace(sc, motion=arm_scenario("arm6.xml", faults=["actuator_additive:joint1:1@0.5"], seed=7).motion,
                 faults=())
    rec = run_scenario(sc, calibration(sc)[0])
    z = np.abs(_trace(rec, model, design, rates).residual[SKIP:])
    assert z.max() < 2.0, z.max(axis=0)


def test_actuator_step_raises_its_joint_only_and_no_sensor_row(designed):
    base, _, model, rates, _, design = designed
    sc = arm_scenario("arm6.xml", faults=["actuator_additive:joint3:60@1.0"], seed=3, schemes=("momentum",))
    tr = _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates)
    n, t = model.n, tr.time
    z = np.abs(tr.residual)
    before, after = t < 1.0, (t >= 1.0) & (t < 1.2)
    assert z[before & (t > SKIP * 0.002)].max() < 2.0
    first = t[after][np.argmax(z[after, 2] > 2.0)]
    assert z[after, 2].max() > 2.0 and first - 1.0 <= 0.012          # within 6 samples of 2 ms
    assert z[after, n:2 * n].max() < 2.0                             # kinematic rows: actuator faults cannot raise them
    assert _first_isolation(tr)[1] == "joint3"
    np.testing.assert_allclose(tr.estimate[(t > 1.15) & (t < 1.2), 2].mean(), 60.0, rtol=0.15)
    assert z[after, 3 * n].max() < 0.5                               # one joint's torque is not a payload


def test_a_payload_change_is_isolated_as_the_payload_and_its_mass_estimated(designed):
    """5 kg added at the payload point at 1 s (the plant's component_mass fault): the dynamic rows of the joints
    it loads alarm, the payload row names it, and the least-squares mass is within 15 % of 5 kg; nothing alarms
    before."""
    _, _, model, rates, _, design = designed
    sc = arm_scenario("arm6.xml", faults=["component_mass:payload:5@1.0"], seed=3, schemes=("momentum",), duration=1.6)
    tr = _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates, confirm=ArmSchemeSettings().consistency_confirm)
    n, t = model.n, tr.time
    z = np.abs(tr.residual)
    assert z[(t > SKIP * 0.002) & (t < 1.0)].max() < MARGIN
    time, got = _first_isolation(tr)
    assert got == "payload" and time - 1.0 < 0.1, (time, got)
    np.testing.assert_allclose(np.median(tr.estimate[(t > 1.2) & (t < 1.6), 3 * n]), 5.0, rtol=0.15)


def test_position_sensor_bias_raises_its_kinematic_row(designed):
    base, _, model, rates, _, design = designed
    sc = arm_scenario("arm6.xml", faults=["sensor_bias:joint2_pos:0.001@1.0"], seed=4, schemes=("momentum",))
    tr = _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates)
    n, t = model.n, tr.time
    z = np.abs(tr.residual)
    after = (t >= 1.0) & (t < 1.05)
    assert z[after, n + 1].max() > 2.0
    assert t[after][np.argmax(z[after, n + 1] > 2.0)] - 1.0 <= 0.0021
    assert np.delete(z[after, n:], 1, axis=1).max() < 2.0
    time, isolated = _first_isolation(tr)
    assert isolated == "joint2_pos" and time - 1.0 <= 0.0021
    np.testing.assert_allclose(tr.estimate[t > 1.1, tr.estimate_components.index("joint2_pos")].mean(), 1e-3, rtol=0.1)


@pytest.mark.parametrize("fault, isolated", [("sensor_bias:joint5_vel:0.05@1.0", "joint5_vel"),
                                             ("sensor_drift:joint5_pos:-0.05@1.0", "joint5_pos"),
                                             ("sensor_bias:joint3_pos:0.05@1.0", "joint3_pos"),
                                             ("sensor_bias:joint6_pos:4e-5@1.0", "joint6_pos")])
def test_velocity_bias_and_encoder_drift_are_told_apart_by_the_step_row(designed, fault, isolated):
    """Kinematically identical (both add −T·0.05 rad to every e_k); only the velocity step has no torque behind it.
    A 50 mrad encoder step on the moving elbow moves M(q)q̇ at once (ν reaches 2.5× the margin when every sample
    counts), but its kinematic increment is far more than a velocity step of that ν makes, so it is not counted.
    A 40 µrad (7-count) encoder step shows only in the single-sample kinematic term; that sample is held in the
    kinematic row, so the step persists into the scheme's confirmation window and is isolated."""
    _, _, model, rates, _, design = designed
    sc = arm_scenario("arm6.xml", faults=[fault], seed=5, schemes=("momentum",))
    tr = _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates,
                confirm=ArmSchemeSettings().consistency_confirm, evidence=True)
    n, t = model.n, tr.time
    j = int(isolated[5]) - 1
    step = np.abs(tr.residual[:, 2 * n + j])
    assert step[(t > SKIP * 0.002) & (t < 1.0)].max() < 2.0
    if isolated.endswith("_vel"):       # ν = b on its own joint: 0.05 rad/s against ≈ 0.01 fault-free
        q, v = (np.asarray(x) for x in sc.motion(1.0)[:2])
        bound = design.step_bound(v, design.spread(model.mass_matrix(q)))[j]
        assert step[(t >= 1.0) & (t < 1.01)].max() * bound == pytest.approx(0.05, rel=0.25)
        # the onset's ν stays held: the increment −T·b that persists after it is a velocity offset, no position step
        held = step[(t >= 1.0) & (t < 1.0 + STEP_HOLD - 0.01)]
        assert np.all(held[int(np.argmax(held)):] == held.max())
    else:
        assert step[t >= 1.0].max() < 2.0
    time, got = _first_isolation(tr)
    assert got == isolated and time - 1.0 < 0.1


def test_a_velocity_step_below_the_step_alarm_is_isolated_from_its_evidence(designed):
    """A velocity bias of 1.3× the fault-free bound of ν at the joint's speed (ν at onset is b plus noise; the
    increments' agreement T b over twice the single-sample scale is 1.7): its step row stays below the alarm
    threshold (2), so without evidence levels only the kinematic row speaks and it is called an encoder drift;
    counted as evidence from the fault-free bound (1) once the kinematic row has alarmed, it is the velocity
    sensor. (At 1.8× the agreement alone crosses 2: the step row detects it.)"""
    _, _, model, rates, _, design = designed
    motion = arm_scenario("arm6.xml", seed=5, schemes=("momentum",)).motion
    q, v = (np.asarray(x) for x in motion(1.0)[:2])
    b = 1.3 * design.step_bound(v, design.spread(model.mass_matrix(q)))[4]     # the bound at the planned pose
    sc = arm_scenario("arm6.xml", faults=[f"sensor_bias:joint5_vel:{b}@1.0"], seed=5, schemes=("momentum",))
    rec = run_scenario(sc, calibration(sc)[0])
    confirm = ArmSchemeSettings().consistency_confirm
    graded, plain = (_trace(rec, model, design, rates, confirm, evidence) for evidence in (True, False))
    n, t = model.n, graded.time
    step = np.abs(graded.residual[:, 2 * n + 4])
    assert 1.0 < step[(t >= 1.0) & (t < 1.01)].max() < MARGIN
    assert _first_isolation(plain)[1] == "joint5_pos"
    time, got = _first_isolation(graded)
    assert got == "joint5_vel" and time - 1.0 < 0.02
    assert graded.isolated[-1] == "joint5_vel"       # the encoder hypothesis is not added once ν has decayed


@pytest.mark.parametrize("channel, isolated", [("vel", "joint6_vel"), ("pos", "joint6_pos")])
def test_a_velocity_step_below_the_step_bound_is_told_from_an_encoder_drift_by_agreement(designed, channel,
                                                                                       isolated):
    """A wrist velocity bias at 0.75× the fault-free bound of ν at its speed, so ν alone is no evidence; its −T b
    over two samples is 1.4× twice the single-sample kinematic scale, and ν at the step agrees with it: the step
    row holds the agreement (> 1, the evidence level) and the velocity sensor is named. An encoder drift with
    the kinematic signature of a velocity bias of twice the bound makes no ν: it stays an encoder fault. (The
    choice is the nearer hypothesis, so near ν's noise it errs both ways: with the wrist's ν spread of about a
    quarter of its bound, a drift of 0.75× the bound is called a velocity fault with a probability of ≈ 7 %.)"""
    _, _, model, rates, _, design = designed
    motion = arm_scenario("arm6.xml", seed=5, schemes=("momentum",)).motion
    q, v = (np.asarray(x) for x in motion(1.0)[:2])
    bound = design.step_bound(v, design.spread(model.mass_matrix(q)))[5]          # at the planned pose
    single = design.window_scales[5, int(np.argmin(design.windows)), 0]
    b = 0.75 * bound
    assert design.T * b > 2.4 * single      # the precondition of the agreement, with room for noise
    fault = f"sensor_bias:joint6_vel:{b}@1.0" if channel == "vel" else f"sensor_drift:joint6_pos:{-2 * bound}@1.0"
    sc = arm_scenario("arm6.xml", faults=[fault], seed=5, schemes=("momentum",))
    tr = _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates,
                confirm=ArmSchemeSettings().consistency_confirm, evidence=True)
    n, t = model.n, tr.time
    step = np.abs(tr.residual[:, 2 * n + 5])
    assert step[(t > SKIP * 0.002) & (t < 1.0)].max() < 1.0
    if channel == "vel":
        assert step[(t >= 1.0) & (t < 1.01)].max() == pytest.approx(design.T * b / (2 * single), rel=0.3)
    else:
        assert step[(t >= 1.0) & (t < 1.2)].max() < 1.0
    time, got = _first_isolation(tr)
    assert got == isolated and time - 1.0 < 0.1


def _joint3_move(designed, fault, duration, start):
    """The consistency trace (the scheme's own confirmation, evidence and overturn) of a 2.6 s arm run with
    ``fault``, in which joint 3 moves by 1 rad over ``duration`` s from ``start`` s and the others rest."""
    base, _, model, rates, _, design = designed
    q0 = (np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, -2.4)
    sc = replace(base, motion=Quintic(q0, (0, 0, 1.0, 0, 0, 0), duration, start=start),
                 faults=(parse_fault_spec(fault),), duration=2.6)
    rule = scheme_calibration("consistency")
    return _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates, rule.confirm, True, rule.overturn)


@pytest.mark.parametrize("fault, isolated", [("sensor_scale:joint3_vel:0.15@0.4", "joint3_vel"),
                                             ("sensor_scale:joint3_vel:-0.08@0.4", "joint3_vel"),
                                             ("sensor_drift:joint3_pos:0.005@0.4", "joint3_pos"),
                                             ("sensor_drift:joint3_pos:0.0005@0.9", "joint3_pos"),
                                             ("sensor_noise:joint3_pos:0.004@0.4", "joint3_pos"),
                                             ("sensor_scale:joint3_pos:0.15@0.4", "joint3_pos"),
                                             ("sensor_scale:joint3_pos:-0.03@0.4", "joint3_pos")])
def test_a_velocity_gain_error_that_starts_at_rest_is_named_from_the_motion_that_follows(designed, fault, isolated):
    """A gain error set while its joint rests has no step at onset; once the joint moves (at 0.8 s), the increments
    follow the velocity, which no encoder drift does — also one that starts as the joint accelerates (0.9 s), nor a
    noisy encoder. The first call is the encoder (nothing else has spoken yet); the gain evidence overturns it
    within the run. An encoder's gain error makes the same increments once the joint moves, but it stepped the
    reading by g·q at its onset (joint 3 rests at π/6: 78 and 16 mrad), which a velocity sensor cannot: it stays
    the encoder."""
    tr = _joint3_move(designed, fault, 1.5, 0.8)
    t = tr.time
    assert np.abs(tr.residual[(t > SKIP * 0.002) & (t < 0.4)]).max() < 1.0
    time, got = _first_isolation(tr)
    assert tr.isolated[-1] == isolated and time < 1.5, (time, got, tr.isolated[-1])


@pytest.mark.parametrize("fault, isolated", [("sensor_drift:joint3_vel:0.05@0.5", "joint3_vel"),
                                             ("sensor_drift:joint3_vel:-0.02@0.5", "joint3_vel"),
                                             ("sensor_drift:joint3_pos:0.002@0.5", "joint3_pos"),
                                             ("sensor_bias:joint3_pos:0.003@0.5~exponential_rise(0.5)", "joint3_pos")])
def test_a_velocity_drift_is_named_from_increments_that_grow(designed, fault, isolated):
    """A velocity reading that drifts by d rad/s² has no step at onset, and its kinematic row alarms like an
    encoder's, which the first call names; its increments −T d (t − t₀) then grow steadily away from zero, which
    an encoder drift's (constant) and an encoder offset that rises to its value (falling) do not: the trend
    evidence overturns the call within the run, and only for the velocity sensor."""
    tr = _joint3_move(designed, fault, 2.0, 0.2)
    t = tr.time
    assert np.abs(tr.residual[(t > SKIP * 0.002) & (t < 0.5)]).max() < 1.0
    assert tr.isolated[-1] == isolated, (_first_isolation(tr), tr.isolated[-1])


def test_a_frozen_velocity_sensor_is_isolated_as_the_velocity_sensor(designed):
    """A held velocity reading has no step at onset (ν says nothing) and was called an encoder fault; its
    repeated samples count in the step row."""
    _, _, model, rates, _, design = designed
    sc = arm_scenario("arm6.xml", faults=["sensor_freeze:joint3_vel:0@1.0"], seed=5, schemes=("momentum",),
                      duration=1.2)
    tr = _trace(run_scenario(sc, calibration(sc)[0]), model, design, rates,
                confirm=ArmSchemeSettings().consistency_confirm, evidence=True)
    t = tr.time
    assert np.abs(tr.residual[(t > SKIP * 0.002) & (t < 1.0)]).max() < MARGIN
    time, got = _first_isolation(tr)
    assert got == "joint3_vel" and time - 1.0 < 0.1


def test_a_velocity_sensor_frozen_while_its_joint_rests_is_isolated_as_the_velocity_sensor(designed):
    """Frozen at rest, the reading stays right and the increments with it: only its repeats tell. The drive's
    reading never repeats on the design runs (``repeat_scale`` 0), so they count in the kinematic row as well as
    the step row, and the velocity sensor (both rows) is named within 30 ms; with that evidence off
    (``repeat_scale`` None) only the step row alarms, which no hypothesis explains alone, until the frozen
    reading's noise has drifted the increments far enough for the kinematic row (on jaco never, in a campaign)."""
    _, _, model, rates, _, design = designed
    assert np.all(design.repeat_scale == 0)
    sc = arm_scenario("arm6.xml", faults=["sensor_freeze:joint3_vel:0@3.4"], seed=5, schemes=("momentum",),
                      duration=3.8)
    record = run_scenario(sc, calibration(sc)[0])
    k = np.searchsorted(record.time, 3.4)
    assert np.abs(record.truth_state[k - 50:k, model.n + 2]).max() < 0.01       # the joint rests at the onset
    settings = dict(confirm=ArmSchemeSettings().consistency_confirm, evidence=True)
    time, got = _first_isolation(_trace(record, model, design, rates, **settings))
    assert got == "joint3_vel" and time - 3.4 < 0.03, (time, got)
    later, _ = _first_isolation(_trace(record, model, replace(design, repeat_scale=None), rates, **settings))
    assert later is None or later > time + 0.02, (later, time)      # arm6: 64 ms, the frozen noise's drift


def test_the_noise_walk_is_the_drives_velocity_noise_integrated(designed):
    """σ_n, the increments' long-run standard deviation, is what the trapezoid makes of the drive's white
    velocity noise: T σ_v (the sensor model's 1e-3 rad/s at the 2 ms diagnosis sample; the diagnoser never read
    it). The single-sample spread is not: it also holds the encoder's quantisation, which telescopes out of a sum."""
    _, sim, _, _, runs, design = designed
    expected = design.T * sim.sensors.velocity_noise
    np.testing.assert_allclose(design.noise_walk, expected, rtol=0.10)
    n = sim.n
    single = np.concatenate([kinematic_increments(Y[:, :n], Y[:, n:], design.T, design.skew)[SKIP:]
                             for Y, _ in runs]).std(axis=0)
    assert np.all(single > 1.2 * expected), single


def test_a_resting_arm_keeps_its_kinematic_rows_inside_their_bounds(designed):
    """20 s holding a pose: the window sums are the velocity noise's random walk, σ_n √W (the 0.5 s windows'
    spread over the six joints within 10 % of it: 240 independent windows), and the 0.5 s window stays inside
    its bound on every joint. The constants fitted as the tightest bound over the design runs alone sat at
    2.6–3.6 σ_n √W there, and this hold took that window to 1.39 of its bound (the 4 s window to 1.57); with the
    floor of NOISE_WALK_SIGMAS σ_n √W, measured: 0.90, and 1.15 over every window (a joint creeping under its
    controller's quantised feedback; the calibrated thresholds sit at 1.4–1.9)."""
    base, sim, model, rates, _, design = designed
    q0 = (0.3, -1.2, 0.9, -0.4, 1.1, -0.6)
    sc = replace(base, motion=Quintic(q0, np.zeros(sim.n), 20.0), faults=(), duration=20.0)
    Y, _ = diagnoser_inputs(run_scenario(sc, calibration(sc)[0]), rates)
    n = sim.n
    e = kinematic_increments(Y[:, :n], Y[:, n:], design.T, design.skew)[SKIP:]
    w = int(round(0.5 / design.T))
    sums = np.cumsum(e, axis=0)
    spread = (sums[w:] - sums[:-w])[::w] / (design.noise_walk * np.sqrt(w))
    assert np.sqrt(np.mean(spread ** 2)) == pytest.approx(1.0, rel=0.10)
    half = design.windows.index(0.5)
    window = KinematicConsistency(design.T, design.skew, design.window_scales[:, half:half + 1], (0.5,),
                                  design.reach[:, half:half + 1])
    every = KinematicConsistency(design.T, design.skew, design.window_scales, design.windows, design.reach)
    ratios = np.array([[window.update(y[:n], y[n:])[0], every.update(y[:n], y[n:])[0]] for y in Y])[SKIP:]
    assert ratios[:, 0].max() < 1.0 and ratios[:, 1].max() < 1.25, ratios.max(axis=0)


def test_the_noise_walk_of_white_velocity_noise_and_a_quantised_encoder():
    """Synthetic: a smooth motion read by a quantised encoder and a velocity sensor with white noise σ_v; the
    identified σ_n is T σ_v within 3 % (the quantisation telescopes), and every window constant is at least
    NOISE_WALK_SIGMAS σ_n √W."""
    rng = np.random.default_rng(3)
    T, sigma_v, count = 0.002, 1e-3, 40_000
    t = np.arange(count) * T
    v_true = np.column_stack([0.5 * np.sin(0.7 * t), 0.2 * np.cos(1.3 * t)])
    q_true = np.column_stack([0.5 * (1 - np.cos(0.7 * t)) / 0.7, 0.2 * np.sin(1.3 * t) / 1.3])
    q = np.round(q_true / 6e-6) * 6e-6
    v = v_true + rng.normal(0.0, sigma_v, v_true.shape)
    e = kinematic_increments(q, v, T)
    walk = identify_noise_walk([e[: count // 2], e[count // 2:]])
    np.testing.assert_allclose(walk, T * sigma_v, rtol=0.03)
    windows = (0.0, 0.1, 0.5)
    scales = design_window_scales([e], [v], T, windows=windows, noise_walk=walk)
    sizes = np.array([1, 50, 250])
    assert np.all(scales[..., 0] >= NOISE_WALK_SIGMAS * walk[:, None] * np.sqrt(sizes) * (1 - 1e-12))
    with pytest.raises(RobofdiError, match="noise_walk"):
        design_window_scales([e], [v], T, windows=windows, noise_walk=np.array([1e-6]))
    with pytest.raises(RobofdiError, match="identify_noise_walk"):
        identify_noise_walk([e[:3]])


def test_skew_is_identified_when_the_instrument_is_anti_correlated():
    """A joint whose velocity swings at a quarter of the sample rate (as robosuite's iiwa's light joint 7 does)
    makes Σ Δq̇ z negative; the instrumental-variable estimate is still the skew of the integration (it used to be
    refused). The plant: semi-implicit Euler steps of h = T/4 on a velocity linear within each sample, so
    e_k = (h/2) Δq̇_k exactly (kinematic.identify_skew)."""
    T, h, sub = 0.002, 0.0005, 4
    k = np.arange(1000)
    samples = 0.5 * np.sin(2 * np.pi * 0.7 * k * T) + 0.3 * np.cos(np.pi * k / 2)     # 125 Hz = 1 / (4 T)
    v = np.concatenate([[samples[0]], (samples[:-1, None] + np.outer(np.diff(samples), np.arange(1, sub + 1) / sub)).ravel()])
    q = np.cumsum(v) * h                                     # q_{j+1} = q_j + h v_{j+1}
    qs, vs = q[::sub, None], v[::sub, None]
    dv, z = np.diff(vs[:, 0])[3:], vs[2:-2, 0] - vs[:-4, 0]
    assert (dv * z).sum() < 0                                # the case: the instrument is anti-correlated
    np.testing.assert_allclose(identify_skew([qs], [vs], T), h / 2, rtol=1e-6)


def test_the_refutation_allows_the_noise_of_a_change_of_the_increment_learnt_from_fault_free_runs(designed):
    """The move scale is the largest fault-free |e_k − e_{k−1}| over the single-sample scale: more than one
    sample's bound (the floor) where the velocity noise moves e, less than the two samples' bounds added (what
    the refutation allowed before): consecutive increments share a velocity reading (|Δe| ≈ 1–1.7 scales for white
    velocity and encoder noise)."""
    design = designed[-1]
    assert np.all(design.move_scale >= 1.0) and np.all(design.move_scale < 2.0), design.move_scale
    assert np.any(design.move_scale > 1.0), design.move_scale


@pytest.mark.parametrize("moved, move, counted", [(1.0, 2.0, True), (1.3, 2.0, True), (0.0, 2.0, False),
                                                   (0.2, 2.0, False), (2.0, 2.0, False),
                                                   (0.38, 2.0, True), (0.38, 1.0, False), (1.0, 1.0, True)])
def test_the_step_row_counts_nu_only_where_the_increments_do_not_refute_a_readings_step(moved, move, counted):
    """A reading's step of ν at a sample moves the kinematic increment by m = −(T/2 + τ_s) ν at once; a real
    velocity change (a torque) leaves it where it was. ν = 5× its bound: counted when e moved by ``moved`` × m
    within |m|/2 plus ``move`` single-sample scales (here 100 µrad ± 50 µrad + move × 10 µrad), else the row
    holds nothing."""
    T, skew, single, nu, bound = 0.002, 0.001, 10e-6, 0.05, 0.01
    made = -(T / 2 + skew) * nu                       # −100 µrad
    hold = 50
    steps, jumps, previous = np.zeros((hold, 1)), np.zeros((hold, 1)), np.zeros((3, 1))
    z, estimate = np.empty(4), np.empty(4)
    _step_rows(np.zeros(1), np.array([nu]), np.zeros(1), np.array([moved * made]), np.ones(1),
               np.array([[single, 1.0]]), 0, np.array([skew]), np.array([move]), np.array([bound]), np.zeros(1), 2.0,
               steps, jumps, previous, 3, 2, T, z, estimate, np.zeros(1), np.zeros(1), np.zeros((15, 1)), 0.99,
               np.zeros(1), np.zeros(1), np.zeros((8, 1)), np.zeros((4, 1)), 0, np.zeros(1), np.zeros(1), np.zeros(1),
               np.zeros(1))
    assert z[2] == (pytest.approx(nu / bound) if counted else 0.0)
    assert z[1] == 0.0                                # no position step: |e| is within what ν makes


@pytest.mark.parametrize("case, held", [("encoder frozen while the joint moves", False),
                                        ("velocity step while the joint moves", True),
                                        ("velocity step as the reading stands still one sample", True),
                                        ("velocity step at rest", True)])
def test_the_step_row_holds_no_velocity_step_where_the_encoder_reading_stopped_in_motion(case, held):
    """A frozen encoder on a moving joint makes e = −T q̇ from its onset, what a step of q̇ in the velocity reading
    would make; with ν near that step by its noise, the agreement held it as a velocity step and the refutation
    let ν count (robosuite's baxter, left_w0 at 0.01–0.05 rad/s, named the velocity sensor twice). Where the
    encoder's reading stood still while the velocity readings said the joint moved by more than a single-sample
    scale a sample (at the step's sample and the next), the step row holds neither. The same increments with the
    reading moving, or standing still for the step's sample only (kinova3's wrist reversing: a velocity bias
    there was lost to a one-sample version of this rule), or a velocity step at rest (the reading still, the
    velocity reading 0 before the step), are held: 4e-5 rad over twice the 1e-5 scale."""
    T, skew, single, v0, hold = 0.002, 0.001, 10e-6, 0.02, 50
    steps, jumps, previous = np.zeros((hold, 1)), np.zeros((hold, 1)), np.zeros((3, 1))
    z, estimate = np.empty(4), np.empty(4)
    sums = np.zeros((gain_rows(T), 1))
    sums[Q_LAST] = sums[Q_BEFORE] = np.nan
    frozen, paused, in_motion = case.startswith("encoder"), "one sample" in case, not case.endswith("at rest")
    for k in range(5):
        onset = k >= 3                    # the step (or the freeze) at sample 3, judged at sample 4
        counts = (min(k, 2) if frozen else 2 if paused and k == 3 else k) if in_motion else 0
        q = 0.5 + T * v0 * counts
        v = v0 if (in_motion or onset) else 0.0
        e = -T * v0 if onset else 0.0
        nu = 0.015 if k == 3 else 0.0     # ν at the step: near the step of 0.02 the increments imply
        _step_rows(np.zeros(1), np.array([nu]), np.zeros(1), np.array([e]), np.ones(1), np.array([[single, 1.0]]), 0,
                   np.array([skew]), np.array([1.0]), np.array([1.0]), np.zeros(1), 2.0, steps, jumps, previous,
                   k % hold, (k - 1) % hold, T, z, estimate, np.array([q]), np.array([v]), sums, 0.99, np.zeros(1),
                   np.zeros(1), np.zeros((8, 1)), np.zeros((4, 1)), k, np.zeros(1), np.zeros(1), np.zeros(1),
                   np.zeros(1))
    assert z[2] == (pytest.approx(2.0) if held else 0.0)      # the agreement (ν over its bound is 0.015 only)


def test_the_kinematic_windows_do_not_sum_what_a_velocity_change_within_the_sample_made():
    """An increment blip that ν explains (the same sign, up to −(T/2 + τ_s) ν) is left out of the window sums; one
    of the other sign, or larger than it explains, is summed (the excess); the returned e is the increment as is."""
    T, n = 0.002, 1
    scales = np.ones((n, len(WINDOWS), 3)) * [1e-5, 0.0, 0.0]
    def ratios(blip, explained):
        kc = KinematicConsistency(T, np.zeros(n), scales, WINDOWS)
        q, out = 0.0, []
        for k in range(20):
            q += 0.01 * T + (blip if k == 10 else 0.0)
            x = np.array([explained if k == 10 else 0.0])
            r, e = kc.update(np.array([q]), np.array([0.01]), x)
            out.append((r[0], e[0]))
        return out
    quiet, explained = ratios(0.0, 0.0), ratios(1e-4, 1.5e-4)
    assert explained[10][1] == pytest.approx(1e-4)                      # e itself is reported
    assert max(r for r, _ in explained) == pytest.approx(max(r for r, _ in quiet), abs=1e-9)   # not summed
    excess = ratios(1e-4, 0.4e-4)                                       # only the part it explains is removed
    assert max(r for r, _ in excess) == pytest.approx(6.0, rel=1e-6)    # 60 µrad over the 10 µrad scale
    opposite = ratios(1e-4, -1.5e-4)
    assert max(r for r, _ in opposite) == pytest.approx(10.0, rel=1e-6)


def test_kinematic_stepping_matches_the_offline_sums():
    rng = np.random.default_rng(0)
    T, n = 0.002, 2
    v = np.cumsum(rng.normal(0, 0.01, (400, n)), axis=0)
    q = np.cumsum(v, axis=0) * T + rng.normal(0, 1e-6, (400, n))
    e = kinematic_increments(q, v, T)
    scales = design_window_scales([e], [v], T, windows=(0.0, 0.1))
    k = KinematicConsistency(T, np.zeros(n), scales, windows=(0.0, 0.1))
    ratios = np.array([k.update(qq, vv)[0] for qq, vv in zip(q, v)])
    assert ratios.max() <= 1.0 + 1e-6 and ratios.max() > 0.99      # tight: the bound touches the data


def test_bad_inputs_are_named():
    with pytest.raises(RobofdiError, match="viscous"):
        JointFriction(np.ones(2), np.ones(3), np.ones(2), np.zeros(2))
    with pytest.raises(RobofdiError, match="scales"):
        KinematicConsistency(0.002, np.zeros(2), np.ones((2, 4)))
    with pytest.raises(RobofdiError, match="reach"):
        KinematicConsistency(0.002, np.zeros(2), np.ones((2, 1, 3)), windows=(0.0,), reach=np.ones((2, 2, 2)))


def test_the_velocity_innovation_is_one_joint_step_that_explains_the_impulse(designed):
    """A velocity step b on joint j adds the impulse M_j b (column j of M(q)): the one-joint fit gives ν_j = b
    exactly, on arm6's M(q) and on one whose joints 1 and 3 are nearly coaxial (M gains 500 kg·m² along
    e1 + e3: each joint alone moves everything beyond it, their opposite motion almost nothing). There M⁻¹
    turns a small impulse noise into large opposite steps on joints 1 and 3; the one-joint fit does not."""
    _, _, model, _, _, design = designed
    d = ConsistencyResidual(model, design)

    def innovation(M, dr):
        d.reset()
        d.velocity_innovation(M, np.zeros(model.n))
        return d.velocity_innovation(M, dr)

    mass = model.mass_matrix(np.zeros(model.n))
    v = np.zeros(model.n)
    v[[0, 2]] = 1.0
    coaxial = mass + 500.0 * np.outer(v, v)
    for M in (mass, coaxial):
        for j in range(model.n):
            assert innovation(M, design.gain * M[:, j] * 0.05)[j] == pytest.approx(0.05, rel=1e-9)
    noise = np.random.default_rng(0).normal(0.0, 1e-3, (200, model.n)) * design.gain      # 1 mN·m·s impulses
    fit = np.array([innovation(coaxial, w) for w in noise])
    inverse = np.array([np.linalg.solve(coaxial, w) / design.gain for w in noise])
    assert np.abs(fit[:, [0, 2]]).max() < 0.2 * np.abs(inverse[:, [0, 2]]).max()


def test_the_step_bound_follows_the_spread_that_impulse_noise_gives_nu_at_the_pose(designed):
    """Impulse noise of the design's spread per joint makes ν_j scatter by (M_jᵀ W M_j)^(−1/2) (``spread``): at
    arm6's folded and stretched poses, 4000 noise draws give that standard deviation within 5 %, the shoulder's
    spread changes with the reach while the wrist's does not, and the step bound grows with it where the design
    learnt that it must (c₂ > 0), so a pose of small inertia is not judged by the bound of a large one."""
    _, _, model, _, _, design = designed
    d = ConsistencyResidual(model, design)
    rng = np.random.default_rng(1)
    folded, stretched = np.array([0.0, 0.3, 2.4, 0.0, 0.0, 0.0]), np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])
    spreads = []
    for q in (folded, stretched):
        M = model.mass_matrix(q)
        noise = rng.normal(0.0, 1.0, (4000, model.n)) * design.impulse_scale * design.gain
        d.reset()
        d.velocity_innovation(M, np.zeros(model.n))
        nu = np.array([d.velocity_innovation(M, w) for w in np.cumsum(noise, axis=0)])
        np.testing.assert_allclose(nu.std(axis=0), d.spread, rtol=0.05)
        np.testing.assert_allclose(design.spread(M), d.spread, rtol=1e-12)
        spreads.append(d.spread.copy())
    assert spreads[0][0] > 1.2 * spreads[1][0]            # the shoulder turns a smaller inertia when folded
    assert spreads[0][5] == pytest.approx(spreads[1][5], rel=0.02)      # the wrist's inertia does not change
    bounds = [design.step_bound(np.zeros(model.n), s) for s in spreads]
    grows = design.step_scale[:, 2] > 0
    assert grows.any()
    np.testing.assert_array_less(bounds[1][grows & (spreads[0] > spreads[1])],
                                 bounds[0][grows & (spreads[0] > spreads[1])])


def test_the_gain_evidence_counts_only_where_the_encoder_does_not_jump():
    """Increments that follow the velocity two samples back (a +15 % gain error on a joint speeding up and slowing
    down) raise the gain evidence above a drift's; the same window counts nothing once more than GAIN_JUMPS of its
    moving samples were position steps (a noisy encoder's small increments are a biased sample). A drift's
    constant increments raise none."""
    from robofdi.observers.consistency import GAIN_JUMPS, JUMPED, MOVING, _gain_evidence, _gain_fit

    T, lam, floor = 0.002, 0.99, 1e-5
    noise = np.random.default_rng(3).normal(0.0, 2e-6, 400)
    sums = np.zeros((gain_rows(T), 1))
    v = 3.0 * (1.0 - np.cos(2 * np.pi * T * np.arange(400) / 0.8))      # the velocity readings [rad/s]
    for k in range(2, 400):
        sums[MOVING, 0] = lam * sums[MOVING, 0] + 1.0
        value = _gain_evidence(sums, 0, -T * 0.15 * v[k - 2] + noise[k], T * v[k - 2], True, lam, floor)
    assert value > 5.0
    sums[JUMPED, 0] = (GAIN_JUMPS + 0.01) * sums[MOVING, 0]
    assert _gain_fit(sums, 0, lam, floor) == 0.0
    sums[JUMPED, 0] = (GAIN_JUMPS - 0.01) * sums[MOVING, 0]
    assert _gain_fit(sums, 0, lam, floor) == value
    drift = np.zeros((gain_rows(T), 1))           # constant increments (an encoder drift) over the same motion
    for k in range(2, 400):
        drift[MOVING, 0] = lam * drift[MOVING, 0] + 1.0
        assert _gain_evidence(drift, 0, 5e-5 + noise[k], T * v[k - 2], True, lam, floor) < 1.0


def _evidence(e, x, T=0.002, lam=0.99, floor=1e-5):
    from robofdi.observers.consistency import _gain_evidence

    sums = np.zeros((gain_rows(T), 1))
    return np.array([_gain_evidence(sums, 0, a, b, True, lam, floor) for a, b in zip(e, x)])


def test_the_gain_evidence_takes_a_gain_error_from_its_onset_on_a_joint_accelerating_steadily():
    """300 samples of fault-free motion (1 rad/s, then slowing to rest: the samples at rest are not counted), then
    the joint accelerates from rest at 20 rad/s² with a −16 % velocity-gain error: increments −T g q̇ that ramp
    from 0 while the window still holds the earlier motion's. A drift fitted as a level and a trend took that for
    a drift (the earlier form: 0 at 40 samples of motion, 1.3 at 80; arm6's campaigns: evidence 52–520 ms after
    the first alarm). With the gain and the encoder drift each fitted from its own onset, the gain passes 1 at 20
    samples and 5 at 80; an encoder drift that starts with the motion (one level, the gain error's size there)
    raises none, nor does one that starts 37 samples into it, between two of the onsets the gain fit tries (the
    drift gets every split)."""
    T = 0.002
    v = np.concatenate([np.full(200, 1.0), np.linspace(1.0, 0.0, 100), 20.0 * T * np.arange(200)])    # [rad/s]
    x = T * np.concatenate([[0.0, 0.0], v[:-2]])                  # the reading two samples back, times T
    k = np.arange(v.size)
    noise = np.random.default_rng(5).normal(0.0, 2e-6, v.size)
    gain = _evidence(np.where(k >= 300, 0.16, 0.0) * x + noise, x)
    assert gain[:300].max() < 0.3
    assert gain[320] > 1.0 and gain[380] > 5.0
    for onset in (300, 337):
        drift = _evidence(np.where(k >= onset, 0.16 * x[400], 0.0) + noise, x)
        assert drift.max() < 0.3, onset


def test_the_trend_evidence_is_a_steady_growth_away_from_zero():
    """Four windows of m samples: a ramp away from zero (a velocity drift's increments) gives the difference of
    consecutive window means over the noise of a mean; a step to a constant (an encoder drift) gives none once its
    onset has left the oldest window, nor does a decay towards zero (an encoder offset rising to its value)."""
    from robofdi.observers.consistency import _trend_evidence

    m, floor = 25, 1e-5
    k = np.arange(400)

    def last(e):
        ring, sums = np.zeros((4 * m, 1)), np.zeros((4, 1))
        return np.array([_trend_evidence(ring, sums, j, 0, x, floor) for j, x in enumerate(e)])

    ramp = last(-2e-7 * np.maximum(k - 100, 0))         # −T d (t − t₀): −2e-7 rad a sample
    assert ramp[:4 * m - 1].max() == 0.0                # not before the four windows have filled
    assert ramp[-1] == pytest.approx(2e-7 * m / (floor / np.sqrt(m)), rel=1e-9)
    step = last(np.where(k >= 100, 5e-5, 0.0))
    assert step[100 + 4 * m:].max() == 0.0
    decay = last(np.where(k >= 100, 5e-5 * np.exp(-(k - 100) / 80.0), 0.0))
    assert decay[101:].max() == 0.0


def test_the_encoder_counts_as_stepped_on_a_spike_of_its_increments_not_on_large_smooth_ones():
    """A velocity-gain error in hard acceleration makes large increments that change by many single-sample scales
    a sample, but smoothly: the encoder is not marked as stepped (its gain evidence stays). One increment that
    stands out from both neighbours by more than ENCODER_STEP scales (an encoder step) marks it for the run."""
    from robofdi.observers.consistency import ENCODER_STEP

    T, single, hold = 0.002, 2e-6, 50

    def stepped(e):
        steps, jumps, previous = np.zeros((hold, 1)), np.zeros((hold, 1)), np.zeros((3, 1))
        sums = np.zeros((gain_rows(T), 1))
        sums[Q_LAST] = np.nan
        z, estimate = np.empty(4), np.empty(4)
        for k, x in enumerate(e):
            _step_rows(np.zeros(1), np.zeros(1), np.zeros(1), np.array([x]), np.ones(1), np.array([[single, 1.0]]), 0,
                       np.array([0.001]), np.array([2.0]), np.array([0.01]), np.zeros(1), 2.0, steps, jumps, previous,
                       k % hold,
                       (k - 1) % hold, T, z, estimate, np.array([0.01 * k]), np.array([5.0]), sums, 0.99, np.zeros(1),
                       np.zeros(1), np.zeros((8, 1)), np.zeros((4, 1)), k, np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1))
        return bool(sums[STEPPED, 0] > 0)

    accelerating = -T * 0.16 * 50.0 * T * np.arange(200)     # −T g q̇, q̇ rising by 50 rad/s² (32 µrad a sample)
    assert np.abs(np.diff(accelerating)).min() > ENCODER_STEP * single
    assert not stepped(accelerating)
    spike = np.zeros(200)
    spike[100] = 30 * single
    assert stepped(spike)
    spike[100] = 8 * single
    assert not stepped(spike)


def test_a_carried_payload_the_file_lacks_is_identified_with_the_friction(designed):
    """A 1.5 kg load at the payload point that the robot file (the nominal model) lacks is a pose-dependent torque
    on every joint no friction term follows: the design identifies its mass with the friction (within 15 %). On
    the same arm without it the fit finds 0.11 kg (the link masses' errors), which explains too little of the
    residual to enter the design."""

    base, _, model, rates, _, design = designed
    assert design.payload == 0.0
    loaded = evolve(replace(base, faults=()), payload=1.5)
    runs = [diagnoser_inputs(r, rates) for r in calibration_records(loaded).values()]
    carried = design_consistency(model, runs, 1.0 / rates.diagnosis_hz, skip=SKIP)
    assert carried.payload == pytest.approx(1.5, rel=0.15), carried.payload
    assert ConsistencyDesign.from_arrays(carried.arrays()).payload == carried.payload


def test_a_ripple_that_grows_with_the_torque_is_identified_with_it():
    """e_k = Re((A + B τ_k) exp(i m q_k)) + noise on samples near the alias of order m, τ_k varied: the fit finds
    |A| and |B| (its Wald statistic far above RIPPLE_LOAD_WALD); with the torque held constant, or none given, B is
    not separable and the constant amplitude alone is kept. Every sample lies near the alias."""
    gen = np.random.default_rng(11)
    T, m, K = 0.002, 360.0, 600
    v = np.full(K, 2 * np.pi / (m * T)) * (1 + gen.uniform(-0.02, 0.02, K))          # one ripple turn per sample
    q = np.cumsum(v) * T
    A, B = 2e-6 * np.exp(0.7j), 1.5e-7 * np.exp(-2.1j)

    def run(tau):
        e = np.real((A + B * tau) * np.exp(1j * m * q)) + gen.normal(0, 3e-7, K)
        # positions whose increments are e beyond the trapezoid (no skew): q_k = q_{k−1} + T(v_k + v_{k−1})/2 + e_k
        qm = np.concatenate([[0.0], np.cumsum(T * (v[1:] + v[:-1]) / 2 + e[1:])])
        return qm[:, None], v[:, None], tau[:, None]

    q1, v1, u1 = run(gen.uniform(-20, 20, K))
    amp, load = identify_ripple([q1], [v1], T, np.zeros(1), np.array([[m]]), us=[u1])
    assert amp[0, 0] == pytest.approx(abs(A), rel=0.05) and load[0, 0] == pytest.approx(abs(B), rel=0.05)
    q2, v2, u2 = run(np.full(K, 5.0))
    amp2, load2 = identify_ripple([q2], [v2], T, np.zeros(1), np.array([[m]]), us=[u2])
    assert load2[0, 0] == 0 and amp2[0, 0] == pytest.approx(abs(A + 5 * B), rel=0.05)
    _, none = identify_ripple([q1], [v1], T, np.zeros(1), np.array([[m]]))
    assert none[0, 0] == 0


def test_the_kinematic_rows_cover_a_ripple_grown_with_the_torque():
    """A window that cruises on the alias at a torque the design's constant amplitude never saw: with |B| the
    bound covers the coherent sum that |A| alone leaves outside it."""
    gen = np.random.default_rng(12)
    T, m, K = 0.002, 360.0, 400
    v = np.full(K, 2 * np.pi / (m * T)) * (1 + gen.uniform(-0.002, 0.002, K))      # the aliased phase creeps
    A, B, tau = 1e-6 * np.exp(0.3j), 2e-7 * np.exp(0.3j), np.full(K, 20.0)
    q = np.concatenate([[0.0], np.cumsum(T * (v[1:] + v[:-1]) / 2)])
    q = q + np.concatenate([[0.0], np.cumsum(np.real((A + B * tau[1:]) * np.exp(1j * m * q[1:])))])
    scales = np.tile([2e-6, 0.0, 0.0], (1, len(WINDOWS), 1))
    plain = KinematicConsistency(T, np.zeros(1), scales, WINDOWS, None, np.array([[m]]), np.array([[abs(A)]]))
    loaded = KinematicConsistency(T, np.zeros(1), scales, WINDOWS, None, np.array([[m]]), np.array([[abs(A)]]),
                                  np.array([[abs(B)]]))
    a = np.array([plain.update(q[k:k + 1], v[k:k + 1], None, tau[k:k + 1])[0] for k in range(K)])
    b = np.array([loaded.update(q[k:k + 1], v[k:k + 1], None, tau[k:k + 1])[0] for k in range(K)])
    assert a.max() > 2 and b.max() < 1 and np.all(b <= a)
