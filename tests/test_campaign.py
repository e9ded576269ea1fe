"""Campaigns: the same table whatever the backend (this process, a 2-process pool, a Dask cluster of two workers
on 127.0.0.1), SIGTERM + --resume gives the uninterrupted table, bad input is one line before any run, a run that
raises is an error row, and the campaign statistics against closed forms. Real MuJoCo arm and linear-plant runs."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from robofdi import RobofdiError
from robofdi.campaign import (
    clopper_pearson, detection_curve, load, load_spec, register_system, run_campaign, run_seed, shipped_specs,
)
from robofdi.campaign.backends import DaskCluster, LocalPool
from robofdi.systems.linear import LinearSystem

ARM = """
seed = 3
fault_free_runs = 2
faulty_runs = 2
diagnosers = ["simple", "momentum"]

[system]
name = "arm"
speed = "fast"
tail = 0.3

[[faults]]
kind = "actuator_additive"
magnitude_fraction = [0.1, 0.3]
onset_fraction = [0.3, 0.5]
"""

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

[[faults]]
kind = "sensor_bias"
targets = ["enc*"]
magnitude_fraction = [0.005, 0.05]
onset_fraction = [0.4, 0.8]
"""


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """Identical tables but for the wall-clock time of each run."""
    pd.testing.assert_frame_equal(a.drop(columns="wall_time"), b.drop(columns="wall_time"))


def test_arm_table_is_identical_in_process_on_two_workers_and_on_a_dask_cluster(tmp_path, monkeypatch):
    distributed = pytest.importorskip("dask.distributed")
    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path / "cache"))      # a cold cache of its own: calibrated once here
    spec = load_spec(ARM)
    one = run_campaign(spec, tmp_path / "w1", workers=1, progress=False)
    two = run_campaign(spec, tmp_path / "w2", workers=2, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        dask = run_campaign(spec, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    _same(one.table, two.table)
    _same(one.table, dask.table)
    t = one.table
    assert len(t) == 4 * 2 and list(t["index"].unique()) == [0, 1, 2, 3]
    assert t["error"].isna().all()
    # the runs really differ: distinct seeds from the campaign seed, distinct random start poses
    assert sorted(set(t["run_seed"])) == sorted({run_seed(3, i) for i in range(4)})
    assert t.drop_duplicates("index")["mission"].nunique() == 4
    faulty = t[t["faulty"]]
    assert set(faulty["kind"]) == {"actuator_additive"} and faulty["size"].between(0.1, 0.3).all()
    assert (faulty["onset"] < faulty["duration"]).all()
    # the peak threshold ratios say what the alarms did: detected where the fault's peak passes 1, false alarms
    # where the fault-free samples' peak does (both fixed-threshold decisions: every row has them)
    assert t[["peak_ratio_free"]].notna().all().all() and faulty["peak_ratio_fault"].notna().all()
    assert ((faulty["peak_ratio_fault"] > 1) == faulty["detected"].astype(bool)).all()
    assert ((t["peak_ratio_free"] > 1) == (t["false_alarms"] > 0)).all()
    assert t.loc[~t["faulty"], "peak_ratio_fault"].isna().all()
    # what the files say is what the API returned
    back = load(tmp_path / "dask")
    _same(back.table, one.table)
    summary = json.loads((tmp_path / "w1" / "campaign.json").read_text())
    assert summary["runs"] == {"finished": 4, "fault_free": 2, "faulty": 2, "errors": 0}
    cached = {k: json.loads((tmp_path / k / "campaign.json").read_text())["execution"]["calibration"]["per_key"]["0"]["cached"]
              for k in ("w1", "w2", "dask")}
    assert cached == {"w1": False, "w2": True, "dask": True}        # calibrated once, then from the cache
    per_key = summary["execution"]["calibration"]["per_key"]["0"]
    assert per_key["identified"] == {}             # the arm's notes: the consistency scheme's payload, not run here
    assert "Dask cluster" in json.loads((tmp_path / "dask" / "campaign.json").read_text())["execution"]["backend"]
    for name in ("results.parquet", "report.md", "figures/confusion_momentum.png", "figures/detection_vs_size.png",
                 "figures/delay_cdf.png"):
        assert (tmp_path / "w1" / name).is_file(), name


def _journal_lines(folder: Path) -> int:
    path = folder / "runs.jsonl"
    return path.read_text().count("\n") if path.is_file() else 0


def test_sigterm_mid_way_then_resume_gives_the_uninterrupted_table(tmp_path):
    spec_path = tmp_path / "linear.toml"
    spec_path.write_text(LINEAR.format(ff=16, faulty=16))
    whole = run_campaign(load_spec(spec_path), tmp_path / "whole", workers=1, progress=False)
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "robofdi.cli", "campaign", str(spec_path), "--out", str(out), "--workers", "2", "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while _journal_lines(out) < 3 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    done = _journal_lines(out)
    assert proc.returncode == 143, err
    assert "interrupted" in err and "--resume" in err and len(err.strip().splitlines()) == 1
    assert 3 <= done < 32
    assert not (out / "results.parquet").exists()
    # --resume runs only what is missing (here in the CLI's own process: the worker count changes nothing)
    resumed = subprocess.run(cmd[:-2] + ["1", "--quiet", "--resume"], capture_output=True, text=True, timeout=180)
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads((out / "campaign.json").read_text())
    assert summary["execution"]["runs_this_session"] == 32 - done
    _same(load(out).table, whole.table)
    # and a second plain run into the same folder is refused rather than mixed
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and "--resume" in again.stderr


def test_runs_prefix_is_a_prefix_of_the_full_campaign(tmp_path):
    spec = load_spec(LINEAR.format(ff=4, faulty=4).replace("seed = 5", "seed = 5\nrecords = true"))
    part = run_campaign(spec, tmp_path / "a", workers=1, runs=3, progress=False)
    whole = run_campaign(spec, tmp_path / "a", workers=1, resume=True, progress=False)
    assert sorted(set(part.table["index"])) == [0, 1, 2]
    _same(part.table, whole.table[whole.table["index"] < 3].reset_index(drop=True))
    assert len(whole.table) == 8
    free = whole.table[~whole.table["faulty"]]
    assert len(free) == 4 and free["fault"].isna().all() and (free["kind"] == "none").all()
    # records = true: every run's record, whose fault label matches its row
    from robofdi.record import load as load_record

    assert len(list((tmp_path / "a" / "records").glob("run-*.h5"))) == 8
    row = whole.table[whole.table["faulty"]].iloc[0]
    rec = load_record(tmp_path / "a" / "records" / f"run-{row['index']:06d}.h5")
    active = rec.time[rec.faults[row["fault"]].active.astype(bool)]
    assert active[0] == pytest.approx(row["onset"], abs=0.01)


class FlakyLinear(LinearSystem):
    """The linear plant, but a run raises when the drawn mission asks for a left-wheel mean speed above 7.5 rad/s."""

    name = "flaky-linear"

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        if mission.plan.mean[0] > 7.5:
            raise RuntimeError(f"left wheel mean {mission.plan.mean[0]:.2f} rad/s refused")
        return super().run(options, calibration, key, mission, faults, seed, diagnosers)


def test_a_run_that_raises_is_an_error_row_and_the_campaign_goes_on(tmp_path):
    register_system(FlakyLinear())
    spec = load_spec(LINEAR.format(ff=4, faulty=4).replace('name = "linear"', 'name = "flaky-linear"'))
    result = run_campaign(spec, tmp_path, workers=1, progress=False)
    t = result.table
    bad = t[t["error"].notna()]
    assert 0 < len(bad) < len(t)
    assert bad["error"].str.contains("RuntimeError: left wheel mean").all()
    assert bad["detected"].isna().all() and t.loc[t["error"].isna(), "false_alarms"].notna().all()
    summary = result.summary
    assert summary["runs"]["errors"] == bad["index"].nunique()
    assert "refused" in (tmp_path / "report.md").read_text()


@pytest.mark.parametrize("edit, message", [
    (("seed = 5", "seed = 5\nworkerz = 2"), "unknown field 'workerz'"),
    (("duration = 3.0", "duration = 3.0\nrobot = 'x'"), "system: unknown field 'robot'"),
    (('name = "linear"', 'name = "submarine"'), "unknown system 'submarine'"),
    (('kind = "sensor_bias"', 'kind = "sensor_melt"'), "faults[1].kind: unknown fault kind 'sensor_melt'"),
    (('targets = ["enc*"]', 'targets = ["wheel3"]'), "faults[1].targets: unknown target 'wheel3'"),
    (("magnitude_fraction = [0.05, 0.4]", "magnitude_fraction = [0.4, 0.05]"), "faults[0].magnitude_fraction: empty range"),
    (("magnitude_fraction = [0.05, 0.4]", "magnitude_fraction = [0.05, 1.5]"),
     "faults[0].magnitude_fraction: [0.05, 1.5] is outside [0, 1]"),
    (("magnitude_fraction = [0.05, 0.4]", "magnitude = [0.1, 2.5]"),
     "faults[0].magnitude: [0.1, 2.5] is outside the limits of target 'tau_L'"),
    (("onset_fraction = [0.4, 0.8]", "onset_fraction = [0.4, 1.0]"), "faults[0].onset_fraction"),
    (('targets = ["enc*"]', 'targets = ["enc*"]\nmagnitude_draw = "exponential"'),
     "faults[1].magnitude_draw: expected one of uniform, log_uniform"),
    (("magnitude_fraction = [0.05, 0.4]", 'magnitude_fraction = [0.0, 0.4]\nmagnitude_draw = "log_uniform"'),
     "faults[0].magnitude_draw: log_uniform needs a range with low > 0"),
])
def test_bad_spec_is_one_line_naming_the_field(edit, message):
    text = LINEAR.format(ff=2, faulty=2).replace(*edit, 1)
    with pytest.raises(RobofdiError) as info:
        load_spec(text)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_log_uniform_sizes_spread_evenly_over_the_decades():
    from robofdi.campaign.runs import draw_fault

    log_sizes = 'magnitude_fraction = [0.0001, 0.1]\nmagnitude_draw = "log_uniform"\nweight = 1e6'
    text = LINEAR.format(ff=0, faulty=400).replace("magnitude_fraction = [0.005, 0.05]", log_sizes)
    spec = load_spec(text)
    sizes = []
    for i in range(400):
        fault, info = draw_fault(spec, run_seed(spec.seed, i), 3.0)
        assert fault.kind == "sensor_bias"
        sizes.append(abs(fault.magnitude) / info["limit"])
    counts = np.histogram(np.log10(sizes), bins=[-4, -3, -2, -1])[0]
    assert counts.sum() == 400 and counts.min() > 100          # a third per decade, not 90 % in the top one


def test_cli_bad_spec_exits_2_with_one_line_before_any_run(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text(ARM.replace('kind = "actuator_additive"', 'kind = "actuator_explode"'))
    out = subprocess.run([sys.executable, "-m", "robofdi.cli", "campaign", str(spec), "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "bad.toml: faults[0].kind: unknown fault kind 'actuator_explode'" in out.stderr
    assert not (tmp_path / "o").exists()


def test_unreachable_scheduler_is_an_error_before_any_run(tmp_path):
    pytest.importorskip("dask.distributed")
    with pytest.raises(RobofdiError, match=r"--scheduler: cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"):
        DaskCluster("tcp://127.0.0.1:9", timeout=1.0)
    with pytest.raises(RobofdiError, match="--workers and --scheduler exclude each other"):
        run_campaign(load_spec(ARM), tmp_path / "o", workers=2, scheduler="tcp://127.0.0.1:9")
    assert not (tmp_path / "o").exists()


def test_shipped_specs_are_valid_and_installed():
    specs = shipped_specs()
    assert {"arm", "linear", "auv", "hydraulic", "helicopter"} <= set(specs)
    # every spec in experiments/campaigns/ is installed and valid
    assert {p.stem for p in (Path(__file__).resolve().parents[1] / "experiments" / "campaigns").glob("*.toml")} <= set(specs)
    auv, hyd = load_spec("auv"), load_spec("hydraulic")
    assert {f.kind for f in auv.faults} >= {"actuator_float", "component_thruster_blocking", "component_thruster_flooding",
                                            "actuator_loss_of_effectiveness", "sensor_dropout", "sensor_bias"}
    assert auv.faults[0].limits["thruster8"] == (40.0, "N") and auv.options.scenario.duration == 60.0
    assert {f.kind for f in hyd.faults} >= {"component_open_winding", "component_valve_sticking", "component_leak"}
    assert hyd.faults[2].limits["motor"] == (0.05, "mm^2")
    assert load_spec("helicopter").faults[0].targets == ("collective", "cyclic")
    arm = load_spec("arm")
    assert arm.system == "arm" and arm.runs >= 200 and arm.options.plant.robot == "arm6.xml"
    # a magnitude as a fraction of the target's limit: the arm's motor torque limits from its MJCF
    additive = arm.faults[0]
    assert additive.limits["joint1"] == (400.0, "N·m") and additive.limits["joint6"] == (50.0, "N·m")
    assert load_spec("linear").faults[1].limits["gyro"] == (2.5, "rad/s")


def test_clopper_pearson_and_detection_curve_against_closed_forms():
    # no event in n trials: the exact upper bound solves (1 − p)^n = α/2
    assert clopper_pearson(0, 300) == pytest.approx([0.0, 1 - 0.025 ** (1 / 300)], abs=1e-12)
    assert clopper_pearson(300, 300) == pytest.approx([0.025 ** (1 / 300), 1.0], abs=1e-12)
    assert clopper_pearson(0, 0) is None
    # pool-adjacent-violators by hand: outcomes 0 1 0 1 1 by increasing size → 0, ½, ½, 1, 1
    size, p = detection_curve(np.array([0.5, 0.1, 0.3, 0.2, 0.4]), np.array([1, 0, 0, 1, 1]))
    assert size.tolist() == [0.1, 0.2, 0.3, 0.4, 0.5]
    assert p.tolist() == pytest.approx([0.0, 0.5, 0.5, 1.0, 1.0])


def test_run_seed_derives_from_the_campaign_seed_and_index():
    from robofdi.seeding import stream

    assert run_seed(7, 12) == int(stream(7, "campaign", "run", "12").generate_state(1)[0])
    assert len({run_seed(7, i) for i in range(1000)}) == 1000



# ------------------------------------------------------------------------- the AUV, the hydraulic rig, the helicopter
AUV = """
seed = 2
fault_free_runs = 1
faulty_runs = 2
diagnosers = ["voltage_residual", "current_map"]

[system]
name = "auv"
duration = 14.0
calibration_runs = 1
calibration_duration = 40.0

[[faults]]
kind = "component_thruster_blocking"
magnitude = [1.0, 1.0]
onset_fraction = [0.4, 0.6]
"""

HYDRAULIC = """
seed = 1
fault_free_runs = 1
faulty_runs = 1
diagnosers = ["nlar", "nlar_better"]

[system]
name = "hydraulic"
duration = 3.0
calibration_runs = 2

[[faults]]
kind = "component_open_winding"
magnitude = [0.9, 1.0]
onset_fraction = [0.75, 0.85]
"""

HELICOPTER = """
seed = 4
fault_free_runs = 2
faulty_runs = 4

[system]
name = "helicopter"
robot_seeds = [0, 1]
duration = 8.0

[[faults]]
kind = "actuator_loss_of_effectiveness"
targets = ["collective"]
magnitude = [0.5, 0.6]
onset_fraction = [0.2, 0.3]
"""


def _one_and_two_workers(spec_text: str, tmp_path: Path, runs: int | None = None):
    spec = load_spec(spec_text)
    one = run_campaign(spec, tmp_path / "w1", workers=1, progress=False, report=False)
    two = run_campaign(spec, tmp_path / "w2", workers=2, runs=runs, progress=False, report=False)
    _same(one.table[one.table["index"] < len(two.table["index"].unique())].reset_index(drop=True), two.table)
    assert one.table["error"].isna().all(), one.table["error"].dropna().tolist()
    system = spec.campaign_system           # one calibration per robot seed, computed once, then from the cache
    assert all(system.calibrate(spec.options, key, spec.diagnosers)[1] for key in system.calibration_keys(spec.options))
    return one.table


def test_auv_campaign_detects_and_isolates_blocked_thrusters_same_table_on_two_workers(tmp_path):
    t = _one_and_two_workers(AUV, tmp_path, runs=2)
    assert len(t) == 3 * 2 and t.drop_duplicates("index")["mission"].nunique() == 3      # seeded random missions
    faulty = t[t["faulty"]]
    assert faulty["target"].str.fullmatch(r"thruster[1-8]").all() and (faulty["unit"] == "1").all()
    # a stalled rotor shows in the motor current within a second, isolated on its own thruster
    current = faulty[faulty["diagnoser"] == "current_map"]
    assert current["detected"].all() and current["correct"].all() and (current["delay"] < 1.0).all()
    assert (t[~t["faulty"]]["false_alarms"] == 0).all()


def test_hydraulic_campaign_detects_an_open_winding_same_table_on_two_workers(tmp_path):
    t = _one_and_two_workers(HYDRAULIC, tmp_path)
    mission = json.loads(t["mission"].iloc[0])
    assert 4.0 <= mission["target_rpm"] <= 6.0 and 0.9e-6 <= mission["throttle_area"] <= 2.5e-6   # a random profile
    faulty = t[t["faulty"]]
    assert (faulty["kind"] == "component_open_winding").all() and (faulty["target"] == "servovalve").all()
    assert faulty["detected"].all() and (faulty["delay"] < 0.3).all()
    assert (t[~t["faulty"]]["false_alarms"] == 0).all()


def test_helicopter_campaign_detects_loss_of_effectiveness_with_two_beliefs(tmp_path):
    t = _one_and_two_workers(HELICOPTER, tmp_path, runs=2)
    assert set(t["robot_seed"]) == {0, 1}
    faulty = t[t["faulty"]]
    assert (faulty["target"] == "collective").all() and faulty["size"].between(0.5, 0.6).all()
    assert faulty["detected"].all() and faulty["correct"].all()
    assert (t[~t["faulty"]]["false_alarms"] == 0).all()


def test_a_local_pool_has_started_every_worker_when_it_opens():
    """The executor would start workers one by one as tasks come; the pool starts them all at once (their interpreter
    and robofdi's campaign engine imported), so that a campaign's runs do not wait for one."""
    with LocalPool(2) as pool:
        processes = list(pool._pool._processes.values())
        assert len(processes) == 2 and all(p.is_alive() for p in processes)
        assert set(pool.map_unordered(os.getpid, [()] * 4)) <= {p.pid for p in processes}     # the tasks run there


def _profiling(dask_worker=None) -> bool:
    return dask_worker.periodic_callbacks["profile"].is_running()


def test_a_dask_cluster_pauses_its_workers_profiler_while_a_campaign_runs_and_starts_it_again():
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        with distributed.Client(cluster.scheduler_address) as client:
            assert set(client.run(_profiling).values()) == {True}
            with DaskCluster(cluster.scheduler_address) as pool:
                assert set(pool.client.run(_profiling).values()) == {False}
            assert set(client.run(_profiling).values()) == {True}
            with DaskCluster(cluster.scheduler_address, pause_profiler=False) as pool:
                assert set(pool.client.run(_profiling).values()) == {True}
