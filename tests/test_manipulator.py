"""The nominal model (Pinocchio, built from MuJoCo's compiled model) against MuJoCo's own dynamics, for arm6,
arm7 (gripper excluded) and a file written with <include>, <default> classes and angle="degree"; and the
drive table shared with the simulator."""
import mujoco
import numpy as np
import pinocchio as pin
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.mjcf import compile_arm
from robofdi.models import ManipulatorModel, ModelMismatch
from robofdi.sims.arm import full_mass_matrix

INCLUDED_LINK = """<mujocoinclude>
  <body name="wrist" pos="0.05 0.02 0.30" axisangle="1 1 0 35">
    <joint name="roll" class="drive" axis="0.3 0.4 0.866" ref="20" range="-150 150"/>
    <joint name="pitch" class="drive" axis="0 1 0" pos="0 0 0.02" range="-90 90"/>
    <geom type="capsule" fromto="0 0 0 0 0 0.15" size="0.03" mass="1.2"/>
    <body name="tool" pos="0 0 0.17" euler="0 30 0">
      <geom type="box" size="0.03 0.02 0.04" mass="0.4"/>
      <body name="jaw" pos="0.03 0 0.05">
        <joint name="jaw" type="hinge" axis="0 1 0" range="-30 30"/>
        <geom type="box" size="0.01 0.01 0.03" mass="0.05"/>
      </body>
    </body>
  </body>
</mujocoinclude>
"""

MAIN = """<mujoco model="generic_arm">
  <compiler angle="degree" autolimits="true"/>
  <option timestep="0.001" gravity="0.5 -0.3 -9.7"/>
  <default>
    <geom contype="0" conaffinity="0"/>
    <default class="drive">
      <joint type="hinge" armature="0.05" damping="0.7" frictionloss="0.3"/>
    </default>
    <default class="heavy">
      <joint armature="0.8" damping="4"/>
    </default>
  </default>
  <worldbody>
    <body name="base" pos="0.1 0 0.2" euler="0 0 30">
      <joint name="swing" class="heavy" axis="0 0 1" range="-170 170"/>
      <inertial pos="0.01 0.02 0.05" mass="3" fullinertia="0.05 0.04 0.03 0.002 -0.001 0.003"/>
      <body name="slider" pos="0 0 0.1">
        <joint name="lift" type="slide" axis="0 0 1" range="-0.1 0.2" armature="2" damping="30" ref="0.05"/>
        <geom type="box" pos="0.1 0 0" size="0.12 0.03 0.03" mass="2"/>
        <body name="weld" pos="0.22 0 0" quat="0.9 0.1 0.3 0.2">
          <geom type="sphere" size="0.04" mass="0.7"/>
          <include file="generic_link.xml"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="pitch" name="m_pitch" gear="50" ctrlrange="-1 1"/>
    <motor joint="swing" name="m_swing" gear="-80" ctrlrange="-2 1.5"/>
    <motor joint="roll" name="m_roll" ctrlrange="-20 20"/>
    <motor joint="lift" name="m_lift" forcerange="-300 300"/>
    <position joint="jaw" name="jaw" kp="20"/>
  </actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def generic(tmp_path_factory):
    folder = tmp_path_factory.mktemp("generic")
    (folder / "generic_link.xml").write_text(INCLUDED_LINK)
    path = folder / "generic_arm.xml"
    path.write_text(MAIN)
    return path


def mujoco_terms(arm, q, v):
    """MuJoCo's arm-DOF block of M and qfrc_bias + damping·q̇, with every non-arm joint at its reference."""
    m = arm.model
    d = mujoco.MjData(m)
    qadr = [dr.qpos for dr in arm.drives]
    dofs = [dr.dof for dr in arm.drives]
    d.qpos[:] = m.qpos0
    d.qpos[qadr], d.qvel[dofs] = q, v
    mujoco.mj_forward(m, d)
    M = full_mass_matrix(m, d)[np.ix_(dofs, dofs)]
    return M, d.qfrc_bias[dofs] + m.dof_damping[dofs] * v


def random_states(model, count, seed):
    rng = np.random.default_rng(seed)
    lo, hi = model.joint_range.T
    for _ in range(count):
        yield rng.uniform(lo, hi), rng.uniform(-2.0, 2.0, model.n)


@pytest.mark.parametrize("name", ["arm6.xml", "arm7.xml", "generic"])
def test_nominal_model_equals_mujoco_without_mismatch(name, generic):
    path = generic if name == "generic" else ASSETS / name
    model = ManipulatorModel(path)
    arm = compile_arm(path)
    worst_M = worst_n = 0.0
    for q, v in random_states(model, 15, seed=11):
        M_mj, n_mj = mujoco_terms(arm, q, v)
        M = model.mass_matrix(q)
        worst_M = max(worst_M, np.max(np.abs(M - M_mj)) / np.max(np.abs(M_mj)))
        worst_n = max(worst_n, np.max(np.abs(model.bias(q, v) - n_mj)) / np.max(np.abs(n_mj)))
        a = np.linspace(-1, 1, model.n)
        np.testing.assert_allclose(model.inverse_dynamics(q, v, a), M_mj @ a + n_mj, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(model.acceleration(q, v, M_mj @ a + n_mj), a, rtol=1e-8, atol=1e-8)
    assert worst_M < 1e-9 and worst_n < 1e-9, (worst_M, worst_n)


def test_arm7_arm_is_found_by_its_motors_and_the_gripper_is_left_out():
    model = ManipulatorModel("arm7.xml")
    assert model.joint_names == [f"joint{i}" for i in range(1, 8)]
    assert model.input_names == model.joint_names
    assert model.measurement_names == [f"joint{i}_pos" for i in range(1, 8)] + [f"joint{i}_vel" for i in range(1, 8)]
    np.testing.assert_allclose(model.torque_limit, [320, 320, 176, 176, 110, 40, 40])
    assert model.system == "arm7"
    # the gripper (0.59 kg) is lumped into link7: the last link carries link7 + hand + fingers
    assert np.isclose(model.model.inertias[7].mass, 1.2 + 0.12 + 0.35 + 0.06 + 0.06)
    np.testing.assert_allclose(model.damping, [5, 5, 3, 3, 1.5, 0.5, 0.5])
    np.testing.assert_allclose(model.model.armature, [1.0, 1.0, 0.5, 0.5, 0.2, 0.1, 0.1])


def test_generic_file_drive_table(generic):
    arm = compile_arm(generic)
    assert arm.system == "generic_arm"
    assert arm.joint_names == ["swing", "lift", "roll", "pitch"]          # file order, not actuator order
    assert [d.actuator for d in arm.drives] == ["m_swing", "m_lift", "m_roll", "m_pitch"]
    assert [d.kind for d in arm.drives] == ["hinge", "slide", "hinge", "hinge"]
    np.testing.assert_allclose([d.gain for d in arm.drives], [-80, 1, 1, 50])
    # negative gear flips the range: ctrl in [-2, 1.5] gives τ in [-120, 160]; forcerange-only slide: ±300 N
    np.testing.assert_allclose(arm.torque_range, [[-120, 160], [-300, 300], [-20, 20], [-50, 50]])
    np.testing.assert_allclose(arm.torque_limit, [160, 300, 20, 50])
    model = ManipulatorModel(generic)
    assert model.measurement_names[:2] == ["swing_pos", "lift_pos"]


def test_matches_pinocchio_mjcf_parser_on_arm6():
    ours = ManipulatorModel("arm6.xml")
    theirs = pin.buildModelFromMJCF(str(ASSETS / "arm6.xml"))
    data = theirs.createData()
    assert [theirs.names[i] for i in range(1, theirs.njoints)] == ours.joint_names
    for q, v in random_states(ours, 10, seed=5):
        M = pin.crba(theirs, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        np.testing.assert_allclose(ours.mass_matrix(q), M, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(ours.bias(q, v), pin.nonLinearEffects(theirs, data, q, v) + theirs.damping * v,
                                   rtol=1e-10, atol=1e-10)


def test_nominal_model_never_sees_the_simulators_changes():
    from robofdi.sims import ArmSimulator

    sim = ArmSimulator("arm7.xml", payload=3.0)
    sim.apply_component_fault("component_mass", "link3", 2.0)
    q = sim.default_positions()
    np.testing.assert_array_equal(sim.nominal_model().mass_matrix(q), ManipulatorModel("arm7.xml").mass_matrix(q))


def test_mismatch_is_seeded_through_the_belief_stream():
    a = ManipulatorModel("arm7.xml", ModelMismatch(mass=0.05, seed=3))
    b = ManipulatorModel("arm7.xml", ModelMismatch(mass=0.05, seed=3))
    c = ManipulatorModel("arm7.xml", ModelMismatch(mass=0.05, seed=4))
    q = np.full(7, 0.2)
    np.testing.assert_array_equal(a.mass_matrix(q), b.mass_matrix(q))
    assert np.max(np.abs(a.mass_matrix(q) - c.mass_matrix(q))) > 1e-4
    with pytest.raises(RobofdiError, match="'seed'"):
        ModelMismatch(seed=-1)


def test_explicit_joints_must_be_known_and_in_file_order(generic):
    with pytest.raises(RobofdiError, match="elbow"):
        ManipulatorModel(generic, joints=["swing", "elbow"])
    with pytest.raises(RobofdiError, match="file's order"):
        ManipulatorModel(generic, joints=["lift", "swing"])
    with pytest.raises(RobofdiError, match="moves with the non-arm joint 'lift'"):
        ManipulatorModel(generic, joints=["swing", "roll"])
    sub = ManipulatorModel(generic, joints=["swing", "lift"])       # wrist locked at its reference
    assert sub.n == 2 and sub.joint_names == ["swing", "lift"]
