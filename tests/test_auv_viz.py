"""The AUV replay: pose from the quaternion, thrust arrows, failed thrusters red from detection, onset markers."""
import numpy as np

from robofdi.faults import Fault
from robofdi.systems.auv import AuvCalibration, AuvScenario, build_loop


def test_auv_replay_marks_the_isolated_thruster_and_the_onset(tmp_path):
    import meshcat

    from robofdi.viz import write_replay_html
    from robofdi.viz.auv_replay import build_auv_replay, thruster_detection_times
    from robofdi.viz.replay import close_visualizer

    sc = AuvScenario(duration=4.0, diagnosers=("voltage_residual",), variant="diagnosed",
                     faults=(Fault("thruster2_off", "actuator_float", "thruster2", onset=2.0),))
    cal = AuvCalibration(np.zeros(3), {"voltage_residual": np.full(8, 1.0)}, 10, sc.plant.control_dt)
    record = build_loop(sc, cal).run(sc.duration, sc.start_pose, seed=0)
    times = thruster_detection_times(record, "voltage_residual", [f"thruster{i}" for i in range(1, 9)])
    assert set(times) == {"thruster2"} and 2.0 <= times["thruster2"] <= 2.5
    vis = meshcat.Visualizer()
    try:
        anim = build_auv_replay(vis, record, "voltage_residual", fps=10)
    finally:
        close_visualizer(vis)
    paths = {p.lower() for p in anim.clips}
    assert any(p.endswith("auv_scene/hull") for p in paths)
    assert any(p.endswith("thruster2/onset") for p in paths) and any(p.endswith("thruster5/arrow") for p in paths)
    html = write_replay_html(record, tmp_path / "replay.html")
    assert html.stat().st_size > 10_000
