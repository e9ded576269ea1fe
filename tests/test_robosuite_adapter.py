"""robosuite's Panda with robofdi faults injected where a real robot fails (torques after the controller, joint
sensors before the controller, components in the model), labels in every step's info, and the momentum
diagnosers from a nominal model of the environment's own MJCF — all on robosuite's real MuJoCo simulation."""
from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

pytest.importorskip("robosuite")
from robofdi import RobofdiError  # noqa: E402
from robofdi.adapters import robosuite_diagnosis as rd  # noqa: E402
from robofdi.adapters.robosuite import LABELS_KEY, FaultyRobosuiteEnv  # noqa: E402
from robofdi.evaluate import summarize  # noqa: E402
from robofdi.sims.arm import SensorModel  # noqa: E402

STEPS = 60             # 3 s scripted episodes: the cube is lifted at about 1.8 s
ONSET = 1.0
LOE = f"actuator_loss_of_effectiveness:joint2:0.6@{ONSET}"


@pytest.fixture(scope="module")
def lift():
    env = rd.make_lift()
    yield env
    env.close()


@pytest.fixture(scope="module")
def calibration():
    """Thresholds of the plain momentum diagnoser from 6 fault-free scripted episodes (grasps included)."""
    return rd.calibrate_lift(seeds=range(2000, 2006), steps=STEPS, diagnosers=("momentum",))


def test_nominal_model_is_the_arm_of_the_env_mjcf_with_the_gripper_lumped(lift):
    model = rd.arm_model(lift)                     # no mismatch: the MJCF's own parameters
    assert model.joint_names == [f"joint{i}" for i in range(1, 8)] and model.n == 7
    np.testing.assert_allclose(model.B, np.eye(7))                       # one torque motor per joint, gear 1
    m, d = lift.sim.model._model, mujoco.MjData(lift.sim.model._model)
    wrapped = FaultyRobosuiteEnv(lift, [])
    wrapped.detach()
    arm = wrapped.arm
    g = np.random.default_rng(0)
    q, v = g.uniform(-1, 1, 7), g.uniform(-1, 1, 7)
    d.qpos[:] = m.qpos0
    d.qpos[arm.qpos], d.qvel[arm.dofs] = q, v                          # fingers at their reference, at rest
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, M, d.qM)
    # locking the fingers and lumping the hand into link 7 leaves the arm block of the full dynamics unchanged
    np.testing.assert_allclose(model.mass_matrix(q), M[np.ix_(arm.dofs, arm.dofs)], atol=1e-9)
    np.testing.assert_allclose(model.bias(q, v), d.qfrc_bias[arm.dofs] + m.dof_damping[arm.dofs] * v, atol=1e-9)
    from robofdi.models.multibody import MultibodyModel

    with pytest.raises(RobofdiError, match=r"joints: \['robot0_joint9'\] are not joints of panda"):
        MultibodyModel(m, "panda", joints=["robot0_joint1", "robot0_joint9"])
    with pytest.raises(RobofdiError, match="joints: list them in the model's order"):
        MultibodyModel(m, "panda", joints=["robot0_joint2", "robot0_joint1"])


def test_bad_input_is_one_line_naming_the_target(lift):
    cases = [(["actuator_loss_of_effectiveness:joint8:0.5@1"], "fault target 'joint8': Panda has joints joint1..joint7"),
             (["actuator_additive:gripper0_right_finger_joint1:1@1"], "the gripper is excluded from diagnosis"),
             (["sensor_bias:finger_joint1_pos:0.1@1"], "the gripper is excluded from diagnosis"),
             (["component_mass:link3:1@1"], "component_mass on 'payload'"),
             (["component_leak:joint2:1@1"], "not supported by the robosuite adapter")]
    for faults, message in cases:
        with pytest.raises(RobofdiError, match=message) as err:
            FaultyRobosuiteEnv(lift, faults)
        assert "\n" not in str(err.value)
    with pytest.raises(RobofdiError, match=r"part 'right_gripper': controller SimpleGripController of Panda does not "
                                           r"output joint torques; expected one of OperationalSpaceController"):
        FaultyRobosuiteEnv(lift, [], part="right_gripper")
    with pytest.raises(RobofdiError, match="expected a robosuite robot environment"):
        FaultyRobosuiteEnv(object(), [])
    assert not getattr(lift, "_robofdi_wrapped", False)                 # nothing refused was left attached


def test_actuator_fault_acts_after_the_controller_and_labels_are_in_info(lift):
    env = FaultyRobosuiteEnv(lift, ["actuator_loss_of_effectiveness:joint2:0.5@0.5"], seed=0, sensors=SensorModel.ideal())
    try:
        env.reset()
        for _ in range(20):                                             # 1 s holding the start pose under OSC
            _, _, _, info = env.step(np.zeros(7))
            t_last = env.history["time"][-1]                            # the last substep of this policy step
            labels = info[LABELS_KEY]
            assert labels.shape == (1, 2) and labels[0, 0] == float(t_last >= 0.5)
            u, applied = env.history["u"][-1], env.history["u_applied"][-1]
            assert labels[0, 1] == pytest.approx(applied[1] - u[1], abs=1e-9)
        h = {k: np.array(v) for k, v in env.history.items()}
        after = h["time"] >= 0.5
        np.testing.assert_allclose(h["u_applied"][after, 1], 0.5 * h["u"][after, 1], atol=1e-9)   # joint 2 at 50 %
        np.testing.assert_allclose(h["u_applied"][:, [0, 2, 3, 4, 5, 6]], h["u"][:, [0, 2, 3, 4, 5, 6]], atol=1e-9)
        np.testing.assert_allclose(h["u_applied"][~after], h["u"][~after], atol=1e-9)
        assert np.abs(h["u"][after, 1]).min() > 1.0                     # joint 2 carries the arm's weight
    finally:
        env.detach()


def test_sensor_fault_changes_the_observation_and_what_the_controller_computes_with(lift):
    env = FaultyRobosuiteEnv(lift, ["sensor_bias:joint4_pos:0.05@0.2"], seed=0, sensors=SensorModel.ideal())
    try:
        obs = env.reset()
        controller = lift.robots[0].part_controllers["right"]         # robosuite builds its controllers at reset
        np.testing.assert_allclose(obs["robot0_joint_pos"], lift.sim.data.qpos[env.arm.qpos], atol=1e-12)
        for _ in range(12):
            obs, _, _, info = env.step(np.zeros(7))
            true_q = lift.sim.data.qpos[env.arm.qpos]
            bias = 0.05 if env.time >= 0.2 else 0.0
            assert obs["robot0_joint_pos"][3] - true_q[3] == pytest.approx(bias, abs=1e-12)
            np.testing.assert_allclose(np.delete(obs["robot0_joint_pos"] - true_q, 3), 0, atol=1e-12)
            assert obs["robot0_joint_pos_cos"][3] == pytest.approx(np.cos(true_q[3] + bias))
            # the controller ran its kinematics at the measured state of the last substep, the physics at the true one
            y_true, y_meas = env.history["y_true"][-1], env.history["y_meas"][-1]
            np.testing.assert_allclose(controller.joint_pos, y_meas[:7], atol=1e-12)
            assert controller.joint_pos[3] - y_true[3] == pytest.approx(0.05 if env.history["time"][-1] >= 0.2 else 0,
                                                                         abs=1e-12)
        assert info[LABELS_KEY][0, 0] == 1.0 and info[LABELS_KEY][0, 1] == pytest.approx(0.05)
        faulty_q = lift.sim.data.qpos[env.arm.qpos].copy()
    finally:
        env.detach()
    clean = FaultyRobosuiteEnv(lift, [], seed=0, sensors=SensorModel.ideal())
    try:
        clean.reset()
        for _ in range(12):
            clean.step(np.zeros(7))
        # the OSC acted on the wrong joint angle: the true arm moved away from the fault-free episode's
        moved = np.abs(faulty_q - lift.sim.data.qpos[clean.arm.qpos])
        assert moved.max() > 2e-3, moved             # 4.7 mrad (joint 4), 5.4 mrad (joint 6) here
    finally:
        clean.detach()


def test_component_faults_change_the_model_and_are_undone_at_reset(lift):
    env = FaultyRobosuiteEnv(lift, ["component_mass:payload:1.5@0.1", "component_friction:joint3:2.0@0.1"], seed=0)
    m = lift.sim.model._model
    try:
        env.reset()
        body, dof = env.arm.payload_body, env.arm.dofs[2]
        mass, friction = float(m.body_mass[body]), float(m.dof_frictionloss[dof])
        assert friction > 0                                              # robosuite gives the Panda joints Coulomb friction
        for _ in range(4):
            _, _, _, info = env.step(np.zeros(7))
        assert m.body_mass[body] == pytest.approx(mass + 1.5) and m.dof_frictionloss[dof] == pytest.approx(3 * friction)
        np.testing.assert_allclose(info[LABELS_KEY], [[1.0, 1.5], [1.0, 2.0]])
        env.reset()
        assert m.body_mass[body] == pytest.approx(mass) and m.dof_frictionloss[dof] == pytest.approx(friction)
    finally:
        env.detach()


def test_same_seed_same_episode(lift):
    def episode(seed, raw=lift):
        env = FaultyRobosuiteEnv(raw, ["sensor_outliers:joint3_vel:0.5@0.1;probability=0.2"], seed=seed)
        try:
            obs = env.reset()
            script = rd.LiftScript(seed)
            for _ in range(10):
                obs, *_ = env.step(script(obs))
            return np.array(env.history["y_meas"]), np.array(env.history["u_applied"])
        finally:
            env.detach()

    a, b, c = episode(3), episode(3), episode(4)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])
    fresh = rd.make_lift()                       # another environment (robosuite's construction draw seeded alike)
    try:
        d = episode(3, fresh)
    finally:
        fresh.close()
    assert np.array_equal(a[0], d[0]) and np.array_equal(a[1], d[1])


def test_loe_on_joint2_detected_and_isolated_after_onset_only(lift, calibration):
    for seed in (11, 12):
        ep, record = rd.run_lift(calibration, [LOE], seed, env=lift, steps=STEPS)
        s = summarize(record, "robosuite-lift")["diagnosers"]["momentum"]
        det = s["detections"][0]
        assert s["false_alarms"] == 0 and det["isolated"] == "joint2", (seed, s)
        assert 0 <= det["delay"] <= 0.05 and s["time_to_isolation"][det["fault"]] <= 0.05, (seed, det)
        trace = record.diagnosers["momentum"]
        assert not trace.alarm[trace.time < ONSET].any() and not any(trace.isolated[trace.time < ONSET])
        assert trace.isolated[np.searchsorted(trace.time, ONSET + 0.05)].startswith("joint2")


def test_fault_free_episodes_raise_no_alarm_and_lift_the_cube(lift, calibration):
    for seed in (21, 22):
        ep, record = rd.run_lift(calibration, [], seed, env=lift, steps=STEPS)
        assert ep.success and not record.diagnosers["momentum"].alarm.any(), seed


def test_compensation_of_the_identified_loss_saves_the_lift(lift, calibration):
    lost, _ = rd.run_lift(calibration, [LOE], 11, env=lift, steps=STEPS)
    saved, record = rd.run_lift(calibration, [LOE], 11, accommodation=True, env=lift, steps=STEPS)
    assert not lost.success and lost.cube_height.max() < 0.04
    assert saved.success and saved.cube_height[-1] > 0.1
    assert record.meta["accommodation"] == "EffectivenessCompensation"
    # identified from the residual after isolation (without compensation the arm ends on the table, and the
    # contact torque spoils the estimate: that run is not asserted on)
    assert record.meta["identified_loss"]["momentum"] == {"joint2": pytest.approx(0.6, abs=0.1)}
    u, applied = record.signals["u"], record.u_applied
    late = record.time > ONSET + 0.1
    # the compensation divided the command by 1 − k̂ on joint 2, so the plant receives (1 − k)/(1 − k̂) of u_cmd ≈ u_cmd
    np.testing.assert_allclose(np.median(applied[late, 1] / record.signals["u_cmd"][late, 1]), 1.0, atol=0.1)
    assert np.median(u[late, 1] / record.signals["u_cmd"][late, 1]) == pytest.approx(1 / 0.4, rel=0.2)


def test_robofdi_run_robosuite_lift_writes_the_run_folder(tmp_path, monkeypatch, capsys):
    from robofdi.cli import main

    monkeypatch.setattr(rd, "CALIBRATION_SEEDS", (2000, 2001, 2002))      # a short calibration for the test
    monkeypatch.setattr(rd, "EPISODE_STEPS", STEPS)                       # and 3 s episodes
    assert main(["run", "robosuite-lift", "--out", str(tmp_path), "--quiet"]) == 0
    run = tmp_path / "robosuite-lift-seed0"
    import json

    summary = json.loads((run / "summary.json").read_text())
    assert summary["system"] == "robosuite-Lift-Panda" and summary["controller"] == "OSC_POSE"
    det = summary["diagnosers"]["momentum"]["detections"][0]
    assert det["isolated"] == "joint2" and 0 <= det["delay"] <= 0.05
    task = summary["task"]
    assert task["fault-free"]["success"] and not task["no accommodation"]["success"] and task["compensation"]["success"]
    assert {p.name for p in (run / "figures").iterdir()} >= {"cube_height.png", "residuals_momentum.png"}
    assert (run / "record.h5").is_file() and (run / "compensated.h5").is_file()
    # the replays: the faulty episode's joint 2 ringed from the onset and lit red from its isolation by momentum
    assert (run / "model.xml").is_file() and (run / "replay_compensated.html").is_file()
    clips = _clips(_replay_commands((run / "replay.html").read_text()))
    onset = _first_visible(clips["/meshcat/robot/robot0_link2/fault_onset_robot0_joint2"])
    detected = _first_visible(clips["/meshcat/robot/robot0_link2/fault_detected_robot0_joint2"])
    assert onset == pytest.approx(ONSET, abs=0.02) and detected == pytest.approx(ONSET + det["delay"], abs=0.02)
    capsys.readouterr()
    assert main(["run", "robosuite-lift", "--out", str(tmp_path / "bad"), "--quiet", "--fault",
                 "actuator_additive:joint9:5@1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines()[-1] == "robofdi: error: fault target 'joint9': Panda has joints joint1..joint7"
    assert not (tmp_path / "bad").exists()                                 # refused before anything was simulated


def test_robosuite_campaign_system(tmp_path):
    import pandas as pd

    from robofdi.campaign import load_spec, run_campaign

    spec = load_spec("""
seed = 3
fault_free_runs = 1
faulty_runs = 2
diagnosers = ["momentum"]
[system]
name = "robosuite-lift"
calibration_episodes = 3
episode_steps = 50
[[faults]]
kind = "actuator_loss_of_effectiveness"
targets = ["joint2", "joint4"]
magnitude_fraction = [0.5, 0.7]
onset_fraction = [0.3, 0.5]
""")
    assert spec.faults[0].limits["joint2"] == (1.0, "1")
    run_campaign(spec, tmp_path / "c", workers=1, progress=False)
    rows = pd.read_parquet(tmp_path / "c" / "results.parquet")
    assert rows["error"].isna().all() and (rows["false_alarms"] == 0).all()
    faulty = rows[rows["faulty"]]
    assert faulty["detected"].all() and (faulty["isolated"] == faulty["target"]).all(), faulty
    with pytest.raises(RobofdiError, match=r"system: field 'episode_steps' must be an integer in \[20, 2000\]"):
        load_spec({"system": {"name": "robosuite-lift", "episode_steps": 5}, "fault_free_runs": 1})


# ------------------------------------------------------------------------------------------------ replay
def _replay_commands(html: str) -> list[dict]:
    """The meshcat commands embedded in a static replay html (base64 msgpack blobs)."""
    import base64
    import re

    import umsgpack

    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def _clips(cmds) -> dict:
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    return {a["path"]: a["clip"] for a in anim["animations"]}


def _first_visible(clip) -> float | None:
    """Record time [s] of the first key of a clip's visibility track that shows the object."""
    (track,) = [t for t in clip["tracks"] if t["name"] == ".visible"]
    assert track["keys"][0]["value"] is False
    return next((k["time"] / clip["fps"] for k in track["keys"] if k["value"]), None)


def test_replay_of_an_episode_draws_the_panda_meshes_fingers_cube_and_the_faulty_joint(lift, tmp_path):
    import re

    from robofdi.record import load
    from robofdi.viz import MeshcatScene, write_replay_html
    from robofdi.viz.replay import _resample, resolve_mjcf

    wrapped = FaultyRobosuiteEnv(lift, ["actuator_loss_of_effectiveness:joint2:0.6@0.3"], seed=0)
    try:
        rd.run_lift_episode(wrapped, 0, steps=12)                         # 0.6 s
        wrapped.record("replay-test").save(tmp_path / "record.h5")
        wrapped.write_mjcf(tmp_path)
    finally:
        wrapped.detach()
    record = load(tmp_path / "record.h5")
    m = lift.sim.model._model
    qpos, cols = record.signals["qpos"], record.columns["signals/qpos"]
    assert qpos.shape == (len(record.time), m.nq) and len(cols) == m.nq
    arm = [cols.index(f"robot0_joint{i}") for i in range(1, 8)]
    np.testing.assert_array_equal(qpos[:, arm], record.truth_state[:, :7])          # the same instants as the truth
    table = float(lift.table_offset[2])
    assert np.all(qpos[:, cols.index("cube_joint0_z")] > table)                        # the cube stands on the table
    # the model the record names resolves in its folder, and the replay is drawn from it with the recorded qpos
    assert resolve_mjcf(record, tmp_path) == tmp_path / "model.xml"
    scene = MeshcatScene(tmp_path / "model.xml")
    ft, qs = _resample(record, scene, 50)
    np.testing.assert_allclose(qs[-1], qpos[np.searchsorted(record.time, ft[-1])], atol=1e-9)
    html = write_replay_html(tmp_path / "record.h5", tmp_path / "out" / "replay.html").read_text()
    assert len(html) < 8e6
    assert not re.search(r'(src|href)\s*=\s*["\']?\s*(https?:)?//', html, re.I)
    assert not re.search(r'(fetch|import)\s*\(?\s*["\']https?://', html)
    cmds = _replay_commands(html)
    meshes = {c["path"].split("/")[3] for c in cmds if c["type"] == "set_object"
              and c["object"]["geometries"][0]["type"] == "BufferGeometry"}
    assert {f"robot0_link{i}" for i in range(8)} | {"gripper0_right_leftfinger", "gripper0_right_rightfinger"} <= meshes
    clips = _clips(cmds)
    assert {"/meshcat/robot/cube_main", "/meshcat/robot/gripper0_right_leftfinger"} <= set(clips)
    assert _first_visible(clips["/meshcat/robot/robot0_link2/fault_onset_robot0_joint2"]) == pytest.approx(0.3, abs=0.02)
    assert not any("fault_" in p and "joint4" in p for p in clips)
