"""Tests of robofdi.models (the Pinocchio nominal model) against MuJoCo (spec ch. 3, §6.3), of the deliberate
model mismatch, of the file/joint input checks, and of the determinism of robofdi.sims.ArmSimulator."""
import mujoco
import numpy as np
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch
from robofdi.sims.arm import ArmSimulator, SensorModel, TorqueRipple

ARM = ASSETS / "arm6.xml"
Q0 = np.array([np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0])


@pytest.fixture(scope="module")
def nominal():
    return ManipulatorModel(ARM)


@pytest.fixture(scope="module")
def sim():
    return ArmSimulator(ARM, sensors=SensorModel.ideal())


def random_states(sim, count, seed):
    rng = np.random.default_rng(seed)
    lo, hi = sim.joint_range.T
    for _ in range(count):
        yield rng.uniform(lo, hi), rng.uniform(-2.0, 2.0, sim.n)


def mujoco_mass_matrix(m, d):
    M = np.zeros((m.nv, m.nv))
    try:
        mujoco.mj_fullM(m, d, M)          # MuJoCo >= 4.0
    except TypeError:
        mujoco.mj_fullM(m, M, d.qM)       # older signature
    return M


def mujoco_terms(sim, q, v):
    m, d = sim.model, mujoco.MjData(sim.model)
    d.qpos[:], d.qvel[:] = q, v
    mujoco.mj_forward(m, d)
    return mujoco_mass_matrix(m, d), d.qfrc_bias.copy(), d.qfrc_passive.copy()


# ---------------------------------------------------------------------------------------------------------------
# Pinocchio nominal model == MuJoCo plant when there is no mismatch (spec §6.3: "pin a test on this")
# ---------------------------------------------------------------------------------------------------------------
def test_mass_matrix_matches_mujoco_with_armature_once(nominal, sim):
    for q, v in random_states(sim, 10, seed=0):
        M_mj, _, _ = mujoco_terms(sim, q, v)
        M = nominal.mass_matrix(q)
        np.testing.assert_allclose(M, M_mj, rtol=0, atol=1e-10)
        np.testing.assert_array_equal(M, M.T)
    # the armature is in there exactly once: removing it from MuJoCo leaves a gap of diag(armature)
    m0 = ArmSimulator(ARM).model
    armature = m0.dof_armature.copy()
    assert np.all(armature > 0)
    m0.dof_armature[:] = 0.0
    d0 = mujoco.MjData(m0)
    d0.qpos[:] = Q0
    mujoco.mj_forward(m0, d0)
    np.testing.assert_allclose(nominal.mass_matrix(Q0) - mujoco_mass_matrix(m0, d0), np.diag(armature), atol=1e-10)


def test_bias_matches_mujoco_bias_plus_damping(nominal, sim):
    for q, v in random_states(sim, 10, seed=1):
        _, bias_mj, passive_mj = mujoco_terms(sim, q, v)
        # MuJoCo's damping is a passive force opposing the motion
        np.testing.assert_allclose(passive_mj, -sim.model.dof_damping * v, atol=1e-12)
        np.testing.assert_allclose(nominal.bias(q, v), bias_mj - passive_mj, rtol=0, atol=1e-10)
        np.testing.assert_allclose(nominal.bias(q, v), bias_mj + nominal.damping * v, rtol=0, atol=1e-10)
        np.testing.assert_allclose(nominal.gravity(q), nominal.bias(q, 0 * v), atol=1e-10)


def test_acceleration_matches_mujoco_without_friction(nominal):
    """aba with damping == MuJoCo forward dynamics once the (deliberately unmodelled) frictionloss is off."""
    s = ArmSimulator(ARM)
    s.model.dof_frictionloss[:] = 0.0
    rng = np.random.default_rng(2)
    for q, v in random_states(s, 5, seed=2):
        tau = rng.uniform(-50, 50, 6)
        d = mujoco.MjData(s.model)
        d.qpos[:], d.qvel[:], d.ctrl[:] = q, v, tau
        mujoco.mj_forward(s.model, d)
        np.testing.assert_allclose(nominal.acceleration(q, v, tau), d.qacc, rtol=1e-8, atol=1e-8)


def test_nominal_model_reads_joints_drives_and_limits(nominal, sim):
    assert nominal.joint_names == sim.joint_names == [f"joint{i}" for i in range(1, 7)]
    assert nominal.n == 6
    np.testing.assert_array_equal(nominal.damping, sim.model.dof_damping)
    np.testing.assert_array_equal(nominal.model.armature, sim.model.dof_armature)
    np.testing.assert_array_equal(nominal.torque_limit, [400, 400, 250, 80, 80, 50])
    np.testing.assert_array_equal(nominal.torque_limit, sim.torque_limit)
    assert sim.nominal_model().joint_names == sim.joint_names


# ---------------------------------------------------------------------------------------------------------------
# Deliberate mismatch
# ---------------------------------------------------------------------------------------------------------------
def link_masses(model):
    return np.array([model.model.inertias[i].mass for i in range(1, model.model.njoints)])


def test_mass_mismatch_is_seeded_and_reproducible(nominal):
    a = ManipulatorModel(ARM, ModelMismatch(mass=0.05, seed=1))
    b = ManipulatorModel(ARM, ModelMismatch(mass=0.05, seed=1))
    c = ManipulatorModel(ARM, ModelMismatch(mass=0.05, seed=2))
    m0 = link_masses(nominal)
    np.testing.assert_array_equal(m0, [40, 22, 14, 8, 3, 0.6])
    ma = link_masses(a)
    assert np.all(ma != m0) and np.max(np.abs(ma / m0 - 1)) <= 2 * 0.05 + 1e-12   # 5 % σ, draws truncated at ±2σ
    np.testing.assert_array_equal(ma, link_masses(b))
    assert np.all(link_masses(c) != ma)
    Ma, Mb, Mc, M0 = (x.mass_matrix(Q0) for x in (a, b, c, nominal))
    np.testing.assert_array_equal(Ma, Mb)
    assert np.max(np.abs(Ma - M0)) > 1e-3 and np.max(np.abs(Ma - Mc)) > 1e-3
    # only the masses/inertias were asked for: the drive parameters stay nominal
    np.testing.assert_array_equal(a.damping, nominal.damping)
    np.testing.assert_array_equal(a.model.armature, nominal.model.armature)


def test_drive_mismatch_changes_damping_and_armature(nominal):
    mm = ManipulatorModel(ARM, ModelMismatch(damping=0.1, armature=0.1, seed=4))
    assert np.all(mm.damping != nominal.damping)
    assert np.all(mm.model.armature != nominal.model.armature)
    np.testing.assert_array_equal(link_masses(mm), link_masses(nominal))
    # the perturbed damping is what the bias uses
    v = np.linspace(-1, 1, 6)
    np.testing.assert_allclose(mm.bias(Q0, v) - nominal.bias(Q0, v), (mm.damping - nominal.damping) * v, atol=1e-9)


@pytest.mark.parametrize("robot", ["arm6.xml", "arm7.xml"])
def test_a_declared_load_is_the_plants_payload_in_mujoco(robot):
    """The nominal model carrying a declared 1.5 kg changes the inverse dynamics exactly as the plant's 1.5 kg payload
    changes MuJoCo's (mj_inverse with and without it, frictionloss off); the mismatch draw is unchanged by it."""
    rng = np.random.default_rng(7)
    plain, loaded = (ArmSimulator(robot, payload=kg) for kg in (0.0, 1.5))
    m0, m1 = plain.nominal_model(), plain.nominal_model(payload=1.5)
    lo, hi = plain.joint_range.T
    for _ in range(5):
        q = lo + (hi - lo) * rng.uniform(0.1, 0.9, plain.n)          # inside the ranges: no limit forces
        v, a = rng.uniform(-1, 1, (2, plain.n))
        diff = []
        for s in (plain, loaded):
            s.model.dof_frictionloss[:] = 0.0
            d = mujoco.MjData(s.model)
            d.qpos[s._qadr], d.qvel[s._dofs], d.qacc[s._dofs] = q, v, a
            mujoco.mj_inverse(s.model, d)
            diff.append(d.qfrc_inverse[s._dofs].copy())
        effect = diff[1] - diff[0]
        assert np.abs(effect).max() > 0.5                         # the load matters at these states
        np.testing.assert_allclose(m1.inverse_dynamics(q, v, a) - m0.inverse_dynamics(q, v, a), effect, atol=1e-9)
    seeded = (plain.nominal_model(ModelMismatch(mass=0.1, seed=3), payload=p) for p in (0.0, 1.5))
    masses = [[model.model.inertias[i].mass for i in range(1, model.model.njoints - 1)] for model in seeded]
    assert masses[0] == masses[1]                                  # every link but the payload's, drawn alike


@pytest.mark.parametrize("value", [-0.5, np.nan, np.inf, True, "1"])
def test_an_invalid_declared_load_names_the_field(value):
    with pytest.raises(RobofdiError, match="'payload'.*finite mass >= 0 kg"):
        ManipulatorModel(ARM, payload=value)


@pytest.mark.parametrize("field", ["mass", "inertia", "damping", "armature"])
@pytest.mark.parametrize("value", [-0.01, np.nan, np.inf, 0.6])
def test_invalid_mismatch_names_the_field(field, value):
    with pytest.raises(RobofdiError, match=f"'{field}'"):
        ModelMismatch(**{field: value})


def rotational_inertias(model):
    return np.array([model.model.inertias[i].inertia for i in range(1, model.model.njoints)])


@pytest.mark.parametrize("field", ["mass", "inertia", "damping", "armature"])
@pytest.mark.parametrize("seed", range(8))
def test_largest_accepted_mismatch_gives_a_physical_model(nominal, field, seed):
    """σ = 0.49 is accepted ([0, 0.5)); the draws are truncated at ±2σ, so every perturbed parameter is its nominal
    value times a factor in [1 − 2σ, 1 + 2σ] = [0.02, 1.98]: positive, and the others stay nominal."""
    mm = ManipulatorModel(ARM, ModelMismatch(**{field: 0.49}, seed=seed))
    lo, hi = 1 - 2 * 0.49 - 1e-12, 1 + 2 * 0.49 + 1e-12
    mass = link_masses(mm) / link_masses(nominal)
    # each link's rotational inertia is scaled as a whole (mass factor times the extra inertia factor)
    inertia = np.array([np.sum(a * b) / np.sum(b * b) for a, b in zip(rotational_inertias(mm), rotational_inertias(nominal))])
    np.testing.assert_allclose(rotational_inertias(mm), inertia[:, None, None] * rotational_inertias(nominal), rtol=1e-12)
    damping, armature = mm.damping / nominal.damping, mm.model.armature / nominal.model.armature
    factors = {"mass": mass, "inertia": inertia / mass, "damping": damping, "armature": armature}
    for name, f in factors.items():
        if name == field:
            assert np.all((f >= lo) & (f <= hi)) and np.any(f != 1.0), (name, f)
        else:
            np.testing.assert_allclose(f, 1.0, rtol=1e-12, err_msg=name)
    if field == "mass":          # the rotational inertias scale with the masses
        np.testing.assert_allclose(inertia, mass, rtol=1e-12)
    assert np.min(np.linalg.eigvalsh(mm.mass_matrix(Q0))) > 0


# ---------------------------------------------------------------------------------------------------------------
# Bad files and joints
# ---------------------------------------------------------------------------------------------------------------
def test_missing_mjcf_names_the_file(tmp_path):
    missing = tmp_path / "no_such_arm.xml"
    with pytest.raises(RobofdiError, match="no_such_arm.xml"):
        ManipulatorModel(missing)
    with pytest.raises(RobofdiError, match="no_such_arm.xml"):
        ArmSimulator(missing)
    with pytest.raises(RobofdiError, match="no_such_arm.xml"):
        ManipulatorModel("no_such_arm.xml")         # a bare name is looked up in the assets too


@pytest.mark.parametrize("text", [
    '<mujoco model="broken"><worldbody><body name="a"><joint name="j" type="hinge"/>\n',   # truncated
    "this is not xml at all\n",
])
def test_malformed_mjcf_names_the_file(tmp_path, text):
    path = tmp_path / "broken_arm.xml"
    path.write_text(text)
    with pytest.raises(RobofdiError, match="broken_arm.xml"):
        ManipulatorModel(path)
    with pytest.raises(RobofdiError, match="broken_arm.xml"):
        ArmSimulator(path)


def test_joint_mismatch_names_the_joints(tmp_path, sim):
    text = ARM.read_text()
    assert text.count('"joint3"') >= 2          # joint name and the motor's joint reference
    path = tmp_path / "arm6_renamed.xml"
    path.write_text(text.replace('"joint3"', '"elbow"'))
    model = ManipulatorModel(path)
    assert model.joint_names[2] == "elbow"
    with pytest.raises(RobofdiError) as info:
        model.check_joints(sim.joint_names)
    assert "elbow" in str(info.value) and "joint3" in str(info.value)
    nominal = ManipulatorModel(ARM)
    nominal.check_joints(sim.joint_names)                      # same names, same order: fine
    with pytest.raises(RobofdiError, match="joint"):
        nominal.check_joints(list(reversed(sim.joint_names)))  # order matters


def test_reset_outside_joint_range_names_the_joint(sim):
    q = Q0.copy()
    q[1] = 0.6                                               # joint2 range is [-2.8, 0.5]
    with pytest.raises(RobofdiError, match="joint2"):
        sim.reset(q)
    q = Q0.copy()
    q[4] = -2.3                                              # joint5 range is ±2.2
    with pytest.raises(RobofdiError) as info:
        sim.reset(q)
    assert "joint5" in str(info.value) and "joint2" not in str(info.value)
    with pytest.raises(RobofdiError, match="initial_state"):
        sim.reset(Q0[:5])
    y = sim.reset(Q0)                                        # inside the range: fine, at rest
    np.testing.assert_array_equal(y, np.r_[Q0, np.zeros(6)])


# ---------------------------------------------------------------------------------------------------------------
# Simulator determinism and the ripple
# ---------------------------------------------------------------------------------------------------------------
def run_sim(ripple, n_steps=200, seed=3):
    s = ArmSimulator(ARM, ripple=ripple, seed=seed)
    s.reset(Q0, seed=0)
    g0 = ManipulatorModel(ARM).gravity(Q0)
    states = []
    for k in range(n_steps):
        u = g0 + np.array([30, 30, 20, 5, 5, 2.0]) * np.sin(2 * np.pi * 2.0 * k * s.control_dt)
        s.step(u)
        states.append(s.state)
    return np.array(states)


def test_simulator_is_deterministic_and_ripple_matters():
    a = run_sim(TorqueRipple("physical"))
    b = run_sim(TorqueRipple("physical"))
    np.testing.assert_array_equal(a, b)
    assert np.all(np.isfinite(a)) and np.max(np.abs(a[-1, :6] - Q0)) > 1e-3     # the arm moved
    off = run_sim(TorqueRipple("off"))
    other_seed = run_sim(TorqueRipple("physical"), seed=4)
    assert np.max(np.abs(a - off)) > 1e-6
    assert np.max(np.abs(a - other_seed)) > 1e-6


def test_ripple_torque_is_the_documented_formula():
    """δ_i = Σ_h a_h τmax_i sin(h N_i q_i + φ_h,i) + c_load τ_i sin(N_i q_i + ψ_i) + a_t τmax_i sin(2 G_i q_i + φ_t,i)
    with N_i = 6 G_i, written out from the amplitudes, the file's gear ratios and the seeded phases."""
    r = TorqueRipple("physical")
    s = ArmSimulator(ARM, ripple=r, seed=3)
    G = np.array([150, 150, 120, 80, 80, 60.0])                  # robofdi_gear_ratio in arm6.xml
    tau_max = np.array([400, 400, 250, 80, 80, 50.0])             # the motors' ctrlrange in arm6.xml
    phase = r.terms(tau_max, G, 3)[2]                             # the phases (φ₁, φ₂, φ₃, φ_t), seeded
    psi = r.terms(tau_max, G, 3)[5]
    N = 6 * G
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, tau = rng.uniform(-2, 2, 6), rng.uniform(-1, 1, 6) * tau_max
        expected = (0.01 * tau_max * np.sin(N * q + phase[0]) + 0.004 * tau_max * np.sin(2 * N * q + phase[1])
                    + 0.002 * tau_max * np.sin(3 * N * q + phase[2]) + 0.02 * tau * np.sin(N * q + psi)
                    + 0.005 * tau_max * np.sin(2 * G * q + phase[3]))
        np.testing.assert_allclose(s.ripple_torque(q, tau), expected, rtol=1e-12, atol=1e-12)
    off = ArmSimulator(ARM, ripple=TorqueRipple("off"))
    np.testing.assert_array_equal(off.ripple_torque(Q0, tau), 0.0)
    with pytest.raises(RobofdiError, match="mode"):
        TorqueRipple("loud")
