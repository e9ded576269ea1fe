"""A real robot's log: the shipped arm6 log (recorded from the simulator with timing jitter and dropped rows, in
a controller's own column names) is diagnosed offline after calibrating on a fault-free segment; bad logs are
refused in one line naming the column."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.logs import diagnose_log, read_arm_log
from robofdi.models import ManipulatorModel
from robofdi.record import load

LOG = ASSETS / "logs" / "arm6_cycles.csv.gz"
TRUTH = json.loads((ASSETS / "logs" / "arm6_cycles.json").read_text())     # what the log does not say
ONSET = TRUTH["fault"]["onset"]
CALIBRATION = (0.0, 2 * TRUTH["cycle_s"])                                     # the first two cycles


@pytest.fixture(scope="module")
def diagnosed():
    return diagnose_log(LOG, "arm6.xml", CALIBRATION, columns=TRUTH["columns"], schemes=("momentum", "simple"))


def test_the_shipped_log_is_resampled_and_its_timing_reported(diagnosed):
    record, summary = diagnosed
    log = summary["log"]
    assert log["rate_hz"] == TRUTH["rate_hz"] and log["rows"] == TRUTH["rows"]
    assert log["dropouts"] >= 1 and 0.01 < log["longest_gap_s"] < 0.02            # the burst of 6 dropped rows
    assert 20e-6 < log["jitter_s"] < 100e-6                                        # 50 µs stamp jitter
    assert np.allclose(np.diff(record.time), 1 / TRUTH["rate_hz"])
    assert record.meta["truth"].startswith("none")


@pytest.mark.parametrize("scheme", ["momentum", "simple"])
def test_the_logged_fault_is_detected_after_its_onset_and_isolated(diagnosed, scheme):
    record, summary = diagnosed
    result = summary["diagnosers"][scheme]
    trace = record.diagnosers[scheme]
    assert not trace.alarm[trace.time < ONSET].any()          # neither in the calibration cycles nor the held-out one
    assert result["alarm_samples_in_fault_free_segment"] == 0
    assert ONSET < result["first_alarm_s"] < ONSET + 0.5
    assert result["isolated"] == TRUTH["fault"]["target"]


def _bad(tmp_path, change) -> str:
    frame = pd.read_csv(LOG).rename(columns=TRUTH["columns"])
    change(frame)
    path = tmp_path / "bad.csv"
    frame.to_csv(path, index=False)
    return str(path)


@pytest.mark.parametrize("change, message", [
    (lambda f: f.pop("joint3_qd"), "column 'joint3_qd' is missing"),
    (lambda f: f.__setitem__("joint2_tau", f["joint2_tau"].where(f.index != 100)), "column 'joint2_tau' has 1 non-finite"),
    (lambda f: f.__setitem__("time", f["time"].where(f.index != 50, 0.0)), "column 'time' is not strictly increasing"),
    (lambda f: f.__setitem__("joint2_q", np.degrees(f["joint2_q"])), "column 'joint2_q' reaches"),
    (lambda f: f.__setitem__("joint1_qd", np.degrees(f["joint1_qd"])), r"column 'joint1_qd' is 5[67]\.\d × the derivative"),
    (lambda f: f.__setitem__("joint5_tau", 1000 * f["joint5_tau"]), "column 'joint5_tau' reaches"),
])
def test_bad_logs_are_one_line_naming_the_column(tmp_path, change, message):
    model = ManipulatorModel("arm6.xml")
    with pytest.raises(RobofdiError, match=message) as err:
        read_arm_log(_bad(tmp_path, change), model)
    assert "\n" not in str(err.value)


def test_bad_segments_and_diagnosers_are_refused_before_diagnosing(tmp_path):
    with pytest.raises(RobofdiError, match="fault-free segment"):
        diagnose_log(LOG, "arm6.xml", (5.0, 99.0), columns=TRUTH["columns"], schemes=("momentum",))
    with pytest.raises(RobofdiError, match="'consistency' needs the simulated calibration motions"):
        diagnose_log(LOG, "arm6.xml", CALIBRATION, columns=TRUTH["columns"], schemes=("consistency",))
    with pytest.raises(RobofdiError, match="unknown format"):
        read_arm_log(ASSETS / "logs" / "arm6_cycles.json", ManipulatorModel("arm6.xml"))


def test_robofdi_diagnose_writes_the_run_folder(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"MPLBACKEND": "Agg"}
    out = subprocess.run([sys.executable, "-m", "robofdi.cli", "diagnose", str(LOG), "--robot", "arm6.xml",
                          "--fault-free", f"{CALIBRATION[0]}:{CALIBRATION[1]}", "--columns",
                          str(ASSETS / "logs" / "arm6_cycles.json"), "--diagnosers", "momentum", "--no-replay",
                          "--out", str(tmp_path)], capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "momentum" in out.stdout and TRUTH["fault"]["target"] in out.stdout
    run_dir = tmp_path / "diagnose-arm6_cycles"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["lead"]["diagnoser"] == "momentum"
    assert load(run_dir / "record.h5").diagnosers["momentum"].alarm.any()
    bad = subprocess.run([sys.executable, "-m", "robofdi.cli", "diagnose", str(LOG), "--robot", "arm6.xml",
                          "--fault-free", "0-6"], capture_output=True, text=True, env=env, timeout=600)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--fault-free" in bad.stderr
