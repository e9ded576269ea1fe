"""Any arm a user has: the fixed-base arms robosuite ships (their robot.xml, servos turned into torque motors) and
robofdi's own URDF arm, laid out like a ROS description package. Their calibration motions must stay inside the
joint ranges, velocity and torque limits (checked on the planned motions with the nominal model), the URDF must
be read as ROS ships it (package:// meshes, motors from the effort limits), and a closed-loop diagnosis must find
a torque step on the second joint."""
from __future__ import annotations

import importlib.util
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.config import evolve
from robofdi.control import MotionLimits
from robofdi.mjcf import compile_arm, find_package_root, load_model, urdf_to_mjcf
from robofdi.systems.arm import arm_scenario, calibration, calibration_records, calibration_trajectories
from robofdi.sims import ArmSimulator
from robofdi.sims.arm import full_mass_matrix

URDF = ASSETS / "urdf" / "robofdi_arm4_description" / "urdf" / "robofdi_arm4.urdf"
ROBOSUITE_ARMS = ("iiwa", "jaco", "kinova3", "panda", "sawyer", "ur5e", "spot_arm")


def robosuite_arm(name: str) -> Path:
    spec = importlib.util.find_spec("robosuite")
    if spec is None:
        pytest.skip("robosuite is not installed (pip install -e '.[robosuite]')")
    return Path(spec.origin).parent / "models" / "assets" / "robots" / name / "robot.xml"


@pytest.fixture(autouse=True)
def _own_cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path_factory.getbasetemp() / "cache"))


def urdf_joints(path: Path) -> dict[str, dict]:
    """The URDF's movable joints read straight from the XML (type, limits), independently of robofdi."""
    out = {}
    for j in ET.parse(path).getroot().findall("joint"):
        if j.get("type") == "fixed":
            continue
        lim = j.find("limit")
        out[j.get("name")] = {"type": j.get("type"), **{k: float(v) for k, v in lim.attrib.items()}}
    return out


# ----------------------------------------------------------------------------------------------------------
# MotionLimits: working ranges of continuous and wide joints
# ----------------------------------------------------------------------------------------------------------
def test_working_range_is_one_turn_for_continuous_and_wide_joints():
    inf = np.inf
    limits = MotionLimits.from_ranges([-inf, -2 * np.pi, 0.0, -3.14, -1.0], [inf, 2 * np.pi, 10.0, 3.14, 2.0],
                                      [1.0] * 5, range_margin=0.0)
    np.testing.assert_allclose(limits.working_lower, [-np.pi, -np.pi, 5 - np.pi, -3.14, -1.0])
    np.testing.assert_allclose(limits.working_upper, [np.pi, np.pi, 5 + np.pi, 3.14, 2.0])
    moved = MotionLimits.from_ranges([-inf, 0.0], [inf, 10.0], [1.0, 1.0], centre=(1.0, 9.5), range_margin=0.1)
    np.testing.assert_allclose(moved.working_lower, [1 - np.pi, 10 - 2 * np.pi])      # the turn kept inside [0, 10]
    np.testing.assert_allclose(moved.usable_upper, [1 + np.pi - 0.2 * np.pi, 10 - 0.2 * np.pi])
    with pytest.raises(RobofdiError, match="'lower' < 'upper'.*joints \\[1\\]"):
        MotionLimits.from_ranges([0.0, 1.0], [1.0, np.nan], [1.0, 1.0])
    with pytest.raises(RobofdiError, match="'max_speed' must be > 0"):
        MotionLimits.from_ranges([0.0], [1.0], [1.0], max_speed=0.0)


# ----------------------------------------------------------------------------------------------------------
# URDF as ROS description packages ship it
# ----------------------------------------------------------------------------------------------------------
def test_urdf_arm_compiles_with_package_meshes_and_effort_motors():
    joints = urdf_joints(URDF)
    arm = compile_arm(URDF)
    m = arm.model
    assert arm.system == ET.parse(URDF).getroot().get("name")
    assert arm.joint_names == list(joints)
    np.testing.assert_array_equal(arm.torque_limit, [j["effort"] for j in joints.values()])
    assert m.nmesh == 5
    package = URDF.parents[1]
    files = [Path(e.get("file")) for e in ET.parse(arm.path).getroot().iter("mesh")]
    assert len(files) == 5 and all(f.parent == package / "meshes" for f in files)   # package://robofdi_arm4_description/...
    for name, j in joints.items():
        k = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j["type"] == "continuous":
            assert not m.jnt_limited[k]
        else:
            np.testing.assert_array_equal(m.jnt_range[k], [j["lower"], j["upper"]])
    sim = ArmSimulator(URDF)
    model = sim.nominal_model()
    np.testing.assert_array_equal(model.velocity_limit, [j["velocity"] for j in joints.values()])
    assert sim.physics_dt == 1e-3 and model.path == sim.path == arm.path


def test_urdf_belief_is_read_from_the_same_file_as_the_plant():
    sim = ArmSimulator(URDF)
    model = sim.nominal_model()                       # no mismatch: the belief equals the file's rigid body
    m, d = sim.model, mujoco.MjData(sim.model)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, sim.n)
        d.qpos[:], d.qvel[:] = q, 0.0
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(model.mass_matrix(q), full_mass_matrix(m, d), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(model.gravity(q), d.qfrc_bias, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(model.damping, m.dof_damping)


def test_package_found_through_ros_package_path(tmp_path, monkeypatch):
    lonely = tmp_path / "robot.urdf"                  # no package.xml above it: only $ROS_PACKAGE_PATH can help
    shutil.copy(URDF, lonely)
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    with pytest.raises(RobofdiError, match=r"robot\.urdf.*'robofdi_arm4_description'.*ROS_PACKAGE_PATH"):
        urdf_to_mjcf(lonely)
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(URDF.parents[2]))
    assert find_package_root("robofdi_arm4_description") == URDF.parents[1]
    assert compile_arm(lonely).model.nmesh == 5


@pytest.mark.parametrize("text, expected", [
    ("<robot name='x'><link name='a'>", "not well-formed XML.*expected a URDF <robot>"),
    ("<mujoco/>", "root element <mujoco>; expected <robot>"),
    ("<robot name='x'><link name='a'><visual><geometry><mesh filename='meshes/none.stl'/></geometry></visual></link></robot>",
     "mesh 'meshes/none.stl' resolves to .*none.stl', which does not exist"),
])
def test_malformed_urdf_gives_one_line_naming_the_file(tmp_path, text, expected):
    path = tmp_path / "broken.urdf"
    path.write_text(text)
    with pytest.raises(RobofdiError, match=expected) as err:
        compile_arm(path)
    assert "broken.urdf" in str(err.value) and "\n" not in str(err.value)


# ----------------------------------------------------------------------------------------------------------
# Calibration motions inside every limit (planned, nominal model)
# ----------------------------------------------------------------------------------------------------------
def check_planned_motions(path, seed: int) -> None:
    sc = arm_scenario(path, seed=seed, torque_motors=True)
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    lo, hi = sim.joint_range.T
    speed = model.velocity_limit
    budget = 0.6 * model.torque_limit * (1 + 1e-3)          # MotionLimits' default torque_fraction
    motions = {"motion": sc.motion, **calibration_trajectories(sc, sim, model)}
    for name, motion in motions.items():
        for t in np.arange(0.0, motion.end, 0.02):
            q, v, a = motion(t)
            assert np.all((q >= lo) & (q <= hi)), (name, t, q)
            assert np.all(np.abs(v) <= speed * (1 + 1e-9)), (name, t, v)
            assert np.all(np.abs(model.inverse_dynamics(q, v, a)) <= budget), (name, t)


def test_drive_inertia_gives_plant_and_belief_the_same_rotor_inertia_floor():
    """The URDF has no armature; a floor of 0.002 s² per N·m of torque limit lands in the plant and the belief, and
    a joint that already has more keeps its own (arm6's shoulder: 9 kg·m² > 0.002 · 400)."""
    raw, floored = ArmSimulator(URDF), ArmSimulator(URDF, drive_inertia=0.002)
    np.testing.assert_array_equal(raw.model.dof_armature, 0.0)
    dofs = [d.dof for d in floored.drives]
    np.testing.assert_allclose(floored.model.dof_armature[dofs], 0.002 * floored.torque_limit, rtol=1e-12)
    np.testing.assert_allclose(floored.nominal_model().model.armature, 0.002 * floored.torque_limit, rtol=1e-12)
    arm6 = compile_arm("arm6.xml", drive_inertia=0.002)
    np.testing.assert_allclose(arm6.model.dof_armature, [9.0, 9.0, 2.88, 0.32, 0.32, 0.108])   # all above the floor
    np.testing.assert_allclose(compile_arm("arm6.xml", drive_inertia=0.01).model.dof_armature[5], 0.5)
    for bad in (-1e-3, float("nan"), True, "0.002"):
        with pytest.raises(RobofdiError, match="drive_inertia: expected a finite armature"):
            compile_arm(URDF, drive_inertia=bad)


def test_a_run_on_a_file_without_rotor_inertia_says_so_in_one_line(capsys):
    """`robofdi run arm --robot F` notes the joints F gives no armature, and says nothing where the file gives
    them one or --drive-inertia does."""
    from robofdi.cli import _armature_note

    assert compile_arm(URDF).without_armature == ["joint1", "joint2", "joint3", "joint4"]
    assert compile_arm(URDF, drive_inertia=0.002).without_armature == []
    assert compile_arm("arm6.xml").without_armature == []
    _armature_note("arm", {"robot": str(URDF)})
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and "joint1, joint2, joint3, joint4 no rotor inertia" in lines[0] \
        and "--drive-inertia 0.002" in lines[0]
    for options in ({"robot": str(URDF), "drive_inertia": 0.002}, {"robot": "arm6.xml"}, {}):
        _armature_note("arm", options)
    assert capsys.readouterr().out == ""


def test_a_mesh_too_thin_for_a_solid_gets_shell_inertia(tmp_path):
    """MuJoCo refuses a flat mesh as a solid ("mesh volume is too small"; robosuite's raw sawyer file has two visual
    ones); the arm compiles with that mesh's inertia taken as a shell, and the body keeps the inertia it declares."""
    path = tmp_path / "flat.xml"
    path.write_text("""<mujoco model="flat">
      <asset><mesh name="plate" vertex="0 0 0  0.1 0 0  0.1 0.1 0  0 0.1 0" face="0 1 2  0 2 3  0 2 1  0 3 2"/></asset>
      <worldbody><body name="link"><joint name="j1" axis="0 0 1"/>
        <inertial pos="0 0 0" mass="1.5" diaginertia="0.01 0.02 0.03"/>
        <geom type="mesh" mesh="plate" contype="0" conaffinity="0"/></body></worldbody>
      <actuator><motor name="m1" joint="j1" ctrlrange="-10 10"/></actuator></mujoco>""")
    with pytest.raises(ValueError, match="mesh volume is too small"):
        mujoco.MjModel.from_xml_path(str(path))
    arm = compile_arm(path)
    assert arm.model.body_mass[1] == 1.5
    np.testing.assert_array_equal(arm.model.body_inertia[1], [0.01, 0.02, 0.03])
    assert load_model(path).nmesh == 1


def test_links_that_touch_at_every_pose_turn_as_a_bearing(tmp_path):
    """A turret whose shoulder sphere sits 1 mm into the base pillar it turns on (robosuite's raw sawyer file has
    such a pair, at 0 mm): MuJoCo's parent filter keeps that contact, as the pillar is fixed to the world, and its
    friction brakes the joint. The arm as robofdi compiles it excludes the pair: a 5 N·m torque spins the turret as
    a free rigid body would (τ t / I), and a pair whose distance the joints change keeps its contacts."""
    path = tmp_path / "bearing.xml"
    path.write_text("""<mujoco model="bearing"><compiler angle="radian"/>
      <worldbody><body name="base"><geom name="pillar" type="cylinder" size="0.08 0.12" pos="0 0 0.12"/>
        <body name="turret" pos="0 0 0.08"><joint name="yaw" axis="0 0 1" range="-3 3"/>
          <inertial pos="0 0 0.2" mass="2" diaginertia="0.02 0.02 0.025"/>
          <geom name="shoulder" type="sphere" size="0.07" pos="0.05 0 0.229"/>
          <body name="upper" pos="0.2 0 0.2"><joint name="pitch" axis="0 1 0" range="-0.3 2"/>
            <inertial pos="0 0 0" mass="0.1" diaginertia="1e-3 1e-3 1e-3"/>
            <geom name="elbow" type="sphere" size="0.03" pos="0 0 -0.15"/></body></body></body></worldbody>
      <actuator><motor joint="yaw" ctrlrange="-20 20"/><motor joint="pitch" ctrlrange="-20 20"/></actuator>
    </mujoco>""")
    raw, arm = mujoco.MjModel.from_xml_path(str(path)), compile_arm(path)
    assert raw.nexclude == 0 and arm.model.nexclude == 1
    spins = []
    for m in (raw, arm.model):
        d = mujoco.MjData(m)
        d.ctrl[:] = [5.0, 0.0]
        for _ in range(int(round(0.1 / m.opt.timestep))):
            mujoco.mj_step(m, d)
        spins.append(d.qvel[0])
    inertia_about_yaw = 0.025 + 0.1 * 0.2 ** 2 + 1e-3       # the turret about its axis, the upper body 0.2 m out
    assert spins[0] < 0.1 * 5.0 * 0.1 / inertia_about_yaw                   # braked by the contact
    assert spins[1] == pytest.approx(5.0 * 0.1 / inertia_about_yaw, rel=0.02)
    # the elbow's distance to the pillar changes with pitch: it is not a fixed pair, and at pitch 0.8 it touches
    d = mujoco.MjData(arm.model)
    d.qpos[:] = [0.0, 0.8]
    mujoco.mj_forward(arm.model, d)
    assert d.ncon >= 1


@pytest.mark.parametrize("seed", [3, 5, 11])
@pytest.mark.parametrize("arm", ROBOSUITE_ARMS)
def test_robosuite_arm_calibration_motions_fit_the_limits(arm, seed):
    check_planned_motions(robosuite_arm(arm), seed)


@pytest.mark.parametrize("seed", [3, 5, 11])
def test_urdf_arm_calibration_motions_fit_the_limits(seed):
    check_planned_motions(URDF, seed)


# ----------------------------------------------------------------------------------------------------------
# Closed-loop diagnosis: a 25 % torque step on the second joint at 1 s
# ----------------------------------------------------------------------------------------------------------
def diagnose_second_joint_step(path, seed: int, scheme: str = "momentum", drive_inertia: float = 0.0) -> dict:
    from robofdi.evaluate import summarize
    from robofdi.systems.arm import calibration, run_scenario

    sim = ArmSimulator(path, torque_motors=True, drive_inertia=drive_inertia)
    joint = sim.joint_names[1]
    spec = f"actuator_additive:{joint}:{0.25 * sim.torque_limit[1]:.4g}@1.0"
    sc = arm_scenario(path, faults=[spec], seed=seed, torque_motors=True, drive_inertia=drive_inertia,
                      schemes=(scheme,))
    cal, _ = calibration(sc)
    summary = summarize(run_scenario(sc, cal), "arm", [f.to_dict() for f in sc.faults])
    return joint, summary["diagnosers"][scheme]


@pytest.mark.slow
def test_urdf_arm_diagnoses_a_step_on_its_second_joint():
    joint, result = diagnose_second_joint_step(URDF, 5)
    assert result["false_alarms"] == 0
    (detection,) = result["detections"]
    assert detection["isolated"] == joint and 0 <= detection["delay"] < 0.1


@pytest.mark.slow
def test_robosuite_kinova3_with_continuous_joints_diagnoses_a_step_on_its_second_joint():
    joint, result = diagnose_second_joint_step(robosuite_arm("kinova3"), 5)
    assert result["false_alarms"] == 0
    (detection,) = result["detections"]
    assert detection["isolated"] == joint and 0 <= detection["delay"] < 0.1


@pytest.mark.slow
def test_robosuite_jaco_with_a_drive_inertia_floor_diagnoses_a_step_on_its_second_joint():
    """jaco's raw file gives its wrist 1e-6 kg·m² and no rotor: refused as it is (the wrist leaves its range on
    the calibration motions), diagnosed with the rotor inertia of a geared drive (0.002 s² per N·m)."""
    with pytest.raises(RobofdiError, match="leaves the joint range"):
        diagnose_second_joint_step(robosuite_arm("jaco"), 3)
    joint, result = diagnose_second_joint_step(robosuite_arm("jaco"), 3, drive_inertia=0.002)
    assert result["false_alarms"] == 0
    (detection,) = result["detections"]
    assert detection["isolated"] == joint and 0 <= detection["delay"] < 0.1


def test_campaign_sizes_a_continuous_joints_sensor_faults_on_one_turn():
    """kinova3's continuous joints have no range: a sensor fault drawn as a fraction of the range is sized on one
    turn there (2π rad) and on the range elsewhere, read here from the file with MuJoCo."""
    from robofdi.campaign.spec import parse_spec

    path = robosuite_arm("kinova3")
    m = mujoco.MjModel.from_xml_path(str(path))
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    spans = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j):
             float(np.diff(m.jnt_range[j])[0]) if m.jnt_limited[j] else 2 * np.pi for j in hinges}
    assert any(not m.jnt_limited[j] for j in hinges) and any(m.jnt_limited[j] for j in hinges)
    spec = parse_spec({"seed": 1, "fault_free_runs": 0, "faulty_runs": 1, "diagnosers": ["momentum"],
                       "system": {"name": "arm", "robot": str(path), "torque_motors": True},
                       "faults": [{"kind": "sensor_bias", "targets": ["*_pos"], "magnitude_fraction": [0.01, 0.02]}]})
    (entry,) = spec.faults
    for target, (limit, unit) in entry.limits.items():
        assert unit == "rad" and limit == pytest.approx(spans[target.removesuffix("_pos")])


def test_a_load_the_calibration_motions_cannot_carry_is_refused_naming_it():
    """arm7 carrying 1.5 kg its file lacks: the high-acceleration calibration motion, planned with the nominal
    model at 60 % of each motor's torque, saturates a motor (joint 2 or 6, by the robot instance); calibration is
    refused with the load named."""
    loaded = evolve(arm_scenario("arm7.xml", seed=6121, schemes=("momentum",)), payload=1.5)
    refused = r"'high_acceleration' saturates the motor of 'joint[0-9]'.*lacks the plant's 1.5 kg payload"
    with pytest.raises(RobofdiError, match=refused):
        calibration_records(loaded)


def test_a_declared_load_is_planned_with_and_what_it_lacks_is_identified():
    """The same arm7 and load, 1 kg of it declared (nominal_payload): the calibration motions are planned with the
    declared load and calibrate; the consistency scheme identifies the 0.5 kg the declaration lacks."""
    sc = arm_scenario("arm7.xml", seed=6121, schemes=("consistency",), payload=1.5, nominal_payload=1.0)
    assert sc.nominal_model(sc.simulator()).payload == 1.0
    cal, _ = calibration(sc)
    assert cal.designs["consistency"].payload == pytest.approx(0.5, rel=0.2)


@pytest.mark.parametrize("value", [-1.0, float("nan"), "heavy"])
def test_an_invalid_declared_load_is_refused_naming_the_field(value):
    with pytest.raises(RobofdiError, match="'nominal_payload' must be a finite mass >= 0 kg"):
        arm_scenario("arm6.xml", nominal_payload=value)
