"""Shared fixtures: one calibration of the chapter-3 arm per test session (real MuJoCo + Pinocchio runs)."""
from __future__ import annotations

import os
from dataclasses import replace

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session", autouse=True)
def _calibration_cache(tmp_path_factory):
    """The suite's calibrations are cached in a folder of its own (never the user's ~/.cache/robofdi); CLI
    subprocesses inherit it. Parallel workers (``pytest -n``, pytest-xdist) share one folder, so a calibration
    is computed once per suite run (the cache's writes are atomic; tests that need a cold cache use their own)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        folder = tmp_path_factory.getbasetemp().parent / "robofdi-cache"
        folder.mkdir(exist_ok=True)
    else:
        folder = tmp_path_factory.mktemp("robofdi-cache")
    os.environ["ROBOFDI_CACHE"] = str(folder)


@pytest.fixture(scope="session")
def ch3():
    """The ch3-actuator scenario (shorter low-velocity calibration runs, to keep the suite fast) and its calibration."""
    from robofdi.experiments.ch3_industrial_robot import scenario
    from robofdi.systems.arm import calibrate, calibration_records

    sc = scenario("ch3-actuator", seed=0, calibration_low_velocity_time=8.0)
    cal = calibrate(sc, calibration_records(sc))
    return sc, cal


@pytest.fixture(scope="session")
def ch3_runs(ch3):
    """Fault-free, actuator-fault and sensor-fault runs of the book trajectory with every scheme in the loop."""
    from robofdi.experiments.ch3_industrial_robot import FAULTS
    from robofdi.systems.arm import run_scenario

    sc, cal = ch3
    return {
        "fault_free": run_scenario(replace(sc, faults=()), cal),
        "actuator": run_scenario(sc, cal),
        "sensor": run_scenario(replace(sc, name="ch3-sensor", faults=FAULTS["ch3-sensor"]), cal),
    }
