"""`robofdi run arm`: any MJCF arm from the command line — the shipped 7-DOF arm7 (geared motors out of order,
an included gripper, a 2 ms physics step), faults from SPEC strings, calibration cached per robot and seed."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from robofdi import RobofdiError
from robofdi.experiments.arm import run
from robofdi.record import load


def _cli(*args, cwd, cache):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(ROBOFDI_CACHE=str(cache), MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "robofdi.cli", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.mark.slow
def test_run_arm7_actuator_step_detected_isolated_and_compensated(tmp_path, monkeypatch):
    out = _cli("run", "arm", "--robot", "arm7.xml", "--fault", "actuator_additive:joint3:40@0.8", "--seed", "2",
               "--out", str(tmp_path), "--quiet", cwd=tmp_path, cache=tmp_path / "cache")
    assert out.returncode == 0, out.stderr
    run_dir = tmp_path / "arm-arm7-seed2"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["system"] == "arm7" and summary["joints"] == [f"joint{i}" for i in range(1, 8)]
    for name in ("recursive", "momentum", "consistency"):
        result = summary["diagnosers"][name]
        det = result["detections"][0]
        assert det["isolated"] == "joint3" and det["delay"] <= 0.02, (name, det)
        assert result["false_alarms"] == 0
    record = load(run_dir / "record.h5")
    trace = record.diagnosers["momentum"]
    assert not trace.alarm[trace.time < 0.8].any()                      # nothing before onset
    assert record.rates["physics_hz"] == pytest.approx(500.0)          # the file's 2 ms step
    rms = summary["accommodation"]["tracking_rms_after_onset"]
    assert rms["compensation"] < 0.7 * rms["none"] and rms["oracle_compensation"] < 0.7 * rms["none"]
    assert summary["calibration_cached"] is False
    assert (run_dir / "compensated.h5").is_file() and (run_dir / "replay.html").stat().st_size > 100_000
    # the same robot and seed, another fault: the calibration comes from the cache the command filled
    from robofdi.systems.arm import arm_scenario, calibration

    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path / "cache"))
    assert calibration(arm_scenario("arm7.xml", ["sensor_bias:joint5_pos:0.01@0.8"], 2))[1] is True


@pytest.mark.parametrize("args, message", [
    (["--fault", "actuator_additive:joint9:10@1"], "joint9"),
    (["--fault", "actuator_additive:joint2:10"], "expected KIND:TARGET"),
    (["--fault", "actuator_additive:joint2:10@99"], "not inside the run"),
    (["--robot", "no_such_arm.xml"], "no_such_arm.xml"),
    (["--joints", "joint1,elbow"], "elbow"),
])
def test_run_arm_bad_input_is_one_line_before_any_calibration(tmp_path, monkeypatch, capsys, args, message):
    # the command line in this process (the installed entry point is run as a process by the arm7 test above)
    code, err = _main(tmp_path, monkeypatch, capsys, "run", "arm", *args, "--out", str(tmp_path), "--quiet")
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "cache").exists()                            # failed before calibrating


def test_options_of_run_arm_are_refused_by_other_experiments(tmp_path, monkeypatch, capsys):
    code, err = _main(tmp_path, monkeypatch, capsys, "run", "ch3-actuator", "--robot", "arm7.xml")
    assert code == 2 and "--robot" in err and "'ch3-actuator'" in err


def _main(tmp_path, monkeypatch, capsys, *args) -> tuple[int, str]:
    """``robofdi ARGS`` in this process, from ``tmp_path`` with a cache folder there: (exit code, stderr)."""
    from robofdi.cli import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path / "cache"))
    code = main(list(args))
    return code, capsys.readouterr().err


def test_python_overrides_fail_at_once(tmp_path):
    """`run(...)` checks its overrides before any simulation (it used to crash after 30 s and save nothing)."""
    from robofdi.experiments.ch3_industrial_robot import run as run_ch3
    from robofdi.faults import Fault

    with pytest.raises(RobofdiError, match="joint9"):
        run_ch3("ch3-actuator", tmp_path, faults=(Fault("x", "actuator_additive", "joint9", onset=1.0, magnitude=10.0),))
    with pytest.raises(RobofdiError, match="motion gives 6 joint positions.*7 joints"):
        run_ch3("ch3-actuator", tmp_path, robot="arm7.xml", rates=None)
    with pytest.raises(RobofdiError, match="unknown override.*bogus"):
        run_ch3("ch3-actuator", tmp_path, bogus=1)
    with pytest.raises(RobofdiError, match="lock_in_place.*offline"):
        run(robot="arm6.xml", faults=["actuator_lock_in_place:joint2:0@1"], out=tmp_path, injection="offline")
