"""Reliability (issue 26): signals stop `run` and `campaign` cleanly at any moment (the run in flight is not
journaled as an error, what was recorded is kept as a clearly partial record, exit 128 + signal), files are
written atomically, disk errors name the file and keep what was computed, corrupt caches are recomputed, bad input
is refused before anything runs, and faults the sampling cannot represent are refused.

Real runs of the linear system (subprocesses for the signals); a signal at an exact moment is sent by the process to
itself from a wrapper around the real function that is running at that moment (the physics is never replaced)."""
from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

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
elif moment == "finaliser":                         # a signal whose exception Python swallows (raised in __del__)
    import robofdi.experiments.system_run as system_run

    class Finaliser:
        def __del__(self):
            os.kill(os.getpid(), sig)

    real_write = system_run.write_run_folder
    def write_then_collect(*args, **kwargs):
        out = real_write(*args, **kwargs)
        Finaliser()                                   # collected at once: its __del__ gets the signal
        return out
    system_run.write_run_folder = write_then_collect
elif moment == "saving":
    import robofdi.record
    signal_on(robofdi.record, "_put", 4)
from robofdi.cli import main
raise SystemExit(main(sys.argv[3:]))
"""


def _env(tmp_path) -> dict:

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
    from robofdi.cli import main

    assert main(["run", "linear", "--out", str(tmp_path / "runs"), "--quiet"]) == 0
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


def test_a_signal_whose_exception_python_swallows_still_stops_with_its_exit_code(tmp_path):
    proc = _robofdi_run(tmp_path, "finaliser", "SIGINT")
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip() == "robofdi: interrupted by SIGINT", proc.stderr      # no "Exception ignored" traceback


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
    # batches of two runs: the batch of runs 0 and 1 is journaled whole, the one in flight (runs 2 and 3) is lost
    args = ["campaign", str(spec_path), "--out", str(out), "--workers", "1", "--quiet", "--batch", "2"]
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    proc = subprocess.run([sys.executable, str(driver), "simulation", "SIGINT", *args], capture_output=True, text=True,
                          timeout=180, env={**_env(tmp_path), "RUN": "3", "STEP": "100"})   # inside run index 2
    assert proc.returncode == 130, proc.stderr
    assert "interrupted by SIGINT" in proc.stderr and "--resume" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    entries = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert [e["index"] for e in entries] == [0, 1], "the interrupted batch must not be journaled (nor any later one)"
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
        check_faults([a, b], control_hz=1000.0)
    check_faults([Fault("up", "actuator_hard_over", "joint1", onset=1.0, end=2.0, params={"limit": 100.0}), b],
                 control_hz=1000.0)
    check_faults([Fault("s", "actuator_additive", "joint1", onset=1.0, magnitude=1.0, profile=Sinusoid(499.0))],
                 control_hz=1000.0)


def test_a_zero_size_campaign_entry_is_refused_where_the_kind_scales_with_it():
    from robofdi import RobofdiError

    bad = LINEAR.format(ff=1, faulty=1).replace("magnitude_fraction = [0.05, 0.4]", "magnitude_fraction = [0, 0]")
    with pytest.raises(RobofdiError, match=r"faults\[0\].*must not be 0"):
        load_spec(bad)
    # a one-sided range ending at 0 is a real range (the probe takes the end with the larger size)
    load_spec(bad.replace("magnitude_fraction = [0, 0]", "magnitude_fraction = [0, 0.2]"))


# ------------------------------------------------------------------------------ bad input refused before any work
def _arm_variant(tmp_path, pattern: str, replacement: str, name: str) -> Path:
    import re

    from robofdi import ASSETS

    text = (Path(ASSETS) / "arm6.xml").read_text()
    assert re.search(pattern, text), pattern
    path = tmp_path / name
    path.write_text(re.sub(pattern, replacement, text, count=1))
    return path


@pytest.mark.parametrize("args, expected", [
    (["run", "linear", "--seed", str(2**64)], "--seed must be an integer in [0, 2^63 - 1]"),
    (["run", "arm", "--fault", "component_mass:payload:-3@1"], "component_mass expects it >= 0"),
    (["run", "arm", "--fault", "component_friction:joint2:-2@1"], "expects it > -1"),
    (["run", "arm", "--fault", "component_friction:joint2:1.5@1~sin(2)"], "reaches -1.5 with profile sinusoid"),
    (["run", "arm", "--robot", "."], "is a folder"),
    (["run", "arm", "--robot", "/dev/null"], "not a regular file"),
    (["run", "arm", "--joints", ","], "--joints: expected comma-separated joint names"),
])
def test_bad_command_line_input_is_one_line_exit_2_before_any_folder(tmp_path, capsys, args, expected):
    out = tmp_path / "runs"
    code, err = _cli(capsys, *args, "--quiet", "--out", str(out))
    assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


@pytest.mark.parametrize("pattern, replacement, expected", [
    (r'mass="[^"]*"', 'mass="nan"', "mass='nan' is not a finite number"),
    (r'timestep="[^"]*"', 'timestep="0.5"', "timestep> is 0.5 s; expected a physics step in (0, 0.01] s"),
    (r'ctrlrange="[^"]*"', 'ctrlrange="-1e12 1e12"', "expected at most 1e+06 in magnitude"),
])
def test_mjcf_values_mujoco_would_replace_or_that_are_absurd_are_named(tmp_path, capsys, pattern, replacement, expected):
    robot = _arm_variant(tmp_path, pattern, replacement, "bad.xml")
    code, err = _cli(capsys, "run", "arm", "--robot", str(robot), "--quiet", "--out", str(tmp_path / "runs"))
    assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err


def test_non_utf8_mjcf_and_toml_name_the_file_and_the_byte(tmp_path, capsys):
    robot = tmp_path / "latin1.xml"
    robot.write_bytes(b'<mujoco model="\xe9"><worldbody/></mujoco>')
    code, err = _cli(capsys, "run", "arm", "--robot", str(robot), "--quiet", "--out", str(tmp_path / "runs"))
    assert code == 2 and "latin1.xml" in err and "not UTF-8" in err and "byte 15" in err, err
    spec = tmp_path / "latin1.toml"
    spec.write_bytes(LINEAR.format(ff=1, faulty=1).encode() + b"# caf\xe9\n")
    code, err = _cli(capsys, "campaign", str(spec), "--out", str(tmp_path / "c"), "--quiet")
    assert code == 2 and "latin1.toml: not UTF-8" in err, err
    assert not (tmp_path / "c").exists()


def test_an_onset_in_scientific_notation_is_read_as_a_number():
    from robofdi.faults import parse_fault_spec

    assert parse_fault_spec("actuator_additive:joint2:20@1e-3").onset == pytest.approx(1e-3)
    f = parse_fault_spec("actuator_additive:joint2:20@1e-3-2.5")
    assert (f.onset, f.end) == (pytest.approx(1e-3), 2.5)


@pytest.mark.parametrize("change, expected", [
    ('[system]\nname = "arm"\nrobot = "nope.xml"', "system.robot: mjcf: file 'nope.xml' does not exist"),
    ('[system]\nname = "arm"\njoints = ["x"]', "are not joints of arm6.xml"),
    ('[system]\nname = "linear"\nduration = inf', "field 'duration' is out of range, got inf"),
    ('fault_free_runs = 1000000000\n[system]\nname = "linear"', "must be <= 1,000,000"),
    ('seed = 18446744073709551616\n[system]\nname = "linear"', "'seed' must be an integer in [0, 2^63 - 1]"),
])
def test_campaign_fields_are_checked_before_the_folder_is_written(tmp_path, capsys, change, expected):
    spec = tmp_path / "bad.toml"
    spec.write_text("fault_free_runs = 2\n" * ("fault_free_runs" not in change) + change + "\n")
    out = tmp_path / "campaign"
    code, err = _cli(capsys, "campaign", str(spec), "--out", str(out), "--quiet")
    assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


# ------------------------------------------------------------------------------------------------------ full disk
def _run_with_file_size_limit(tmp_path, limit: int) -> subprocess.CompletedProcess:
    """`robofdi run linear` where no file may grow past ``limit`` bytes (RLIMIT_FSIZE, SIGXFSZ ignored: a write
    beyond it fails with EFBIG, as one on a full device fails with ENOSPC)."""
    import resource

    def limited():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    cmd = [sys.executable, "-m", "robofdi.cli", "run", "linear", "--quiet", "--out", str(tmp_path / "runs")]
    return subprocess.run(cmd, preexec_fn=limited, capture_output=True, text=True, timeout=180, env=_env(tmp_path))


def test_a_record_that_does_not_fit_names_the_file_and_keeps_the_summary(tmp_path):
    proc = _run_with_file_size_limit(tmp_path, 50_000)          # summary.json ~1 kB fits, record.h5 ~230 kB does not
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip() == f"robofdi: error: '{tmp_path / 'runs' / 'linear-seed0' / 'record.h5'}': File too large"
    folder = tmp_path / "runs" / "linear-seed0"
    assert sorted(p.name for p in folder.iterdir()) == ["summary.json"]      # no torn record.h5, no temporary file
    assert json.loads((folder / "summary.json").read_text())["diagnosers"]


def test_a_summary_that_does_not_fit_names_the_file(tmp_path):
    proc = _run_with_file_size_limit(tmp_path, 300)
    assert proc.returncode == 2, proc.stderr
    assert "summary.json': File too large" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not list((tmp_path / "runs" / "linear-seed0").iterdir())


# --------------------------------------------------------------------------------------------- calibration cache
def test_a_truncated_calibration_cache_is_reported_with_its_path_and_recomputed(tmp_path, monkeypatch, capsys):
    from robofdi import calibration

    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path / "cache"))
    args = ("run", "linear", "--quiet", "--out", str(tmp_path / "runs"))
    assert _cli(capsys, *args)[0] == 0
    (path,) = (tmp_path / "cache").glob("*.cal.npz")
    good = path.read_bytes()

    def summary():
        data = json.loads((tmp_path / "runs" / "linear-seed0" / "summary.json").read_text())
        data.pop("wall_time", None)
        return data

    before = summary()
    path.write_bytes(good[: len(good) // 2])                              # torn, as by a full disk or a crash
    with pytest.warns(UserWarning) as warned:
        assert _cli(capsys, *args)[0] == 0
    message = " ".join(str(w.message) for w in warned)
    assert str(path) in message and "unreadable" in message and "recomputing" in message
    assert calibration.loads(path.read_bytes()) is not None                 # replaced by a good file
    assert summary() == before
    assert not list((tmp_path / "cache").glob("*.tmp"))


def test_every_corruption_of_a_cache_file_is_detected_and_nothing_is_pickled():
    import numpy as np

    from robofdi import calibration

    data = calibration.dumps({"theta": np.linspace(0.0, 1.0, 40), "k": 3})
    assert b"pickle" not in data
    for n in range(0, len(data), 7):                                        # every truncation
        try:
            calibration.loads(data[:n])
        except Exception:
            continue
        pytest.fail(f"a file cut at byte {n} of {len(data)} was read")
    for k in range(0, len(data), 3):                                        # every flipped byte, even ones that unzip
        flipped = bytearray(data)
        flipped[k] ^= 0xFF
        try:
            value = calibration.loads(bytes(flipped))
        except Exception:
            continue
        assert np.array_equal(value["theta"], np.linspace(0.0, 1.0, 40)) and value["k"] == 3, k


# ----------------------------------------------------------------------------------------------------------- Dask
def test_an_http_server_as_dask_scheduler_is_one_line_within_the_timeout(tmp_path):
    pytest.importorskip("dask.distributed")
    import http.server
    import threading

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        address = f"tcp://127.0.0.1:{server.server_address[1]}"
        start = time.monotonic()
        proc = subprocess.run([sys.executable, "-m", "robofdi.cli", "campaign", "linear", "--scheduler", address,
                               "--out", str(tmp_path / "c"), "--quiet"], capture_output=True, text=True, timeout=120,
                              env=_env(tmp_path))
        seconds = time.monotonic() - start
    finally:
        server.shutdown()
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot reach the Dask scheduler" in lines[0] and "within 10 s" in lines[0], proc.stderr
    assert seconds < 90                                        # 10 s + start-up on a loaded machine, not > 10 min
    assert not (tmp_path / "c").exists()


# ------------------------------------------------------------------------------------------- servers and plug-ins
def _listening(pids: list[int]) -> list[str]:
    """The local addresses (ip:port) the processes ``pids`` listen on over TCP, from /proc."""
    import socket
    import struct

    inodes = set()
    for pid in pids:
        with contextlib.suppress(OSError):
            for fd in os.listdir(f"/proc/{pid}/fd"):
                with contextlib.suppress(OSError):
                    link = os.readlink(f"/proc/{pid}/fd/{fd}")
                    if link.startswith("socket:["):
                        inodes.add(link[8:-1])
    found = []
    for table, family in (("/proc/net/tcp", socket.AF_INET), ("/proc/net/tcp6", socket.AF_INET6)):
        with contextlib.suppress(OSError), open(table) as fh:
            for row in fh.readlines()[1:]:
                cols = row.split()
                if cols[3] != "0A" or cols[9] not in inodes:              # 0A: LISTEN
                    continue
                address, port = cols[1].split(":")
                raw = bytes.fromhex(address)
                raw = b"".join(struct.pack("<I", w) for w in struct.unpack(f">{len(raw) // 4}I", raw))
                found.append(f"{socket.inet_ntop(family, raw)}:{int(port, 16)}")
    return found


def test_robofdi_view_listens_on_127_0_0_1_only(tmp_path):
    if not sys.platform.startswith("linux"):
        pytest.skip("reads the sockets from /proc")
    import select

    from test_viz import _children, make_record

    record = make_record().save(tmp_path / "record.h5")
    proc = subprocess.Popen([sys.executable, "-m", "robofdi.cli", "view", str(record), "--no-browser"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    children: list[int] = []
    try:
        line, deadline = "", time.monotonic() + 120
        while "http" not in line and proc.poll() is None:
            ready, _, _ = select.select([proc.stdout], [], [], max(0.0, deadline - time.monotonic()))
            assert ready, "robofdi view printed no URL within 120 s"
            line = proc.stdout.readline()
        assert "http://127.0.0.1:" in line, proc.stderr.read() if proc.poll() is not None else line
        children = _children(proc.pid)
        addresses = _listening([proc.pid, *children])
        web_port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        assert f"127.0.0.1:{web_port}" in addresses and len(addresses) >= 2, addresses       # web server + zmq
        assert all(a.startswith("127.0.0.1:") for a in addresses), addresses
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0
    finally:
        for pid in [*children, proc.pid]:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stdout.close()
        proc.stderr.close()


def test_building_a_replay_starts_no_server(tmp_path):
    from test_viz import make_record

    from robofdi.viz import write_replay_html

    started: list = []
    watching = [True]

    def audit(event, args):                   # Python's audit events: every subprocess and every socket bind
        if watching[0] and event in ("subprocess.Popen", "socket.bind"):
            started.append((event, args[:2]))

    sys.addaudithook(audit)
    try:
        path = write_replay_html(make_record(), tmp_path / "replay.html")
    finally:
        watching[0] = False
    assert "handle_command_bytearray" in path.read_text()              # the scene is in the file
    assert not started, started                                          # no meshcat-server, nothing listening


def _children(pid: int) -> list[int]:
    from test_viz import _children as children

    return children(pid)


SIDE_EFFECT = """
from pathlib import Path
Path(__file__).with_name("imported").write_text("the module ran")

class NotASystem:
    def __init__(self):
        Path(__file__).with_name("instantiated").write_text("the class ran")
"""


def test_a_module_attr_system_is_imported_only_for_an_otherwise_valid_spec_and_never_blindly_instantiated(
        tmp_path, monkeypatch):
    from robofdi import RobofdiError

    (tmp_path / "sidefx_mod.py").write_text(SIDE_EFFECT)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(RobofdiError, match="'seed' must be an integer"):
        load_spec({"system": "sidefx_mod:NotASystem", "seed": -1, "fault_free_runs": 1})
    with pytest.raises(RobofdiError, match="'fault_free_runs'"):
        load_spec({"system": "sidefx_mod:NotASystem", "fault_free_runs": "many"})
    assert not (tmp_path / "imported").exists(), "the module was imported for an invalid spec"
    with pytest.raises(RobofdiError, match="does not implement the System protocol"):
        load_spec({"system": "sidefx_mod:NotASystem", "fault_free_runs": 1})
    assert (tmp_path / "imported").exists()                      # a valid spec imports it (documented: code runs)
    assert not (tmp_path / "instantiated").exists(), "a class that is not a System was instantiated"


def test_a_pickle_planted_as_a_calibration_is_refused_and_runs_nothing(tmp_path):
    import pickle

    from robofdi import calibration

    class Boom:
        def __reduce__(self):
            return (Path.write_text, (tmp_path / "ran", "pickle executed"))

    with pytest.raises(ValueError):
        calibration.loads(pickle.dumps(Boom()))
    assert not (tmp_path / "ran").exists()


@pytest.mark.parametrize("spec, expected", [
    ("actuator_lock_in_place:joint2:5@1", "must be 0 for actuator_lock_in_place: the kind ignores it"),
    ("sensor_freeze:joint2_pos:0.1@1", "must be 0 for sensor_freeze"),
    ("sensor_delay:joint2_pos:0@1;delay=1e9", "a delay in (0, 60] s"),
])
def test_silently_ignored_or_absurd_fault_values_are_refused(spec, expected):
    from robofdi import RobofdiError
    from robofdi.faults import parse_fault_spec

    with pytest.raises(RobofdiError) as info:
        parse_fault_spec(spec)
    assert expected in str(info.value)
    parse_fault_spec("actuator_lock_in_place:joint2:0@1")                  # the documented form stays valid
