"""Headless tests of the meshcat replay front-end (viz/)."""
from __future__ import annotations

import base64
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("meshcat")
pytest.importorskip("mujoco")
import umsgpack  # noqa: E402  (installed with meshcat)

import robofdi  # noqa: E402
from robofdi import RobofdiError  # noqa: E402
from robofdi.record import DiagnoserTrace, Record  # noqa: E402
from robofdi.viz import MeshcatScene, build_replay, fault_joint, isolated_joints, write_replay_html  # noqa: E402
from robofdi.viz.replay import close_visualizer  # noqa: E402

ARM_ORANGE = np.array([0.85, 0.45, 0.10])


def _quintic(t, T):
    s = np.clip(t / T, 0, 1)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / T


def make_record(diag_isolated="joint3", diag_from=0.45) -> Record:
    """1 s at 100 Hz, quintic joint motion, a joint3 actuator fault at 0.4 s, isolated from 0.45 s."""
    t = np.arange(100) / 100.0
    q0 = np.array([0.0, -0.6, 0.9, 0.0, 0.6, 0.0])
    q1 = np.array([1.2, -1.0, 1.5, 1.0, -0.4, 1.5])
    s, sd = _quintic(t, 1.0)
    q = q0 + np.outer(s, q1 - q0)
    qd = np.outer(sd, q1 - q0)
    td = np.arange(0, 1.0, 0.01)
    iso = np.array([diag_isolated if x >= diag_from - 1e-9 else "" for x in td], dtype=object)
    M = td.size
    trace = DiagnoserTrace(time=td, residual=np.zeros((M, 6)), threshold=np.ones(6), alarm=np.zeros((M, 6), bool),
                           isolated=iso, estimate=np.zeros((M, 1)), components=[f"joint{i}" for i in range(1, 7)])
    return Record(system="arm6", scenario="test", seed=0, rates={"control": 100.0}, time=t,
                  truth_state=np.hstack([q, qd]), diagnosers={"gom": trace},
                  meta={"mjcf": "arm6.xml", "primary_diagnoser": "gom",
                        "faults": [{"name": "f1", "kind": "actuator_bias", "target": "joint3", "onset": 0.4,
                                    "end": None}]})


def decode_commands(html: str) -> list[dict]:
    """The meshcat commands embedded in a static html (base64 msgpack blobs)."""
    blobs = re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)', html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


@pytest.fixture(scope="module")
def replay_html(tmp_path_factory):
    path = write_replay_html(make_record(), tmp_path_factory.mktemp("viz") / "replay.html", fps=25)
    return path


# ------------------------------------------------------------------------------ scene
def test_scene_geoms_and_kinematics():
    scene = MeshcatScene(robofdi.ASSETS / "arm6.xml")
    types = {gs.type for gs in scene.geoms}
    assert {"plane", "cylinder", "box"} <= types
    assert all(gs.path.startswith(gs.body + "/geom_") for gs in scene.geoms)
    q = np.array([0.3, -0.5, 0.8, 0.2, 0.4, -0.1])
    Tb = scene.body_transforms(q)
    Tg = scene.geom_transforms(q)
    # geom world pose == body world pose @ fixed local pose, for every geom
    for gs in scene.geoms:
        np.testing.assert_allclose(Tb[gs.body] @ gs.local, Tg[gs.path], atol=1e-9)
    # a fromto cylinder along the link-2 y axis: meshcat's y axis must map onto it
    link2_cyl = next(gs for gs in scene.geoms if gs.body == "link2" and gs.type == "cylinder")
    np.testing.assert_allclose(abs(Tg[link2_cyl.path][:3, 1] @ Tb["link2"][:3, 1]), 1.0, atol=1e-9)
    with pytest.raises(RobofdiError, match="qpos"):
        scene.body_transforms(np.zeros(3))


def test_missing_mjcf_names_file(tmp_path):
    missing = tmp_path / "nope.xml"
    with pytest.raises(RobofdiError, match="nope.xml"):
        MeshcatScene(missing)


def test_malformed_mjcf_names_file(tmp_path):
    bad = tmp_path / "broken_arm.xml"
    bad.write_text("<mujoco><worldbody><body name='a'><geom type='box' size='1 1 1'/></worldbody></mujoco>")
    with pytest.raises(RobofdiError, match="broken_arm.xml"):
        MeshcatScene(bad)


def test_a_mesh_too_thin_for_a_solid_is_drawn_as_the_simulator_compiles_it(tmp_path):
    """An arm file MuJoCo's own loader refuses ("mesh volume is too small": robosuite's raw baxter and sawyer files)
    runs, because robofdi.mjcf gives that mesh shell inertia; the replay of the run loads the file the same way
    instead of failing after the run (measured on baxter: 70 s of calibration and runs, then the error)."""
    import mujoco

    path = tmp_path / "flat.xml"
    path.write_text("""<mujoco model="flat">
      <asset><mesh name="plate" vertex="0 0 0  0.1 0 0  0.1 0.1 0  0 0.1 0" face="0 1 2  0 2 3  0 2 1  0 3 2"/></asset>
      <worldbody><body name="link"><joint name="j1" axis="0 0 1"/>
        <geom type="mesh" mesh="plate" contype="0" conaffinity="0" mass="0.2"/></body></worldbody>
      <actuator><motor name="m1" joint="j1" ctrlrange="-10 10"/></actuator></mujoco>""")
    with pytest.raises(ValueError, match="mesh volume is too small"):
        mujoco.MjModel.from_xml_path(str(path))
    scene = MeshcatScene(path)
    assert scene.model.nmesh == 1 and scene.joint_names == ["j1"]
    assert [spec.type for spec in scene.geoms] == ["mesh"]


def test_record_without_mjcf_or_with_bad_diagnoser(tmp_path):
    rec = make_record()
    with pytest.raises(RobofdiError, match="diagnoser 'nope'"):
        write_replay_html(rec, tmp_path / "r.html", diagnoser="nope")
    rec.meta.pop("mjcf")
    with pytest.raises(RobofdiError, match="mjcf"):
        write_replay_html(rec, tmp_path / "r.html")
    rec.meta["mjcf"] = str(tmp_path / "missing_model.xml")
    with pytest.raises(RobofdiError, match="missing_model.xml"):
        write_replay_html(rec, tmp_path / "r.html")
    with pytest.raises(RobofdiError, match="no_such_run.h5"):
        write_replay_html(tmp_path / "no_such_run.h5", tmp_path / "r.html")


def test_target_mapping():
    joints = [f"joint{i}" for i in range(1, 7)]
    assert fault_joint("joint3", joints) == "joint3"
    assert fault_joint("joint5_pos", joints) == "joint5"
    assert fault_joint("joint2_vel", joints) == "joint2"
    assert fault_joint("gripper", joints) is None
    assert isolated_joints("joint3+joint5_pos", joints) == {"joint3", "joint5"}
    assert isolated_joints("", joints) == set()


# ------------------------------------------------------------------------------ replay
def test_build_replay_markers_and_frames():
    import io
    from contextlib import redirect_stdout

    import meshcat

    rec = make_record(diag_isolated="joint3+joint5_pos", diag_from=0.45)
    with redirect_stdout(io.StringIO()):
        vis = meshcat.Visualizer()
    try:
        rep = build_replay(vis, rec, fps=50)
    finally:
        close_visualizer(vis)
    assert vis.window.server_proc.poll() is not None  # server stopped
    assert rep.diagnoser == "gom"
    assert len(rep.frame_times) == 50
    onset = rep.marker("joint3", "onset")
    det = rep.marker("joint3", "detected")
    assert onset.path == "robot/link3/fault_onset_joint3" and onset.first_visible == pytest.approx(0.4)
    assert det.path == "robot/link3/fault_detected_joint3" and det.first_visible == pytest.approx(0.45)
    # a wrong isolation (joint5, no true fault there) shows red without a yellow ring
    assert rep.marker("joint5", "detected").first_visible == pytest.approx(0.45)
    assert rep.marker("joint5", "onset").intervals == []
    # visibility keys: hidden at frame 0, shown from the onset frame (0.4 s * 50 fps = 20)
    clip = rep.animation.clips[vis[onset.path].path]
    track = clip.tracks["visible"]
    assert track.frames[0] == 0 and track.values[0] is False
    assert track.values[track.frames.index(20)] is True
    clip = rep.animation.clips[vis[det.path].path]
    assert clip.tracks["visible"].values[clip.tracks["visible"].frames.index(23)] is True  # ceil(0.45*50)
    # the link bodies are animated, every frame
    body_clip = rep.animation.clips[vis["robot/link3"].path]
    assert len(body_clip.tracks["position"].frames) == 50


def _visible_by_frame(rep, vis, path):
    track = rep.animation.clips[vis[path].path].tracks["visible"]
    out, state = [], None
    keys = dict(zip(track.frames, track.values))
    for i in range(len(rep.frame_times)):
        state = keys.get(i, state)
        out.append(state)
    return np.array(out, dtype=bool)


def test_fault_intervals_overlap_end_and_sensor_targets():
    import io
    from contextlib import redirect_stdout

    import meshcat

    rec = make_record(diag_isolated="", diag_from=2.0)  # diagnoser never isolates anything
    rec.meta["faults"] = [
        {"name": "a", "kind": "actuator_bias", "target": "joint3", "onset": 0.2, "end": 0.5},
        {"name": "b", "kind": "actuator_gain", "target": "joint3", "onset": 0.4, "end": None},
        {"name": "c", "kind": "sensor_bias", "target": "joint5_pos", "onset": 0.1, "end": 0.3},
    ]
    with redirect_stdout(io.StringIO()):
        vis = meshcat.Visualizer()
    try:
        rep = build_replay(vis, rec, fps=10)
    finally:
        close_visualizer(vis)
    ft = rep.frame_times
    v3 = _visible_by_frame(rep, vis, rep.marker("joint3", "onset").path)
    np.testing.assert_array_equal(v3, ft >= 0.2 - 1e-9)            # union of [0.2, 0.5) and [0.4, inf)
    v5 = _visible_by_frame(rep, vis, rep.marker("joint5", "onset").path)
    np.testing.assert_array_equal(v5, (ft >= 0.1 - 1e-9) & (ft < 0.3 - 1e-9))
    assert rep.marker("joint5", "onset").path == "robot/link5/fault_onset_joint5"
    assert not _visible_by_frame(rep, vis, rep.marker("joint3", "detected").path).any()


def test_replay_html_self_contained(replay_html):
    assert replay_html.is_file()
    html = replay_html.read_text()
    assert "MeshCat.Viewer" in html
    # no remote resources: no src/href pointing at http(s), no imports from the network
    assert not re.search(r'(src|href)\s*=\s*["\']?\s*(https?:)?//', html, re.I)
    assert not re.search(r'fetch\(\s*["\']https?://', html)
    assert not re.search(r'import\s*\(?\s*["\']https?://', html)
    cmds = decode_commands(html)
    anims = [c for c in cmds if c["type"] == "set_animation"]
    assert len(anims) == 1
    clips = {a["path"]: a["clip"] for a in anims[0]["animations"]}
    assert "/meshcat/robot/link3" in clips and "/meshcat/robot/link6" in clips
    assert clips["/meshcat/robot/link3"]["fps"] == 25
    # joint3 markers: objects exist and their visibility is animated
    objs = {c["path"] for c in cmds if c["type"] == "set_object"}
    assert any(p.startswith("/meshcat/robot/link3/fault_onset_joint3/") for p in objs)
    assert any(p.startswith("/meshcat/robot/link3/fault_detected_joint3/") for p in objs)
    for name in ("fault_onset_joint3", "fault_detected_joint3"):
        clip = clips[f"/meshcat/robot/link3/{name}"]
        (track,) = [t for t in clip["tracks"] if t["name"] == ".visible"]
        assert track["type"] == "boolean"
        assert track["keys"][0] == {"time": 0, "value": False}
        assert any(k["value"] is True for k in track["keys"])
    # no markers on joints without fault / isolation
    assert not any("fault_" in p and "joint1" in p for p in objs)


# ------------------------------------------------------------------------------ live viewer
def _children(pid: int) -> list[int]:
    """PIDs of the child processes of ``pid`` (psutil if installed, else /proc)."""
    try:
        import psutil
    except ImportError:
        out = []
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    stat = (d / "stat").read_text()
                except OSError:
                    continue
                if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                    out.append(int(d.name))
        return out
    return [c.pid for c in psutil.Process(pid).children(recursive=True)]


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        import psutil
    except ImportError:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            return False
        return state not in ("Z", "X")
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_cli_view_stops_on_a_signal_and_leaves_no_meshcat_server(tmp_path, sig):
    """`robofdi view RECORD --no-browser`: URL printed; SIGTERM / SIGINT end it and kill its meshcat-server child."""
    if not sys.platform.startswith("linux"):
        pytest.skip("uses /proc or psutil and POSIX signals")
    record = make_record().save(tmp_path / "record.h5")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.Popen([sys.executable, "-m", "robofdi.cli", "view", str(record), "--no-browser"], cwd=tmp_path,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    children: list[int] = []
    try:
        line, deadline = "", time.monotonic() + 120
        while "http" not in line:
            ready, _, _ = select.select([proc.stdout], [], [], max(0.0, deadline - time.monotonic()))
            if proc.poll() is not None:
                pytest.fail(f"robofdi view exited before printing its URL: {proc.stderr.read()}")
            assert ready, "robofdi view printed no URL within 120 s"
            line = proc.stdout.readline()
        assert line.startswith("robofdi view: http")
        children = _children(proc.pid)
        assert children, "robofdi view started no meshcat server"
        proc.send_signal(sig)
        assert proc.wait(timeout=30) == 0, proc.stderr.read()
        deadline = time.monotonic() + 10
        while any(_alive(c) for c in children) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [c for c in children if _alive(c)], "a meshcat server survived robofdi view"
    finally:
        for pid in [*children, proc.pid]:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stdout.close()
        proc.stderr.close()


# ------------------------------------------------------------------------------ browser
def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        exe = shutil.which(name)
        if exe:
            return exe
    return None


def test_screenshot_shows_arm(replay_html, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("no chromium")
    png = tmp_path / "replay.png"
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--disable-dev-shm-usage", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={png}",
           "--window-size=800,600", "--virtual-time-budget=5000", replay_html.resolve().as_uri()]
    try:
        subprocess.run(cmd, timeout=120, capture_output=True, check=False)
    except subprocess.TimeoutExpired:
        pytest.skip("chromium timed out")
    assert png.is_file(), "chromium produced no screenshot"
    from matplotlib.image import imread

    img = imread(png)[..., :3].astype(float)
    if img.max() > 1.5:
        img /= 255.0
    assert img.shape[:2] == (600, 800)
    assert img.std() > 0.02, "blank screenshot"
    # arm orange (lit, so allow a wide tolerance): clearly more red than green than blue, saturated
    r, gch, b = img[..., 0], img[..., 1], img[..., 2]
    orange = (r > 0.35) & (r - gch > 0.12) & (gch - b > 0.05) & (r - b > 0.3)
    assert orange.sum() > 500, f"only {orange.sum()} arm-coloured pixels"


def test_replay_of_an_arm_with_a_gripper_maps_joints_by_name():
    """arm7 records only its 7 arm joints; the gripper's fingers stay at their reference position in the replay
    (the record's velocity columns must never be read as finger positions)."""
    from robofdi.control import ComputedTorque
    from robofdi.loop import ClosedLoop
    from robofdi.sims import ArmSimulator
    from robofdi.viz.replay import _resample
    from robofdi.viz.scene import MeshcatScene

    sim = ArmSimulator("arm7.xml")
    model = sim.nominal_model()
    q0 = sim.default_positions()
    loop = ClosedLoop(sim, ComputedTorque(model), lambda t: (q0 + 0.3 * t, np.full(7, 0.3), np.zeros(7)))
    record = loop.run(0.3, q0, meta={"joint_names": sim.joint_names})
    scene = MeshcatScene(sim.path)
    _, qs = _resample(record, scene, 50)
    arm = [scene.joint(j)["qposadr"] for j in sim.joint_names]
    fingers = [a for a in range(scene.nq) if a not in arm]
    assert len(fingers) == 2 and np.all(qs[:, fingers] == scene.model.qpos0[fingers])
    np.testing.assert_allclose(qs[-1, arm], record.truth_state[-1, :7], atol=1e-9)
