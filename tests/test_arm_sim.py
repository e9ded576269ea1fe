"""ArmSimulator on any MJCF arm: drive mapping and gear, saturation, servos, gripper exclusion, rates, sensors and
their seed streams, component faults and payload, against real MuJoCo outcomes and independent computations."""
import mujoco
import numpy as np
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.control import ComputedTorque
from robofdi.mjcf import compile_arm
from robofdi.models import ManipulatorModel
from robofdi.protocols import Simulator
from robofdi.sims import ArmSimulator, SensorModel, StribeckFriction, TorqueRipple
from robofdi.sims.arm import add_point_mass, full_mass_matrix

ARM6, ARM7 = ASSETS / "arm6.xml", ASSETS / "arm7.xml"
Q6 = np.array([np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0])
G = 9.81


def quiet(mjcf=ARM7, **kw):
    """Ideal sensors, no ripple, no Stribeck term: only what MuJoCo's file holds."""
    return ArmSimulator(mjcf, sensors=SensorModel.ideal(), ripple=TorqueRipple("off"),
                        friction=StribeckFriction(breakaway=0.0), **kw)


def variant(tmp_path, old, new, source=ARM6, name="variant.xml"):
    text = source.read_text()
    assert text.count(old) == 1, old
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


# ---------------------------------------------------------------------------------------------------------------
# Drives: mapping, gear, saturation
# ---------------------------------------------------------------------------------------------------------------
def test_arm7_interface():
    sim = ArmSimulator(ARM7)
    assert isinstance(sim, Simulator)
    joints = [f"joint{i}" for i in range(1, 8)]
    assert sim.system == "arm7" and sim.actuators == joints and sim.model.nq == 9     # 7 arm + 2 finger joints
    assert sim.sensor_channels == [f"{j}_pos" for j in joints] + [f"{j}_vel" for j in joints]
    assert sim.state_names == [f"{j}_q" for j in joints] + [f"{j}_qd" for j in joints]
    assert sim.units == {"state": ["rad"] * 7 + ["rad/s"] * 7, "u": ["N·m"] * 7, "y": ["rad"] * 7 + ["rad/s"] * 7}
    links = [f"link{i}" for i in range(1, 8)]
    assert sim.component_kinds == {"component_friction": joints, "component_mass": links + ["payload"]}
    assert sim.components == joints + links + ["payload"]
    assert sim.state.shape == (14,) and sim.u_applied.shape == (7,)
    np.testing.assert_allclose(sim.torque_limit, [320, 320, 176, 176, 110, 40, 40])


def test_gear_scaling_gives_the_nominal_models_acceleration():
    """A constant torque on a geared joint (gear 160, ctrl = τ/160) accelerates the arm as M̂⁻¹(τ − ĝ) predicts."""
    sim = quiet()
    sim.model.dof_frictionloss[:] = 0.0           # Coulomb friction is (deliberately) not in the nominal model
    sim.model.dof_armature[7:] = 1e9              # and the fingers are rigid in it: make them rigid here too
    nominal = sim.nominal_model()
    q0 = sim.default_positions()
    sim.reset(q0)
    tau = nominal.gravity(q0)
    tau[2] += 30.0                                 # joint3: drive3, gear 160
    y = sim.step(tau)
    assert sim.data.ctrl[sim.drives[2].actuator_id] == pytest.approx(tau[2] / 160)
    dt = sim.control_dt
    # implicitfast integrates damping implicitly: v1 = dt (M + dt D)⁻¹ (τ − g) from rest
    predicted = dt * np.linalg.solve(nominal.mass_matrix(q0) + dt * np.diag(nominal.damping), tau - nominal.gravity(q0))
    np.testing.assert_allclose(y[7:], predicted, rtol=1e-6, atol=1e-12)
    assert abs(predicted[2]) > 1e-3


def test_each_joint_receives_its_own_torque_whatever_the_actuator_order():
    sim = quiet()
    order = [d.actuator for d in sim.drives]
    assert order == [f"drive{i}" for i in range(1, 8)]
    assert [sim.model.actuator(d.actuator_id).name for d in sim.drives] == order
    assert [d.actuator_id for d in sim.drives] != list(range(7))          # the file lists them in another order
    sim.reset()
    u = np.array([11.0, -12, 13, -14, 15, -16, 17])
    sim.step(u)
    np.testing.assert_allclose(sim.data.qfrc_actuator[[d.dof for d in sim.drives]], u, rtol=1e-12)


def test_saturation_clips_to_ctrlrange_and_forcerange():
    sim = quiet()
    sim.reset()
    u = 10 * np.array([320, -320, 176, -176, 110, -40, 40.0])
    sim.step(u)
    np.testing.assert_array_equal(sim.u_applied, np.sign(u) * sim.torque_limit)
    # what MuJoCo applied is the clipped torque (drive6: forcerange tighter than ctrlrange; drive7: forcerange only)
    np.testing.assert_allclose(sim.data.qfrc_actuator[:7], sim.u_applied, rtol=1e-12)
    np.testing.assert_array_equal(sim.saturate(u), sim.u_applied)
    for _ in range(50):
        sim.step(u)
    assert np.all(np.isfinite(sim.state))
    with pytest.raises(RobofdiError, match="7 finite joint torques"):
        sim.step(np.zeros(9))
    with pytest.raises(RobofdiError, match="finite"):
        sim.step(np.r_[np.nan, np.zeros(6)])


def test_gripper_is_simulated_but_not_in_the_arm():
    sim = quiet()
    fingers = [sim.model.joint(n).qposadr[0] for n in ("finger_left", "finger_right")]
    g = sim.nominal_model()
    y = sim.reset()
    for _ in range(200):
        y = sim.step(g.gravity(y[:7]))
    assert y.shape == (14,)
    np.testing.assert_allclose(sim.data.qpos[fingers], 0.0, atol=1e-3)     # held by their servos at ctrl 0
    assert all("finger" not in c for c in sim.components + sim.sensor_channels)


# ---------------------------------------------------------------------------------------------------------------
# Servos, explicit joints, malformed files
# ---------------------------------------------------------------------------------------------------------------
SERVO3 = '<position name="servo3" joint="joint3" kp="2000" gear="2" forcerange="-125 125"/>'


def test_position_servo_rejected_with_a_clear_message_and_converted_on_request(tmp_path):
    path = variant(tmp_path, '<motor name="joint3" joint="joint3" ctrlrange="-250 250"/>', SERVO3)
    with pytest.raises(RobofdiError) as info:
        ArmSimulator(path)
    message = str(info.value)
    assert "'servo3'" in message and "position servo" in message and "torque_motors=True" in message
    assert "variant.xml" in message and "\n" not in message
    with pytest.raises(RobofdiError, match="servo3"):
        ArmSimulator(path, joints=[f"joint{i}" for i in range(1, 7)])
    sim = quiet(path, torque_motors=True)
    assert sim.joint_names == [f"joint{i}" for i in range(1, 7)]
    np.testing.assert_allclose(sim.torque_limit, [400, 400, 250, 80, 80, 50])    # forcerange 125 x gear 2
    np.testing.assert_allclose(sim.nominal_model().torque_limit, sim.torque_limit)
    sim.reset(Q6)
    u = np.zeros(6)
    u[2] = 100.0
    sim.step(u)
    assert sim.data.ctrl[sim.drives[2].actuator_id] == pytest.approx(50.0)      # a motor now: ctrl = τ / gear
    assert sim.data.qfrc_actuator[2] == pytest.approx(100.0)
    # with torque_motors every servo-driven joint is an arm joint unless the joints are named
    assert compile_arm(ARM7, torque_motors=True).joint_names[-2:] == ["finger_left", "finger_right"]
    with pytest.raises(RobofdiError, match="robofdi_gear_ratio.*9 finite values"):      # arm7 lists 7 gear ratios
        ArmSimulator(ARM7, torque_motors=True)
    assert ArmSimulator(ARM7, torque_motors=True, joints=[f"joint{i}" for i in range(1, 8)]).n == 7


def test_a_file_without_actuators_is_told_how_to_add_them_and_runs_once_a_wrapper_does(tmp_path):
    """A dynamics-only file (dm_control's Jaco arm has no <actuator>): one line naming the file and what to add; a
    file that includes it and adds the motors runs as it is."""
    text = ARM6.read_text()
    actuators = text[text.index("<actuator>"):text.index("</actuator>") + len("</actuator>")]
    bare = variant(tmp_path, actuators, "", name="bare.xml")
    with pytest.raises(RobofdiError) as info:
        ArmSimulator(bare)
    message = str(info.value)
    assert "bare.xml" in message and "no joint actuators" in message and '<include file="bare.xml"/>' in message
    assert "<motor" in message and "\n" not in message
    wrapper = tmp_path / "with_motors.xml"
    wrapper.write_text(f'<mujoco model="with_motors"><include file="bare.xml"/>{actuators}</mujoco>')
    np.testing.assert_allclose(quiet(wrapper).torque_limit, quiet(ARM6).torque_limit)


def test_torque_motors_takes_the_joint_actuatorfrcrange_or_refuses(tmp_path):
    servo = '<position name="servo3" joint="joint3" kp="2000"/>'
    path = variant(tmp_path, '<motor name="joint3" joint="joint3" ctrlrange="-250 250"/>', servo)
    with pytest.raises(RobofdiError, match="servo3.*forcerange"):
        ArmSimulator(path, torque_motors=True)
    bounded = variant(tmp_path, 'armature="2.88" damping="10"', 'armature="2.88" actuatorfrcrange="-222 222" damping="10"',
                      source=path, name="bounded.xml")
    np.testing.assert_allclose(ArmSimulator(bounded, torque_motors=True).torque_limit[2], 222)


def test_explicit_joints_are_checked(tmp_path):
    with pytest.raises(RobofdiError, match="'elbow'.*not joints"):
        ArmSimulator(ARM7, joints=["joint1", "elbow"])
    with pytest.raises(RobofdiError, match="file's order"):
        ArmSimulator(ARM7, joints=["joint2", "joint1"])
    with pytest.raises(RobofdiError, match="finger_left.*position servo"):
        ArmSimulator(ARM7, joints=[f"joint{i}" for i in range(1, 8)] + ["finger_left"])
    no_motor = variant(tmp_path, '<motor name="joint6" joint="joint6" ctrlrange="-50 50"/>', "")
    with pytest.raises(RobofdiError, match="'joint6'.*0 joint actuators"):
        ArmSimulator(no_motor, joints=[f"joint{i}" for i in range(1, 7)])
    with pytest.raises(RobofdiError, match="robofdi_gear_ratio.*5 finite values"):
        ArmSimulator(no_motor)                                # automatic: joint6 is not in the arm, 6 gear ratios
    five = variant(tmp_path, 'data="150 150 120 80 80 60"', 'data="150 150 120 80 80"', source=no_motor, name="five.xml")
    assert ArmSimulator(five).n == 5
    ball = variant(tmp_path, '<joint name="joint6" type="hinge" axis="0 0 -1" range="-3.14 3.14"',
                   '<joint name="joint6" type="ball"', name="ball.xml")
    with pytest.raises(RobofdiError, match="'joint6'.*ball joint"):
        ArmSimulator(ball, joints=[f"joint{i}" for i in range(1, 7)])


def test_unbounded_drive_is_refused(tmp_path):
    path = variant(tmp_path, '<motor name="joint6" joint="joint6" ctrlrange="-50 50"/>', '<motor name="joint6" joint="joint6"/>')
    with pytest.raises(RobofdiError, match="'joint6'.*bounds the torque"):
        ArmSimulator(path)


@pytest.mark.parametrize("text", [
    '<mujoco model="broken"><worldbody><body name="a"><joint name="j" type="hinge"/>\n',
    '<mujoco><worldbody><body><joint type="spiral"/></body></worldbody></mujoco>\n',
])
def test_malformed_mjcf_is_one_line_naming_file_and_mujocos_message(tmp_path, text):
    path = tmp_path / "broken_arm.xml"
    path.write_text(text)
    with pytest.raises(RobofdiError) as info:
        ArmSimulator(path)
    message = str(info.value)
    assert "broken_arm.xml" in message and "\n" not in message
    assert "XML" in message or "spiral" in message


def test_system_label_is_the_model_name_else_the_file_stem(tmp_path):
    assert ArmSimulator(ARM6).system == "arm6"
    path = variant(tmp_path, '<mujoco model="arm6">', "<mujoco>", name="nameless_arm.xml")
    assert ArmSimulator(path).system == "nameless_arm"


# ---------------------------------------------------------------------------------------------------------------
# Rates and reset
# ---------------------------------------------------------------------------------------------------------------
def test_physics_step_from_the_file_and_control_dt_validation():
    a7, a6 = ArmSimulator(ARM7), ArmSimulator(ARM6)
    assert (a7.physics_dt, a7.control_dt, a7.substeps) == (0.002, 0.002, 1)
    assert (a6.physics_dt, a6.control_dt, a6.substeps) == (0.0005, 0.001, 2)
    assert ArmSimulator(ARM7, control_dt=0.004).substeps == 2
    assert ArmSimulator(ARM6, 1.5e-3).substeps == 3                     # positional, as before
    for bad in (0.003, 0.001, -0.002, 0.0, np.nan):
        with pytest.raises(RobofdiError) as info:
            ArmSimulator(ARM7, control_dt=bad)
        assert "control_dt" in str(info.value) and "0.002" in str(info.value)
    a7.reset()
    for _ in range(5):
        a7.step(np.zeros(7))
    assert a7.time == pytest.approx(5 * 0.002)


def test_reset_defaults_to_the_home_keyframe_and_checks_the_state():
    sim = ArmSimulator(ARM7, sensors=SensorModel.ideal())
    home = np.radians([0, 30, 0, -60, 0, 60, 0])
    np.testing.assert_allclose(sim.reset(), np.r_[home, np.zeros(7)], atol=1e-4)
    x0 = np.r_[home, 0.1 * np.ones(7)]
    np.testing.assert_array_equal(sim.reset(x0), x0)
    q = home.copy()
    q[3] = np.radians(125)
    with pytest.raises(RobofdiError, match="joint4"):
        sim.reset(q)
    with pytest.raises(RobofdiError, match="initial_state"):
        sim.reset(np.zeros(8))
    np.testing.assert_array_equal(ArmSimulator(ARM6).default_positions(), np.zeros(6))   # no keyframe: qpos0


# ---------------------------------------------------------------------------------------------------------------
# Sensors and seed streams
# ---------------------------------------------------------------------------------------------------------------
def open_loop(sim, seed, steps=300):
    sim.reset(seed=seed)
    g = sim.nominal_model().gravity(sim.default_positions())
    ys, xs = [], []
    for k in range(steps):
        ys.append(sim.step(g + 3.0 * np.sin(0.05 * k)))
        xs.append(sim.state)
    return np.array(ys), np.array(xs)


def test_positions_are_quantised_to_the_encoder_resolution():
    sim = ArmSimulator(ARM7)
    y, x = open_loop(sim, seed=1, steps=100)
    res = 2 * np.pi / 2**20
    counts = y[:, :7] / res
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    assert np.max(np.abs(y[:, :7] - x[:, :7])) <= res / 2 + 1e-15
    assert np.ptp(x[:, :7]) > 100 * res                                   # the arm moved many counts


def test_noise_streams_are_reproducible_independent_and_per_run():
    sim = ArmSimulator(ARM7, seed=0)
    y1, x1 = open_loop(sim, seed=5, steps=1500)
    y2, x2 = open_loop(sim, seed=5, steps=1500)
    np.testing.assert_array_equal(y1, y2)
    noise = y1[:, 7:] - x1[:, 7:]
    np.testing.assert_allclose(noise.std(axis=0), 1e-3, rtol=0.1)
    corr = np.corrcoef(noise.T)
    assert np.max(np.abs(corr - np.eye(7))) < 4 / np.sqrt(len(noise))        # uncorrelated channels
    y3, x3 = open_loop(sim, seed=6, steps=1500)
    np.testing.assert_array_equal(x3, x1)                 # same robot (ripple phases), same plant motion
    assert np.max(np.abs(y3[:, 7:] - y1[:, 7:])) > 1e-3   # a different run seed: different noise
    assert abs(np.corrcoef((y3[:, 7:] - x3[:, 7:]).ravel(), noise.ravel())[0, 1]) < 0.05
    _, x4 = open_loop(ArmSimulator(ARM7, seed=1), seed=5, steps=1500)
    assert np.max(np.abs(x4 - x1)) > 1e-6                 # another robot seed: other ripple phases
    y5, _ = open_loop(sim, seed=np.random.SeedSequence(5), steps=20)
    np.testing.assert_array_equal(y5, y1[:20])            # an int seed and its SeedSequence are the same stream
    with pytest.raises(RobofdiError, match="seed"):
        ArmSimulator(ARM7, sensors=SensorModel.ideal()).reset(seed=-1)


def test_ripple_frequencies_come_from_the_gear_ratios():
    gear = np.array([150, 150, 120, 80, 80, 60.0])
    assert np.array_equal(ArmSimulator(ARM6).settings.gear_ratio, gear)
    amp, freq, phase, load, load_freq, _ = TorqueRipple().terms(np.full(6, 100.0), gear, seed=0)
    np.testing.assert_array_equal(freq, [6 * gear, 12 * gear, 18 * gear, 2 * gear])
    np.testing.assert_allclose(amp[:, 0], [1.0, 0.4, 0.2, 0.5])
    _, low, _, _, _, _ = TorqueRipple("low").terms(np.full(6, 100.0), gear, seed=0)
    assert low[0].max() == pytest.approx(40.0)
    _, _, phase_again, _, _, _ = TorqueRipple("low").terms(np.full(6, 100.0), gear, seed=0)
    np.testing.assert_array_equal(phase, phase_again)
    assert np.array_equal(ArmSimulator(ARM7).settings.gear_ratio, [160, 160, 160, 160, 100, 100, 100])


@pytest.mark.parametrize("mjcf", [ARM6, ARM7])
def test_stribeck_term_does_not_chatter_under_computed_torque(mjcf):
    """Fault-free computed torque on a slow back-and-forth motion (velocity reversals every 0.5 s), at the file's
    physics step (0.5 ms for arm6, 2 ms for arm7): the breakaway term must not make the torque chatter."""
    def run(breakaway):
        sim = ArmSimulator(mjcf, sensors=SensorModel.ideal(), friction=StribeckFriction(breakaway=breakaway))
        model = sim.nominal_model()
        ctrl = ComputedTorque(model, torque_limit=model.torque_limit)
        q0 = Q6 if mjcf == ARM6 else sim.default_positions()
        y = sim.reset(q0, seed=0)
        us = []
        for k in range(int(1.0 / sim.control_dt)):
            wt, w = 2 * np.pi * k * sim.control_dt, 2 * np.pi
            ref = (q0 + 0.05 * (1 - np.cos(wt)), np.full(sim.n, 0.05 * w * np.sin(wt)),
                   np.full(sim.n, 0.05 * w * w * np.cos(wt)))
            y = sim.step(ctrl.update(y, ref))
            us.append(sim.u_applied)
        return np.array(us), np.abs(sim.state[:sim.n] - ref[0])

    u_s, err_s = run(0.3)
    u_0, _ = run(0.0)
    assert np.all(np.isfinite(u_s)) and np.max(err_s) < 0.05
    jerk = lambda u: np.sqrt(np.mean(np.diff(u, 2, axis=0) ** 2, axis=0))       # noqa: E731
    assert np.all(jerk(u_s) <= 1.5 * jerk(u_0) + 0.05), (jerk(u_s), jerk(u_0))


# ---------------------------------------------------------------------------------------------------------------
# Component faults and payload
# ---------------------------------------------------------------------------------------------------------------
def gravity_and_mass(sim, q):
    m, d = sim.model, mujoco.MjData(sim.model)
    d.qpos[sim.drives[0].qpos: sim.drives[-1].qpos + 1] = q
    mujoco.mj_forward(m, d)
    return d.qfrc_bias[:sim.n].copy(), full_mass_matrix(m, d)[:sim.n, :sim.n], d


def point_gravity_torque(sim, d, body, point_in_body, mass):
    """Σ over joints: ((p − anchor) × m g) · axis, and the point mass's M contribution Jᵀ m J."""
    b = sim.model.body(body).id
    p = d.xpos[b] + d.xmat[b].reshape(3, 3) @ point_in_body
    tau = np.zeros(sim.n)
    for i, drive in enumerate(sim.drives):
        if np.dot(p, p) >= 0 and drive.body in ancestors(sim.model, b):
            r = p - d.xanchor[drive.joint_id]
            tau[i] = np.cross(r, [0, 0, -mass * G]) @ d.xaxis[drive.joint_id]
    jac = np.zeros((3, sim.model.nv))
    mujoco.mj_jac(sim.model, d, jac, None, p, b)
    J = jac[:, :sim.n]
    return -tau, mass * J.T @ J                  # qfrc_bias holds +g(q) = −(generalised gravity force)


def ancestors(m, b):
    names = []
    while b > 0:
        names.append(m.body(b).name)
        b = m.body_parentid[b]
    return names


@pytest.mark.parametrize("target", ["link3", "link5", "payload"])
def test_component_mass_adds_a_point_mass(target):
    sim = quiet(ARM6)
    before = {k: getattr(sim.model, k).copy()
              for k in ("body_mass", "body_ipos", "body_iquat", "body_inertia", "body_sameframe", "dof_M0")}
    g0, M0, d0 = gravity_and_mass(sim, Q6)
    body = "link6" if target == "payload" else target
    b = sim.model.body(body).id
    point = np.array([0, 0, -0.10]) if target == "payload" else sim.model.body_ipos[b].copy()
    sim.apply_component_fault("component_mass", target, 2.5)
    assert sim.model.body_mass[b] == pytest.approx(before["body_mass"][b] + 2.5)
    g1, M1, _ = gravity_and_mass(sim, Q6)
    dg, dM = point_gravity_torque(sim, d0, body, point, 2.5)
    assert np.max(np.abs(dg)) > 0.5
    np.testing.assert_allclose(g1 - g0, dg, atol=1e-9)
    np.testing.assert_allclose(M1 - M0, dM, atol=1e-9)                     # inertia: parallel-axis theorem
    sim.apply_component_fault("component_mass", target, 0.0)
    for k, v in before.items():
        np.testing.assert_array_equal(getattr(sim.model, k), v)
    np.testing.assert_array_equal(gravity_and_mass(sim, Q6)[0], g0)


def test_payload_field_uses_the_payload_point():
    base, loaded = quiet(ARM6), quiet(ARM6, payload=6.0)
    g0, _, d0 = gravity_and_mass(base, Q6)
    g1, _, _ = gravity_and_mass(loaded, Q6)
    dg, _ = point_gravity_torque(base, d0, "link6", np.array([0, 0, -0.10]), 6.0)
    np.testing.assert_allclose(g1 - g0, dg, atol=1e-9)
    loaded.apply_component_fault("component_mass", "payload", 1.0)      # on top of the constant payload
    g2, _, _ = gravity_and_mass(loaded, Q6)
    dg7, _ = point_gravity_torque(base, d0, "link6", np.array([0, 0, -0.10]), 7.0)
    np.testing.assert_allclose(g2 - g0, dg7, atol=1e-9)


def test_add_point_mass_keeps_a_valid_principal_frame():
    mass, com, quat, inertia = add_point_mass(2.0, np.array([0.1, 0, 0]), np.array([1.0, 0, 0, 0]),
                                              np.array([0.01, 0.02, 0.03]), 1.0, np.array([0, 0.2, 0.1]))
    assert mass == 3.0
    np.testing.assert_allclose(com, [0.2 / 3, 0.2 / 3, 0.1 / 3])
    assert np.linalg.norm(quat) == pytest.approx(1.0) and np.all(inertia > 0)
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, quat)
    R = R.reshape(3, 3)
    assert np.linalg.det(R) == pytest.approx(1.0)
    # trace is invariant under rotation; a point mass m at r adds 2 m |r|² to it (parallel-axis theorem)
    r_body, r_point = np.array([0.1, 0, 0]) - com, np.array([0, 0.2, 0.1]) - com
    assert np.sum(inertia) == pytest.approx(0.06 + 2 * 2.0 * r_body @ r_body + 2 * 1.0 * r_point @ r_point)


def coast(sim, rise):
    """Joint1 (vertical axis, no gravity) coasting from 1 rad/s while gravity is held: time to stop [s]."""
    sim.apply_component_fault("component_friction", "joint1", rise) if rise else None
    g = sim.nominal_model()
    y = sim.reset(np.r_[Q6, 1.0, np.zeros(5)], seed=0)
    sim.apply_component_fault("component_friction", "joint1", rise)
    for k in range(2000):
        y = sim.step(g.gravity(y[:6]))
        if abs(sim.state[6]) < 1e-3:
            return (k + 1) * sim.control_dt, sim.state
    return np.inf, sim.state


def test_component_friction_makes_a_coasting_joint_stop_sooner():
    sim = quiet(ARM6)
    frictionloss0, damping0 = sim.model.dof_frictionloss.copy(), sim.model.dof_damping.copy()
    t_nominal, x_nominal = coast(sim, 0.0)
    t_worn, _ = coast(sim, 1.0)
    assert sim.model.dof_frictionloss[0] == 2 * frictionloss0[0] and sim.model.dof_damping[0] == 2 * damping0[0]
    assert np.isfinite(t_nominal) and t_worn < 0.8 * t_nominal
    sim.apply_component_fault("component_friction", "joint1", 0.0)
    np.testing.assert_array_equal(sim.model.dof_frictionloss, frictionloss0)
    np.testing.assert_array_equal(sim.model.dof_damping, damping0)
    t_again, x_again = coast(sim, 0.0)
    assert t_again == t_nominal
    np.testing.assert_array_equal(x_again, x_nominal)


def test_component_fault_inputs_are_checked_and_reset_restores():
    sim = ArmSimulator(ARM6)
    with pytest.raises(RobofdiError, match="component_leak"):
        sim.apply_component_fault("component_leak", "joint1", 1.0)
    with pytest.raises(RobofdiError, match="'link9'"):
        sim.apply_component_fault("component_mass", "link9", 1.0)
    with pytest.raises(RobofdiError, match=">= 0 kg"):
        sim.apply_component_fault("component_mass", "link2", -1.0)
    with pytest.raises(RobofdiError, match="> -1"):
        sim.apply_component_fault("component_friction", "joint2", -1.5)
    mass0 = sim.model.body_mass.copy()
    sim.apply_component_fault("component_mass", "link2", 1.0)
    sim.reset(Q6)
    np.testing.assert_array_equal(sim.model.body_mass, mass0)


def test_nominal_model_of_the_simulator_matches_a_fresh_one():
    sim = ArmSimulator(ARM7)
    fresh = ManipulatorModel(ARM7)
    assert sim.nominal_model().joint_names == fresh.joint_names == sim.joint_names
    np.testing.assert_array_equal(sim.nominal_model().torque_limit, sim.torque_limit)
