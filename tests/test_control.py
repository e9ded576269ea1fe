"""Tests of robofdi.control: quintic trajectories and sequences (boundary conditions, continuity by finite
differences), computed-torque control (the control law against an independent computation, clipping, closed-loop
tracking on the MuJoCo arm), and motion design from joint ranges and torque limits (ranges, torque budget,
seeding, arms with n != 6)."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.control import (
    ComputedTorque,
    MotionLimits,
    Quintic,
    Sequence,
    calibration_motions,
    fit_duration,
    joint_ranges,
    random_point_to_point,
)
from robofdi.models.manipulator import ManipulatorModel
from robofdi.seeding import rng as seeded_rng

ARM = ASSETS / "arm6.xml"
Q0 = np.array([np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0])   # the book's start pose
DQ = np.array([np.pi / 4, np.pi / 4, -np.pi / 4, 0.0, -np.pi / 2, np.pi / 2])


@pytest.fixture(scope="module")
def model():
    return ManipulatorModel(ARM)


@pytest.fixture(scope="module")
def limits(model):
    """arm6's ranges from MuJoCo (compiled independently of the code under test) and its motor limits."""
    m = mujoco.MjModel.from_xml_path(str(ARM))
    return MotionLimits.from_ranges(m.jnt_range[:, 0], m.jnt_range[:, 1], m.actuator_ctrlrange[:, 1])


# ---------------------------------------------------------------------------------------------------------------
# Trajectories
# ---------------------------------------------------------------------------------------------------------------
def test_quintic_boundary_conditions_and_hold():
    start, T = 0.7, 3.0
    traj = Quintic(tuple(Q0), tuple(DQ), T, start)
    q, v, a = traj(start)
    np.testing.assert_allclose(q, Q0, atol=1e-15)
    np.testing.assert_allclose(v, 0, atol=1e-15)
    np.testing.assert_allclose(a, 0, atol=1e-15)
    q, v, a = traj(start + T)
    np.testing.assert_allclose(q, Q0 + DQ, atol=1e-12)
    np.testing.assert_allclose(v, 0, atol=1e-12)
    np.testing.assert_allclose(a, 0, atol=1e-12)
    for t in (start + T + 1e-3, start + 10 * T):           # holds the final pose at rest afterwards
        q, v, a = traj(t)
        np.testing.assert_allclose(q, Q0 + DQ, atol=1e-12)
        assert not v.any() and not a.any()
    q, v, a = traj(start - 0.5)                             # and the initial pose before it starts
    np.testing.assert_allclose(q, Q0, atol=1e-15)
    # midpoint of a symmetric quintic: half-way, peak speed 15/8 Δq/T, zero acceleration
    q, v, a = traj(start + T / 2)
    np.testing.assert_allclose(q, Q0 + DQ / 2, atol=1e-12)
    np.testing.assert_allclose(v, 1.875 * DQ / T, atol=1e-12)
    np.testing.assert_allclose(a, 0, atol=1e-12)
    np.testing.assert_allclose(traj.start_pose, Q0)


def test_quintic_derivatives_match_finite_differences():
    traj = Quintic(tuple(Q0), tuple(DQ), 2.0)
    h = 1e-5
    for t in np.linspace(0.05, 1.95, 9):
        qm, vm, _ = traj(t - h)
        qp, vp, _ = traj(t + h)
        _, v, a = traj(t)
        np.testing.assert_allclose(v, (qp - qm) / (2 * h), atol=1e-7)
        np.testing.assert_allclose(a, (vp - vm) / (2 * h), atol=1e-6)


def test_sequence_is_continuous_in_position_velocity_and_acceleration_at_the_joints():
    waypoints = [Q0, Q0 + DQ, Q0 - 0.5 * DQ, Q0]
    seq = Sequence.through(waypoints, [1.0, 0.8, 1.5], start=0.2)
    assert seq.start == 0.2 and seq.end == pytest.approx(3.5)
    np.testing.assert_allclose(seq.start_pose, Q0)
    np.testing.assert_allclose(seq.waypoints, np.array(waypoints))
    h = 1e-6
    for joint in (1.2, 2.0):
        ql, vl, al = seq(joint - h)
        qr, vr, ar = seq(joint + h)
        q, v, _ = seq(joint)
        np.testing.assert_allclose(ql, qr, atol=1e-9)
        np.testing.assert_allclose(vl, vr, atol=1e-5)
        np.testing.assert_allclose(al, ar, atol=1e-3)
        np.testing.assert_allclose(v, 0, atol=1e-12)        # at rest at every waypoint
        # the velocity is the derivative of the position across the joint, the acceleration that of the velocity
        # (the jerk jumps at a joint, so the central difference of q̇ is off by ~|Δjerk| k / 4 <= 5e-4 here)
        k = 1e-5
        (qm, vm, _), (qp, vp, _) = seq(joint - k), seq(joint + k)
        np.testing.assert_allclose(v, (qp - qm) / (2 * k), atol=1e-8)
        np.testing.assert_allclose(seq(joint)[2], (vp - vm) / (2 * k), atol=1e-3)
    np.testing.assert_allclose(seq(seq.end + 1.0)[0], Q0, atol=1e-12)


def test_a_reference_read_ahead_equals_the_reference_called_at_each_time_bit_for_bit():
    """Quintic.sample / Sequence.sample (the loop reads its reference ahead through a kernel) against __call__ at
    every time: before the start, on a 1 ms grid through several segments, on the segment ends, after the end;
    compiled and on the pure-Python path."""
    from robofdi.jit import interpreted

    rng = np.random.default_rng(11)
    seq = Sequence.through(rng.uniform(-2, 2, (5, 6)), rng.uniform(0.3, 1.7, 4), start=0.25)
    times = np.concatenate([[-0.1, 0.0, 0.25], np.arange(0.0, seq.end + 0.3, 1e-3), seq._ends, rng.uniform(0, 6, 500)])
    for motion in (seq, seq.segments[1]):
        expected = [np.array([motion(t)[i] for t in times]) for i in range(3)]
        for ahead in (motion.sample(times), motion.sample(list(times))):
            for got, want in zip(ahead, expected):
                assert got.tobytes() == want.tobytes()
        with interpreted():
            for got, want in zip(motion.sample(times), expected):
                assert got.tobytes() == want.tobytes()
    assert np.ptp(expected[2]) > 1.0                      # the accelerations vary: the comparison is not vacuous


def test_trajectory_validation():
    with pytest.raises(RobofdiError, match="duration"):
        Quintic((0.0,), (1.0,), 0.0)
    with pytest.raises(RobofdiError, match="same length"):
        Quintic((0.0, 1.0), (1.0,), 1.0)
    with pytest.raises(RobofdiError, match="one duration per segment"):
        Sequence.through([Q0, Q0 + DQ], [1.0, 1.0])


# ---------------------------------------------------------------------------------------------------------------
# Computed torque
# ---------------------------------------------------------------------------------------------------------------
def test_computed_torque_law_against_an_independent_computation(model):
    other = ManipulatorModel(ARM)                                   # a second instance of the same model
    kp, kd = 250.0, 30.0
    ctrl = ComputedTorque(model, kp=kp, kd=kd)
    rng = np.random.default_rng(3)
    lo, hi = np.array(joint_ranges(ARM))
    for _ in range(5):
        q, qd = rng.uniform(lo, hi), rng.uniform(lo, hi)
        v, vd, ad = rng.uniform(-1, 1, (3, 6))
        tau = ctrl.update(np.concatenate([q, v]), (qd, vd, ad))
        expected = other.mass_matrix(q) @ (ad + kd * (vd - v) + kp * (qd - q)) + other.bias(q, v)
        np.testing.assert_allclose(tau, expected, rtol=1e-10, atol=1e-8)


def test_computed_torque_clips_at_the_torque_limit(model):
    limit = np.array([50.0, 40.0, 30.0, 20.0, 10.0, 5.0])
    ctrl = ComputedTorque(model, torque_limit=limit)
    free = ComputedTorque(ManipulatorModel(ARM))
    y = np.concatenate([Q0, np.zeros(6)])
    ref = (Q0 + 0.3, np.full(6, 0.5), np.zeros(6))               # a large error: every joint wants more
    tau, unclipped = ctrl.update(y, ref), free.update(y, ref)
    assert np.all(np.abs(unclipped) > limit)
    np.testing.assert_array_equal(tau, np.sign(unclipped) * limit)
    small = (Q0 + 1e-4, np.zeros(6), np.zeros(6))                # gravity compensation plus a little: inside
    np.testing.assert_allclose(ComputedTorque(model, torque_limit=np.full(6, 1e4)).update(y, small), free.update(y, small))


@pytest.mark.parametrize("kp, kd", [(0.0, 40.0), (400.0, -1.0)])
def test_computed_torque_rejects_non_positive_gains(model, kp, kd):
    with pytest.raises(RobofdiError, match="kp"):
        ComputedTorque(model, kp=kp, kd=kd)


def test_computed_torque_tracks_a_designed_motion_on_the_mujoco_arm(model, limits):
    """Closed loop on the real plant (Coulomb friction and motor ripple that the model lacks). With the
    nominal model otherwise exact, the error obeys ë + K_D ė + K_P e = M⁻¹ d; K_P = 400, K_D = 40 is critically
    damped, so |e_j| stays below sup |M⁻¹ d|_j / K_P. d is bounded by the Coulomb friction (MJCF frictionloss)
    plus the ripple, c1 + c2 |τ| <= 3 % of the torque limit with the shipped defaults (5 % taken); 1.3× covers
    the 1 ms zero-order hold and the integrator."""
    from robofdi.sims import ArmSimulator

    motion = random_point_to_point(model, limits, 11, n_segments=1, speed="fast", dwell=0.2)
    sim = ArmSimulator("arm6.xml")
    ctrl = ComputedTorque(model, torque_limit=model.torque_limit)
    dt = sim.control_dt
    y = sim.reset(motion.start_pose)
    errors, k = [], 0
    while k * dt < motion.end:
        y = sim.step(ctrl.update(y, motion(k * dt)))
        k += 1
        errors.append(np.abs(motion(k * dt)[0] - y[:6]))
    err = np.max(errors, axis=0)

    mj = mujoco.MjModel.from_xml_path(str(ARM))
    d_max = mj.dof_frictionloss + 0.05 * mj.actuator_ctrlrange[:, 1]
    peak = np.max([np.abs(np.linalg.inv(model.mass_matrix(motion(t)[0]))) @ d_max
                   for t in np.linspace(0, motion.end, 50)], axis=0)
    bound = 1.3 * peak / ctrl.kp
    assert np.all(err < bound), f"tracking error {err} above {bound}"
    assert np.all(err[:3] < 0.01)                 # the heavy joints track to < 0.6°
    assert np.abs(y[:6] - motion.waypoints[-1]).max() < bound.max()


# ---------------------------------------------------------------------------------------------------------------
# Motion design
# ---------------------------------------------------------------------------------------------------------------
def check_motion(model, motion, lower, upper, margin=0.1, fraction=0.6, dt=2e-3):
    """Independent check: sample the motion (plus both sides of every segment joint), stay inside the ranges
    shrunk by the margin, nominal feed-forward within fraction × limit. Returns the peak torque ratio."""
    lower, upper = np.asarray(lower), np.asarray(upper)
    lo, hi = lower + margin * (upper - lower), upper - margin * (upper - lower)
    budget = fraction * model.torque_limit
    joints = np.cumsum([0.0] + [s.duration for s in motion.segments])
    times = np.unique(np.concatenate([np.arange(0.0, motion.end, dt), joints, joints[1:-1] - 1e-6, [motion.end]]))
    peak = 0.0
    for t in times:
        q, v, a = motion(t)
        assert np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12), f"t={t}: q={q} leaves [{lo}, {hi}]"
        tau = model.inverse_dynamics(q, v, a)
        peak = max(peak, float(np.max(np.abs(tau) / budget)))
    assert peak <= 1.0 + 1e-9, f"feed-forward uses {peak:.4f} of the torque budget"
    assert not np.any(motion(0.0)[1]) and not np.any(motion(motion.end)[1])     # starts and ends at rest
    return peak


def test_limits_from_the_model_are_the_mjcf_ranges(model, limits):
    from_model = MotionLimits.from_model(model)
    assert from_model == limits
    np.testing.assert_allclose(limits.usable_lower, np.array(limits.lower) + 0.1 * (np.array(limits.upper) - limits.lower))
    np.testing.assert_allclose(limits.torque_budget, 0.6 * model.torque_limit)


def test_fit_duration_is_the_shortest_admissible_duration(model, limits):
    q0, q1 = Q0, Q0 + DQ
    T = fit_duration(model, q0, q1, limits)
    assert T > 0.5                                   # torque-bound, not the floor
    peak = check_motion(model, Sequence((Quintic(tuple(q0), tuple(q1 - q0), T),)), limits.lower, limits.upper, margin=0)
    assert peak > 0.99                               # it really uses the budget
    for factor in (1.2, 2.0, 5.0):                   # every longer duration is admissible
        check_motion(model, Sequence((Quintic(tuple(q0), tuple(q1 - q0), factor * T),)), limits.lower, limits.upper, margin=0)
    shorter = Quintic(tuple(q0), tuple(q1 - q0), 0.97 * T)
    over = max(np.max(np.abs(model.inverse_dynamics(*shorter(t))) / limits.torque_budget)
               for t in np.linspace(0, shorter.duration, 400))
    assert over > 1.0


def test_fit_duration_floor_speed_limit_and_gravity_error(model, limits):
    assert fit_duration(model, Q0, Q0 + 1e-3, limits) == 0.5
    assert fit_duration(model, Q0, Q0 + 1e-3, limits, floor=0.2) == 0.2
    slow = MotionLimits.from_ranges(limits.lower, limits.upper, limits.torque_limit, max_speed=0.5)
    T = fit_duration(model, Q0, Q0 + DQ, slow)
    v = max(np.max(np.abs(Quintic(tuple(Q0), tuple(DQ), T)(t)[1])) for t in np.linspace(0, T, 201))
    assert v <= 0.5 + 1e-9 and v > 0.49
    weak = MotionLimits.from_ranges(limits.lower, limits.upper, limits.torque_limit, torque_fraction=0.05)
    horizontal = np.array([0.0, -0.2, 0.0, 0.0, 0.0, 0.0])   # upper arm near horizontal: ~240 N·m on joint 2
    with pytest.raises(RobofdiError, match="gravity torque of joint 1"):
        fit_duration(model, horizontal, horizontal + 0.1, weak)
    with pytest.raises(RobofdiError, match="q_end"):
        fit_duration(model, Q0, Q0 + 10.0, limits)


@pytest.mark.parametrize("seed, segments, speed", [(0, 1, "normal"), (1, 3, "fast"), (2, 2, "slow"), (3, 4, 1.5)])
def test_random_motions_stay_inside_the_ranges_and_the_torque_budget(model, limits, seed, segments, speed):
    motion = random_point_to_point(model, limits, seed, n_segments=segments, speed=speed, dwell=0.3)
    check_motion(model, motion, limits.lower, limits.upper)
    moving = [s for s in motion.segments if np.any(s.dq)]
    assert len(moving) == segments and len(motion.segments) == 2 * segments    # every move followed by a rest
    assert all(s.duration == 0.3 for s in motion.segments if not np.any(s.dq))
    for seg in moving:
        base = fit_duration(model, seg.q0, seg.qf, limits)
        assert seg.duration >= base - 1e-9
        if speed == "fast":
            assert seg.duration == pytest.approx(base, abs=1e-9)


def test_same_seed_same_motion_other_seed_other_motion(model, limits):
    a = random_point_to_point(model, limits, 5, n_segments=2)
    b = random_point_to_point(model, limits, 5, n_segments=2)
    c = random_point_to_point(model, limits, 6, n_segments=2)
    np.testing.assert_array_equal(a.waypoints, b.waypoints)
    assert a.durations == b.durations
    for t in np.linspace(0, a.end, 7):
        np.testing.assert_array_equal(a(t)[0], b(t)[0])
    assert not np.allclose(a.start_pose, c.start_pose)
    # an int seed is the "motion" stream of robofdi.seeding
    d = random_point_to_point(model, limits, seeded_rng(5, "motion"), n_segments=2)
    np.testing.assert_array_equal(a.waypoints, d.waypoints)
    # a given start pose is kept
    e = random_point_to_point(model, limits, 5, q_start=Q0)
    np.testing.assert_array_equal(e.start_pose, Q0)


def test_calibration_motions_are_wide_feasible_and_seeded(model, limits):
    motions = calibration_motions(model, limits, 0, n_random=2)
    assert set(motions) == {"low_velocity", "high_acceleration", "random_1", "random_2"}
    peaks = {name: check_motion(model, m, limits.lower, limits.upper) for name, m in motions.items()}
    width = 0.8 * (np.array(limits.upper) - limits.lower)
    # low velocity: every joint sweeps a third of its usable range there and back in 16 s
    low = motions["low_velocity"]
    assert low.end == pytest.approx(16.0)
    qs = np.array([low(t)[0] for t in np.linspace(0, low.end, 801)])
    np.testing.assert_allclose(np.ptp(qs, axis=0), width / 3, rtol=1e-6)
    np.testing.assert_allclose(qs[-1], qs[0], atol=1e-12)
    assert np.max(np.abs([low(t)[1] for t in np.linspace(0, low.end, 801)])) < 1.875 * np.max(width / 3) / 8 + 1e-9
    # high acceleration: wide moves at the torque budget, there and back along the same path
    high = motions["high_acceleration"]
    wps = high.waypoints
    assert len(wps) == 5
    np.testing.assert_allclose(wps[::-1], wps, atol=1e-12)
    assert peaks["high_acceleration"] > 0.99
    assert np.mean(np.abs(np.diff(wps, axis=0)) / width) > 0.3       # joints travel a large part of their range
    assert high.end < low.end / 2
    # same seed, same motions; another seed, other motions
    again = calibration_motions(model, limits, 0, n_random=2)
    other = calibration_motions(model, limits, 1)
    for name in motions:
        np.testing.assert_array_equal(motions[name].waypoints, again[name].waypoints)
    assert not np.allclose(motions["high_acceleration"].waypoints, other["high_acceleration"].waypoints)


def test_calibration_motion_options_are_validated(model, limits):
    with pytest.raises(RobofdiError, match="low_velocity_time"):
        calibration_motions(model, limits, 0, low_velocity_time=0.01)
    with pytest.raises(RobofdiError, match="sweep_fraction"):
        calibration_motions(model, limits, 0, sweep_fraction=1.5)
    with pytest.raises(RobofdiError, match="waypoints"):
        calibration_motions(model, limits, 0, waypoints=1)
    with pytest.raises(RobofdiError, match="seed"):
        random_point_to_point(model, limits, -1)
    with pytest.raises(RobofdiError, match="speed"):
        random_point_to_point(model, limits, 0, speed="warp")
    with pytest.raises(RobofdiError, match="n_segments"):
        random_point_to_point(model, limits, 0, n_segments=0)


@pytest.mark.parametrize("kwargs, field", [
    (dict(lower=(0.0, 1.0), upper=(1.0, 0.5), torque_limit=(1.0, 1.0)), "lower"),
    (dict(lower=(0.0,), upper=(1.0, 2.0), torque_limit=(1.0,)), "upper"),
    (dict(lower=(0.0,), upper=(1.0,), torque_limit=(0.0,)), "torque_limit"),
    (dict(lower=(0.0,), upper=(1.0,), torque_limit=(float("nan"),)), "torque_limit"),
    (dict(lower=(0.0,), upper=(1.0,), torque_limit=(1.0,), range_margin=0.5), "range_margin"),
    (dict(lower=(0.0,), upper=(1.0,), torque_limit=(1.0,), torque_fraction=1.2), "torque_fraction"),
    (dict(lower=(0.0,), upper=(1.0,), torque_limit=(1.0,), max_speed=-1.0), "max_speed"),
])
def test_motion_limits_validation_names_the_field(kwargs, field):
    with pytest.raises(RobofdiError, match=field):
        MotionLimits(**kwargs)


# ---------------------------------------------------------------------------------------------------------------
# Arms with n != 6
# ---------------------------------------------------------------------------------------------------------------
def chain_mjcf(n: int) -> str:
    """An n-joint serial arm: 0.3 m links, yaw joints every third link, pitch joints otherwise."""
    head = '<mujoco model="chain"><compiler angle="radian"/><option timestep="0.001"/><worldbody>'
    body, tail, motors = "", "", ""
    for i in range(n):
        axis = "0 0 1" if i % 3 == 0 else "0 1 0"
        mass = 6.0 * 0.75**i
        pos = "0 0 0.2" if i == 0 else "0 0 0.3"
        body += (f'<body name="l{i}" pos="{pos}"><joint name="j{i}" type="hinge" axis="{axis}" limited="true" '
                 f'range="{-2.0 + 0.1 * i} {2.2 - 0.1 * i}" armature="{0.5 * 0.7**i:.4f}" damping="{2.0 * 0.8**i:.4f}"/>'
                 f'<inertial pos="0 0 0.15" mass="{mass:.4f}" '
                 f'diaginertia="{0.05 * mass:.4f} {0.05 * mass:.4f} {0.01 * mass:.4f}"/>'
                 f'<geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.04"/>')
        tail += "</body>"
        motors += f'<motor joint="j{i}" ctrlrange="{-300 * 0.7**i:.2f} {300 * 0.7**i:.2f}"/>'
    return head + body + tail + "</worldbody><actuator>" + motors + "</actuator></mujoco>"


@pytest.mark.parametrize("n", [3, 7])
def test_motions_for_an_arm_with_another_number_of_joints(tmp_path, n):
    path = tmp_path / f"chain{n}.xml"
    path.write_text(chain_mjcf(n))
    model = ManipulatorModel(path)
    assert model.n == n
    limits = MotionLimits.from_model(model)
    lower, upper = np.array([-2.0 + 0.1 * i for i in range(n)]), np.array([2.2 - 0.1 * i for i in range(n)])
    np.testing.assert_allclose(limits.lower, lower)
    np.testing.assert_allclose(limits.upper, upper)
    motion = random_point_to_point(model, limits, 0, n_segments=3)
    assert motion.start_pose.shape == (n,)
    check_motion(model, motion, lower, upper)
    for m in calibration_motions(model, limits, 0, n_random=1).values():
        check_motion(model, m, lower, upper)
    with pytest.raises(RobofdiError, match="joints"):
        random_point_to_point(ManipulatorModel(ARM), limits, 0)


def test_joint_ranges_names_a_missing_or_unlimited_joint(tmp_path):
    with pytest.raises(RobofdiError, match="joint9"):
        joint_ranges(ARM, ["joint1", "joint9"])
    path = tmp_path / "free.xml"
    path.write_text(chain_mjcf(2).replace('limited="true" ', 'limited="false" ', 1))
    with pytest.raises(RobofdiError, match="'j0'.*no range"):
        joint_ranges(path)
