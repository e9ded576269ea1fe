"""Reliability (issue 26): signals stop `run` and `campaign` cleanly at any moment (the run in flight is not
journaled as an error, what was recorded is kept as a clearly partial record, exit 128 + signal), files are
written atomically, disk errors name the file and keep what was computed, corrupt caches are recomputed, bad input
is refused before anything runs, and faults the sampling cannot represent are refused.

Real runs of the linear system (subprocesses for the signals); a signal at an exact moment is sent by the process to
itself from a wrapper around the real function that is running at that moment (the physics is never replaced)."""
from __future__ import annotations

import json
import subprocess
import sys

import h5py
import pandas as pd
import pytest

from robofdi.campaign import load, load_spec, run_campaign

LINEAR = """
seed = 5
fault_free_runs = {ff}
faulty_runs = {faulty}

[system]
name = "linear"
duration = 3.0
calibration_runs = 2

[[faults]]
kind = "actuator_additive"
magnitude_fraction = [0.05, 0.4]
onset_fraction = [0.4, 0.8]
"""

# runs the command line in this process, sending SIG to itself at MOMENT: "simulation": at plant step STEP of the
# RUN-th run of the linear system; "calibration": at step 300 of the first calibration run; "saving": while
# record.h5 is being written
DRIVER = """
import os, signal, sys
moment, sig = sys.argv[1], getattr(signal, sys.argv[2])
run_n, step_n = int(os.environ.get("RUN", "1")), int(os.environ.get("STEP", "300"))
calls, runs = [], []
armed = [moment != "simulation"]

def signal_on(owner, name, n):
    real = getattr(owner, name)
    def wrapped(*args, **kwargs):
        calls.append(name)
        if armed[0] and calls.count(name) == n:
            os.kill(os.getpid(), sig)
        return real(*args, **kwargs)
    setattr(owner, name, wrapped)

def arm_on(owner, name):
    real = getattr(owner, name)
    def wrapped(*args, **kwargs):
        runs.append(1)
        armed[0] = len(runs) == run_n
        calls.clear()
        return real(*args, **kwargs)
    setattr(owner, name, wrapped)

if moment in ("simulation", "calibration"):       # calibration: with an empty cache, in its first run
    from robofdi.sims.linear import LinearPlant
    from robofdi.systems.linear import LinearSystem
    signal_on(LinearPlant, "step", step_n if moment == "simulation" else 300)
    if moment == "simulation":
        arm_on(LinearSystem, "run")
elif moment == "saving":
    import robofdi.record
    signal_on(robofdi.record, "_put", 4)
from robofdi.cli import main
raise SystemExit(main(sys.argv[3:]))
"""


def _env(tmp_path) -> dict:
    import os

    return {**os.environ, "ROBOFDI_PROGRESS": "off"}


def _robofdi_run(tmp_path, moment: str, sig: str, *args):
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    cmd = [sys.executable, str(driver), moment, sig, "run", "linear", "--out", str(tmp_path / "runs"), "--quiet", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180, env=_env(tmp_path))


@pytest.mark.parametrize("sig, code", [("SIGTERM", 143)])
def test_a_signal_mid_simulation_keeps_a_clearly_partial_record(tmp_path, sig, code):
    proc = _robofdi_run(tmp_path, "simulation", sig)
    assert proc.returncode == code, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and sig in lines[0] and "partial.h5" in lines[0], proc.stderr
    folder = tmp_path / "runs" / "linear-seed0"
    assert sorted(p.name for p in folder.iterdir()) == ["partial.h5"]      # no record.h5, nothing half-written
    with h5py.File(folder / "partial.h5", "r") as f:
        assert f.attrs["partial"] == 1
        assert 2.0 < f["time"][-1] < 4.0               # step 300 at 100 Hz; the run lasts 10 s
    # a later successful run in the same folder removes the stale partial record
    again = subprocess.run([sys.executable, "-m", "robofdi.cli", "run", "linear", "--out", str(tmp_path / "runs"),
                            "--quiet"], capture_output=True, text=True, timeout=180, env=_env(tmp_path))
    assert again.returncode == 0, again.stderr
    names = sorted(p.name for p in folder.iterdir())
    assert "partial.h5" not in names and "record.h5" in names and "summary.json" in names
    with h5py.File(folder / "record.h5", "r") as f:
        assert "partial" not in f.attrs


def test_a_signal_during_calibration_saves_nothing_and_the_next_run_calibrates(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path / "cache"))
    proc = _robofdi_run(tmp_path, "calibration", "SIGINT")
    assert proc.returncode == 130, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "SIGINT" in proc.stderr, proc.stderr
    assert not list((tmp_path / "cache").glob("*")) if (tmp_path / "cache").exists() else True
    folder = tmp_path / "runs" / "linear-seed0"
    assert not list(folder.iterdir())


def test_sigterm_while_the_record_is_written_leaves_no_torn_file(tmp_path):
    proc = _robofdi_run(tmp_path, "saving", "SIGTERM")
    assert proc.returncode == 143, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "SIGTERM" in proc.stderr
    folder = tmp_path / "runs" / "linear-seed0"
    names = sorted(p.name for p in folder.iterdir())
    assert "record.h5" not in names and not [n for n in names if n.endswith(".tmp")], names
    assert "summary.json" in names                                           # written first, complete
    json.loads((folder / "summary.json").read_text())


def test_ctrl_c_inside_a_run_of_a_one_worker_campaign_stops_it_and_resume_gives_the_uninterrupted_table(tmp_path):
    spec_path = tmp_path / "linear.toml"
    spec_path.write_text(LINEAR.format(ff=3, faulty=3))
    whole = run_campaign(load_spec(spec_path), tmp_path / "whole", workers=1, progress=False)
    out = tmp_path / "stopped"
    args = ["campaign", str(spec_path), "--out", str(out), "--workers", "1", "--quiet"]
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    proc = subprocess.run([sys.executable, str(driver), "simulation", "SIGINT", *args], capture_output=True, text=True,
                          timeout=180, env={**_env(tmp_path), "RUN": "3", "STEP": "100"})   # inside run index 2
    assert proc.returncode == 130, proc.stderr
    assert "interrupted by SIGINT" in proc.stderr and "--resume" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    entries = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert [e["index"] for e in entries] == [0, 1], "the interrupted run must not be journaled (nor any later one)"
    assert all(r["error"] is None for e in entries for r in e["rows"])
    resumed = subprocess.run([sys.executable, "-m", "robofdi.cli", *args, "--resume"], capture_output=True, text=True,
                             timeout=180, env=_env(tmp_path))
    assert resumed.returncode == 0, resumed.stderr
    pd.testing.assert_frame_equal(load(out).table.drop(columns="wall_time"), whole.table.drop(columns="wall_time"))


# ----------------------------------------------------------------------------------- faults that cannot be seen
def _cli(capsys, *args) -> tuple[int, str]:
    from robofdi.cli import main

    code = main(list(args))
    return code, capsys.readouterr().err


@pytest.mark.parametrize("spec, expected", [
    ("actuator_additive:tau_L:20@1~sin(1e6)", "Nyquist"),                       # aliases to zero at the loop rate
    ("actuator_additive:tau_L:1@1~sin(50)", "Nyquist"),                         # exactly f_s/2: sin(πk) = 0
    ("actuator_additive:tau_L:1@1~intermittent(1e-6,0.5)", "shorter than one control sample"),
    ("actuator_additive:tau_L:0@1", "must not be 0"),
])
def test_faults_the_sampling_cannot_represent_are_refused(tmp_path, capsys, spec, expected):
    code, err = _cli(capsys, "run", "linear", "--quiet", "--out", str(tmp_path), "--fault", spec)
    assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.rglob("*.h5"))


def test_contradicting_hard_overs_on_one_target_are_refused_and_sequential_ones_accepted():
    from robofdi.faults import Fault, check_faults
    from robofdi.faults.profiles import Sinusoid

    a = Fault("up", "actuator_hard_over", "joint1", onset=1.0, params={"limit": 100.0})
    b = Fault("down", "actuator_hard_over", "joint1", onset=2.0, params={"limit": -100.0})
    with pytest.raises(Exception, match="contradicts fault 'up'"):
        check_faults([a, b], 1000.0)
    check_faults([Fault("up", "actuator_hard_over", "joint1", onset=1.0, end=2.0, params={"limit": 100.0}), b], 1000.0)
    check_faults([Fault("s", "actuator_additive", "joint1", onset=1.0, magnitude=1.0, profile=Sinusoid(499.0))], 1000.0)


def test_a_zero_size_campaign_entry_is_refused_where_the_kind_scales_with_it():
    from robofdi import RobofdiError

    bad = LINEAR.format(ff=1, faulty=1).replace("magnitude_fraction = [0.05, 0.4]", "magnitude_fraction = [0, 0]")
    with pytest.raises(RobofdiError, match=r"faults\[0\].*must not be 0"):
        load_spec(bad)
    # a one-sided range ending at 0 is a real range (the probe takes the end with the larger size)
    load_spec(bad.replace("magnitude_fraction = [0, 0]", "magnitude_fraction = [0, 0.2]"))
