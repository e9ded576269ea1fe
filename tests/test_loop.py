"""The closed loop, the run record and the command line, on the real simulated arm."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from robofdi.experiments.ch3_industrial_robot import scenario
from robofdi import RobofdiError
from robofdi.faults import Fault
from robofdi.loop import Diagnosis, Rates, RunAborted, diagnose_record
from robofdi.observers.arm_schemes import arm_schemes
from robofdi.record import load
from robofdi.scenarios.arm import _loop, run_scenario
from robofdi.sims import ArmSimulator


def _short(seed=0, **kw):
    return scenario("ch3-actuator", seed=seed, duration=1.2, schemes=("recursive", "momentum"), **kw)


def test_offline_replay_of_a_record_equals_the_online_diagnosis(ch3):
    sc, cal = ch3
    rec = run_scenario(replace(_short(), faults=sc.faults), cal)
    model = sc.nominal_model(sc.simulator())
    for name in ("recursive", "momentum"):
        offline = diagnose_record(rec, Diagnosis(arm_schemes(model, sc.settings, cal.theta0, [name])[name]))
        np.testing.assert_array_equal(offline.residual, rec.diagnosers[name].residual)


def test_record_round_trip_is_exact(ch3, tmp_path):
    _, cal = ch3
    rec = run_scenario(_short(), cal)
    back = load(rec.save(tmp_path / "run.h5"))
    for attr in ("system", "scenario", "seed", "rates", "meta"):
        assert getattr(back, attr) == getattr(rec, attr), attr
    np.testing.assert_array_equal(back.time, rec.time)
    np.testing.assert_array_equal(back.truth_state, rec.truth_state)
    for k in rec.signals:
        np.testing.assert_array_equal(back.signals[k], rec.signals[k])
    for k, lab in rec.faults.items():
        np.testing.assert_array_equal(back.faults[k].active, lab.active)
        np.testing.assert_array_equal(back.faults[k].value, lab.value)
    for k, tr in rec.diagnosers.items():
        b = back.diagnosers[k]
        for field in ("time", "residual", "threshold", "alarm", "estimate"):
            np.testing.assert_array_equal(getattr(b, field), getattr(tr, field))
        assert list(b.isolated) == list(tr.isolated) and b.components == tr.components


def test_same_seed_same_record_other_seed_other_record(ch3):
    _, cal = ch3
    noisy = dict(sensors=replace(_short().sensors, velocity_noise=1e-4))
    a, b = (run_scenario(_short(seed=3, **noisy), cal) for _ in range(2))
    c = run_scenario(_short(seed=4, **noisy), cal)
    np.testing.assert_array_equal(a.signals["y_meas"], b.signals["y_meas"])
    np.testing.assert_array_equal(a.diagnosers["recursive"].residual, b.diagnosers["recursive"].residual)
    assert not np.array_equal(a.signals["y_meas"], c.signals["y_meas"])


class _BrokenEncoder(ArmSimulator):
    """A plant whose encoder driver starts returning NaN at 0.5 s."""

    def measure(self):
        y = super().measure()
        return y * np.nan if self.time >= 0.5 else y


def test_a_failing_run_keeps_what_it_recorded(ch3):
    sc, cal = ch3
    short = _short()
    sim = _BrokenEncoder(short.mjcf, ripple=short.simulator().ripple)
    model = sim.nominal_model()
    d = arm_schemes(model, short.settings, cal.theta0, ["recursive"])["recursive"]
    loop = _loop(short, short.reference(), diagnoses={"recursive": Diagnosis(d)}, sim=sim, model=model)
    with pytest.raises(RunAborted) as info:
        loop.run(short.duration, short.q0)
    assert "non-finite" in str(info.value) or "'y'" in str(info.value)
    rec = info.value.record
    assert rec.meta["aborted"] and 0.45 < rec.time[-1] < 0.5
    assert len(rec.truth_state) == len(rec.time) and np.all(np.isfinite(rec.truth_state))
    assert len(rec.diagnosers["recursive"].time) >= 240


def test_a_diagnoser_on_a_model_of_another_arm_is_rejected(ch3, tmp_path):
    """A nominal model whose joints differ from the simulator's is refused when the loop is built."""
    from robofdi import ASSETS
    from robofdi.models import ManipulatorModel
    from robofdi.observers import DiagnosticObserver

    other = tmp_path / "other_arm.xml"
    other.write_text((ASSETS / "arm6.xml").read_text().replace('"joint4"', '"wrist_roll"'))
    wrong = DiagnosticObserver(ManipulatorModel(other), 0.002)
    sc = _short()
    with pytest.raises(RobofdiError, match="wrist_roll"):
        _loop(sc, sc.reference(), diagnoses={"recursive": Diagnosis(wrong)})


def test_fault_on_a_joint_the_arm_does_not_have_is_rejected():
    sc = _short(faults=(Fault("tau7", "actuator_additive", "joint7", onset=1.0, magnitude=10.0),))
    with pytest.raises(RobofdiError, match="joint7"):
        _loop(sc, sc.reference(), sc.faults)


@pytest.mark.parametrize(
    "kwargs, field",
    [(dict(diagnosis_hz=300.0), "diagnosis_hz"), (dict(control_hz=-1.0), "control_hz"), (dict(input_hold="last"), "input_hold")],
)
def test_bad_rates_name_the_field(kwargs, field):
    with pytest.raises(RobofdiError, match=field):
        Rates(**kwargs)


def test_scenario_rejects_a_bad_seed():
    with pytest.raises(RobofdiError, match="seed"):
        scenario("ch3-actuator", seed=-1)


def _cli(*args, cwd):
    """The installed command line (robofdi installed, e.g. `pip install -e .`), run from ``cwd``."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-m", "robofdi.cli", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def test_cli_errors_are_one_line_with_nonzero_exit(tmp_path):
    out = _cli("run", "ch9-nothing", cwd=tmp_path)
    assert out.returncode == 2 and out.stderr.strip().count("\n") == 0 and "ch9-nothing" in out.stderr
    out = _cli("view", str(tmp_path / "missing.h5"), cwd=tmp_path)
    assert out.returncode == 2 and "missing.h5" in out.stderr
    out = _cli("run", "ch3-actuator", "--seed", "x", cwd=tmp_path)               # argparse's errors too
    assert out.returncode == 2 and out.stderr.strip().count("\n") == 0 and out.stderr.startswith("robofdi: error: ")


def test_cli_file_system_errors_are_one_line_naming_the_path(tmp_path):
    """An --out that cannot be created: one line with the path and the OS reason, exit 2, before any simulation."""
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    out = _cli("run", "ch3-actuator", "--quiet", "--out", str(blocker / "runs"), cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().count("\n") == 0 and "Traceback" not in out.stderr
    assert out.stderr.startswith("robofdi: error: ") and str(blocker) in out.stderr and "Not a directory" in out.stderr


def test_cli_run_writes_the_run_folder(tmp_path):
    """`robofdi run ch3-sensor`: table on stdout; summary.json (contract), record, figures, replay in the folder."""
    out = _cli("run", "ch3-sensor", "--out", str(tmp_path), "--quiet", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "joint5_pos" in out.stdout and "time_delayed" in out.stdout
    run_dir = tmp_path / "ch3-sensor-seed0"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["experiment"] == "ch3-sensor" and summary["seed"] == 0
    assert all(v == 0 for v in summary["fault_free_false_alarms"].values())
    det = {d["fault"]: d for d in summary["diagnosers"]["recursive"]["detections"]}
    assert det["x3"]["isolated"] == "joint3_pos" and det["x5"]["isolated"] == "joint5_pos"
    assert all(check["pass"] for check in summary["reproduction"])
    assert load(run_dir / "record.h5").diagnosers.keys() == summary["diagnosers"].keys()
    assert (run_dir / "figures" / "residuals_adaptive.png").stat().st_size > 10_000
    html = (run_dir / "replay.html").read_text()
    assert "<script" in html and "src=\"http" not in html
