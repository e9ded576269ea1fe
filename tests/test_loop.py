"""The closed loop, the run record and the command line, on the real simulated arm."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.control import ComputedTorque
from robofdi.decision import ThresholdDecision
from robofdi.evaluate.run_folder import keep_partial
from robofdi.experiments.ch3_industrial_robot import FAULTS, scenario
from robofdi.faults import Fault, Step
from robofdi.ftc import FaultCompensation
from robofdi.loop import ORACLE, ClosedLoop, Diagnosis, Rates, RunAborted, RunInterrupted, diagnose_record
from robofdi.observers import MomentumObserver
from robofdi.observers.arm_schemes import arm_schemes
from robofdi.record import load
from robofdi.systems.arm import run_scenario
from robofdi.sims import ArmSimulator


def _short(seed=0, **kw):
    """The book's arm and trajectory for 1.2 s, with δτ₃ only (δτ₅ starts at 3 s)."""
    kw.setdefault("faults", FAULTS["ch3-actuator"][:1])
    return scenario("ch3-actuator", seed=seed, duration=1.2, schemes=("recursive", "momentum"), **kw)


BOOK_RATES = Rates(1000.0, 500.0)


def _arm_loop(faults=(), diagnoses=None, rates=BOOK_RATES, **kw):
    """arm6 on the book's trajectory, online, with the honest default harness."""
    sc = _short()
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    return ClosedLoop(sim, ComputedTorque(model, torque_limit=model.torque_limit), sc.motion, faults,
                      diagnoses or {}, rates, **kw), sc, model


def test_offline_replay_of_a_record_equals_the_online_diagnosis(ch3):
    sc, cal = ch3
    rec = run_scenario(_short(), cal)
    model = sc.nominal_model(sc.simulator())
    settings = sc.scheme_settings(sc.rates)
    for name in ("recursive", "momentum"):
        offline = diagnose_record(rec, Diagnosis(arm_schemes(model, settings, cal.theta0, [name])[name]))
        np.testing.assert_array_equal(offline.residual, rec.diagnosers[name].residual)


def test_record_round_trip_is_exact_and_every_dataset_has_units_and_columns(ch3, tmp_path):
    _, cal = ch3
    rec = run_scenario(_short(), cal)
    path = rec.save(tmp_path / "run.h5")
    back = load(path)
    for attr in ("system", "scenario", "seed", "rates", "meta", "columns", "units"):
        assert getattr(back, attr) == getattr(rec, attr), attr
    np.testing.assert_array_equal(back.time, rec.time)
    np.testing.assert_array_equal(back.truth_state, rec.truth_state)
    np.testing.assert_array_equal(back.u_applied, rec.u_applied)
    for k in rec.signals:
        np.testing.assert_array_equal(back.signals[k], rec.signals[k])
    for k, lab in rec.faults.items():
        np.testing.assert_array_equal(back.faults[k].active, lab.active)
        np.testing.assert_array_equal(back.faults[k].value, lab.value)
        assert back.faults[k].unit == lab.unit == "N·m"
    for k, tr in rec.diagnosers.items():
        b = back.diagnosers[k]
        for field in ("time", "residual", "threshold", "alarm", "estimate"):
            np.testing.assert_array_equal(getattr(b, field), getattr(tr, field))
        assert list(b.isolated) == list(tr.isolated) and b.components == tr.components and b.units == tr.units
    # plain h5py: every dataset names its columns and their units, one per column
    with h5py.File(path) as f:
        datasets = []
        f.visititems(lambda name, obj: datasets.append((name, obj)) if isinstance(obj, h5py.Dataset) else None)
        for name, ds in datasets:
            columns, units = json.loads(ds.attrs["columns"]), json.loads(ds.attrs["units"])
            width = ds.shape[1] if ds.ndim == 2 else (ds.shape[0] if name.endswith("threshold") else 1)
            assert len(columns) == len(units) == width, name
        assert json.loads(f["signals/u"].attrs["units"]) == ["N·m"] * 6
        assert json.loads(f["signals/y_meas"].attrs["columns"])[:2] == ["joint1_pos", "joint2_pos"]
        assert json.loads(f["signals/y_meas"].attrs["units"])[5:7] == ["rad", "rad/s"]
        assert json.loads(f["diagnosers/recursive/residual"].attrs["units"])[5:7] == ["rad", "N·m"]
    np.testing.assert_array_equal(back.column("signals/u", "joint3"), rec.signals["u"][:, 2])
    with pytest.raises(RobofdiError, match="no column 'joint9'"):
        back.column("signals/u", "joint9")


def test_same_seed_gives_a_byte_identical_record(ch3, tmp_path):
    _, cal = ch3
    sha = []
    for k in range(2):
        rec = run_scenario(_short(seed=3), cal)
        sha.append(hashlib.sha256(rec.save(tmp_path / f"{k}.h5").read_bytes()).hexdigest())
    other = run_scenario(_short(seed=4), cal)
    assert sha[0] == sha[1]
    assert not np.array_equal(rec.signals["y_meas"], other.signals["y_meas"])


def test_noise_streams_are_independent_per_run_key_and_sensor(ch3):
    """Calibration and test runs never replay the same sensor noise; the plant (ripple) stays the same robot."""
    _, cal = ch3
    loop, sc, _ = _arm_loop()
    a = loop.run(0.5, sc.start_pose, seed=0, run_key="run")
    b = loop.run(0.5, sc.start_pose, seed=0, run_key="calibration/low_velocity")
    na = a.signals["y_meas"][:, 6:] - a.signals["y_true"][:, 6:]          # velocity noise
    nb = b.signals["y_meas"][:, 6:] - b.signals["y_true"][:, 6:]
    assert abs(np.corrcoef(na[:, 2], nb[:, 2])[0, 1]) < 0.1                # other run key: other noise
    assert abs(np.corrcoef(na[:, 2], na[:, 3])[0, 1]) < 0.1                # other sensor: other noise
    assert 0.5e-3 < na.std() < 2e-3                                       # the drive's velocity noise, 1e-3 rad/s


class _BrokenEncoder(ArmSimulator):
    """A plant whose encoder driver starts returning NaN at 0.5 s."""

    def measure(self):
        y = super().measure()
        return y * np.nan if self.data.time >= 0.5 else y


def test_a_failing_run_keeps_what_it_recorded(ch3):
    sc, cal = ch3
    sim = _BrokenEncoder(sc.plant.robot)
    model = sim.nominal_model()
    d = arm_schemes(model, sc.scheme_settings(sc.rates), cal.theta0, ["recursive"])["recursive"]
    loop = ClosedLoop(sim, ComputedTorque(model), sc.motion, (), {"recursive": Diagnosis(d)}, Rates(1000, 500))
    with pytest.raises(RunAborted) as info:
        loop.run(1.2, sc.start_pose)
    assert "non-finite" in str(info.value) or "'y'" in str(info.value)
    rec = info.value.record
    assert rec.meta["aborted"] and 0.45 < rec.time[-1] < 0.5
    assert len(rec.truth_state) == len(rec.time) == len(rec.u_applied) and np.all(np.isfinite(rec.truth_state))
    assert len(rec.diagnosers["recursive"].time) >= 240


def test_ctrl_c_keeps_partial_h5(tmp_path):
    """Ctrl-C in the middle of a run: the experiment's run folder keeps partial.h5 with everything so far."""
    loop, sc, _ = _arm_loop()

    ticks = []

    def interrupt_at_600(_):
        ticks.append(1)
        if len(ticks) == 600:
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted, match="interrupted") as info, keep_partial(tmp_path):
        loop.run(1.2, sc.start_pose, progress=interrupt_at_600)
    assert info.value.partial_path == tmp_path / "partial.h5"
    rec = load(tmp_path / "partial.h5")
    assert rec.meta["aborted"] and len(rec.time) == 600 and rec.time[-1] == pytest.approx(0.599)


def test_a_diagnoser_on_a_model_of_another_arm_is_rejected(tmp_path):
    """A nominal model whose joints differ from the simulator's is refused when the loop is built."""
    from robofdi import ASSETS
    from robofdi.models import ManipulatorModel

    other = tmp_path / "other_arm.xml"
    other.write_text((ASSETS / "arm6.xml").read_text().replace('"joint4"', '"wrist_roll"'))
    wrong = MomentumObserver(ManipulatorModel(other), 0.002)
    with pytest.raises(RobofdiError, match="wrist_roll"):
        _arm_loop(diagnoses={"momentum": Diagnosis(wrong)})


def test_fault_on_a_joint_the_arm_does_not_have_is_rejected_when_the_loop_is_built():
    with pytest.raises(RobofdiError, match="joint7"):
        _arm_loop([Fault("tau7", "actuator_additive", "joint7", onset=1.0, magnitude=10.0)])
    with pytest.raises(RobofdiError, match="lock_in_place.*offline"):
        _arm_loop([Fault("l", "actuator_lock_in_place", "joint3", onset=1.0)], injection="offline")


@pytest.mark.parametrize(
    "kwargs, field",
    [(dict(diagnosis_hz=300.0), "diagnosis_hz"), (dict(control_hz=-1.0), "control_hz"), (dict(input_hold="last"), "input_hold")],
)
def test_bad_rates_name_the_field(kwargs, field):
    with pytest.raises(RobofdiError, match=field):
        Rates(**kwargs)


def test_rates_must_match_the_simulator():
    with pytest.raises(RobofdiError, match="control period"):
        _arm_loop(rates=Rates(500.0, 500.0))


class _Probe:
    """A diagnoser that only records what it is told (to check the loop's sampling, not the physics)."""

    def __init__(self, n):
        self.components = self.estimate_components = self.inputs = [f"joint{i + 1}" for i in range(n)]
        self.measurements = [f"joint{i + 1}_{k}" for k in ("pos", "vel") for i in range(n)]
        self.estimate_modes = ["level"] * n
        self.units = {"residual": ["1"] * n, "estimate": ["1"] * n}
        self.seen = []

    def reset(self):
        self.seen = []

    def signatures(self):
        return []

    def update(self, y, u):
        from robofdi.observers import Residual

        self.seen.append((np.array(y), np.array(u)))
        return Residual(np.zeros(len(u)), np.zeros(len(u)))


@pytest.mark.parametrize("diagnosis_hz, hold", [(500.0, "mean"), (250.0, "mean"), (250.0, "first"), (1000.0, "mean")])
def test_diagnosers_get_the_input_held_over_the_interval_that_ended(diagnosis_hz, hold):
    probe = _Probe(6)
    loop, sc, _ = _arm_loop(diagnoses={"probe": Diagnosis(probe)}, rates=Rates(1000.0, diagnosis_hz, hold))
    rec = loop.run(0.2, sc.start_pose)
    ratio = int(1000 / diagnosis_hz)
    tr = rec.diagnosers["probe"]
    np.testing.assert_allclose(tr.time, rec.time[::ratio])
    u = rec.signals["u_diag"]
    for k, (y, u_seen) in enumerate(probe.seen[1:], start=1):
        j = k * ratio
        np.testing.assert_array_equal(y, rec.signals["y_meas"][j])
        held = u[j - ratio:j]
        np.testing.assert_allclose(u_seen, held.mean(axis=0) if hold == "mean" else held[0], rtol=1e-12, atol=1e-12)


def test_offline_injection_tells_the_diagnosers_u_minus_the_fault():
    """Offline (the book's emulation): the plant runs fault-free, the diagnosers are told ū = u − δτ, so a plant
    receiving ū + δτ would have received u; the label is δτ."""
    f = Fault("tau3", "actuator_additive", "joint3", onset=0.5, magnitude=60.0)
    loop, sc, _ = _arm_loop([f], injection="offline")
    rec = loop.run(1.0, sc.start_pose)
    u, u_diag, lab = rec.signals["u"], rec.signals["u_diag"], rec.faults["tau3"]
    on = rec.time >= 0.5
    np.testing.assert_allclose(u_diag[on, 2], u[on, 2] - 60.0)
    np.testing.assert_allclose(lab.value[on], 60.0)
    np.testing.assert_array_equal(u_diag[~on], u[~on])
    limit = np.array([400.0, 400.0, 250.0, 80.0, 80.0, 50.0])          # arm6.xml's motor ctrlranges
    np.testing.assert_array_equal(rec.u_applied, np.clip(u, -limit, limit))


def test_saturated_actuator_labels_what_the_plant_received():
    """A 400 N·m fault on joint 3 (limit 250): the plant gets 250, and the label says how much of the fault arrived."""
    f = Fault("big", "actuator_additive", "joint3", onset=0.3, magnitude=400.0)
    loop, sc, _ = _arm_loop([f])
    rec = loop.run(0.6, sc.start_pose)
    on = rec.time >= 0.3
    assert np.all(np.abs(rec.u_applied[:, 2]) <= 250.0 + 1e-9) and np.any(rec.u_applied[on, 2] == 250.0)
    faulty = rec.signals["u"][on, 2] + 400.0
    np.testing.assert_allclose(rec.faults["big"].value[on], rec.u_applied[on, 2] - np.clip(rec.signals["u"][on, 2], -250, 250))
    clipped = faulty > 250.0                      # until the controller backs off, only part of the fault arrives
    assert clipped[:5].all() and np.all(rec.faults["big"].value[on][clipped] < 400.0)
    np.testing.assert_allclose(rec.faults["big"].value[on][~clipped], 400.0)


class _HealthLog:
    """An accommodation that passes u through and logs when it learns what."""

    def __init__(self):
        self.log = []

    def reset(self):
        self.log = []

    def update(self, u_cmd, health):
        self.log.append(health)
        return u_cmd


def test_health_reaches_the_accommodation_one_diagnosis_sample_late():
    f = Fault("tau3", "actuator_additive", "joint3", onset=0.3, magnitude=150.0)
    obs = MomentumObserver(_arm_loop()[2], 0.002)
    decision = ThresholdDecision(obs.components, np.full(6, 40.0), obs.signatures(), blanking=5)
    log = _HealthLog()
    loop, sc, _ = _arm_loop([f], {"momentum": Diagnosis(obs, decision)}, accommodation=log, health_source="momentum")
    rec = loop.run(0.6, sc.start_pose)
    iso = rec.diagnosers["momentum"]
    k = int(np.flatnonzero(iso.isolated != "")[0])
    t_iso = iso.time[k]
    first = next(j for j, h in enumerate(log.log) if h.isolated)
    assert log.log[first].time == t_iso and "joint3" in log.log[first].isolated
    assert rec.time[first] == pytest.approx(t_iso + 0.002)       # used from the next diagnosis sample on
    assert log.log[first].estimate["joint3"] > 40.0                # the residual that crossed its threshold


def test_compensation_restores_tracking_and_the_oracle_bounds_it():
    """An online 150 N·m step on joint 3: compensating the identified fault after isolation brings joint 3's
    tracking error back to the fault-free one (the wrist's friction error, outside the model, stays as it was);
    the oracle (true fault) is the bound."""
    f = Fault("tau3", "actuator_additive", "joint3", onset=0.4, magnitude=150.0)
    joints = [f"joint{i}" for i in range(1, 7)]

    def joint3_rms(accommodation=None, health=None, faults=(f,)):
        obs = MomentumObserver(_arm_loop()[2], 0.002)
        decision = ThresholdDecision(obs.components, np.full(6, 40.0), obs.signatures(), blanking=5)
        loop, sc, _ = _arm_loop(faults, {"momentum": Diagnosis(obs, decision)}, accommodation=accommodation,
                                health_source=health)
        rec = loop.run(1.2, sc.start_pose)
        after = rec.time >= 0.4
        return np.sqrt(np.mean((rec.signals["reference"][after, 2] - rec.truth_state[after, 2]) ** 2))

    none, free = joint3_rms(), joint3_rms(faults=())
    compensated = joint3_rms(FaultCompensation(joints), "momentum")
    oracle = joint3_rms(FaultCompensation(joints), ORACLE)
    assert none > 5 * compensated
    assert compensated < 1.5 * free and oracle < 1.5 * free


def test_a_component_fault_changes_the_plant_and_is_labelled():
    """5 kg more payload from 0.3 s: against the same run without it (same noise), the momentum residual of the
    shoulder (joint 2) moves by the payload's gravity torque, tens of N·m; before onset nothing differs."""
    f = Fault("load", "component_mass", "payload", onset=0.3, magnitude=5.0, profile=Step())
    traces = {}
    for faults in ((f,), ()):
        obs = MomentumObserver(_arm_loop()[2], 0.002)
        loop, sc, _ = _arm_loop(faults, {"momentum": Diagnosis(obs)})
        rec = loop.run(0.8, sc.start_pose, seed=5)
        traces[bool(faults)] = rec.diagnosers["momentum"]
        if faults:
            assert rec.faults["load"].unit == "kg" and np.all(rec.faults["load"].value[rec.time >= 0.3] == 5.0)
    t = traces[True].time
    diff = traces[True].residual[:, 1] - traces[False].residual[:, 1]
    assert np.all(diff[t < 0.3] == 0.0)
    assert np.abs(diff[t > 0.5]).min() > 10.0
    with pytest.raises(RobofdiError, match="offline"):
        _arm_loop([f], injection="offline")


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
    """`robofdi run ch3-sensor`: table on stdout; summary.json (contract), record, the lead's figures, replay in the
    folder."""
    out = _cli("run", "ch3-sensor", "--out", str(tmp_path), "--quiet", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "joint5_pos" in out.stdout and "time_delayed" in out.stdout
    run_dir = tmp_path / "ch3-sensor-seed0"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["experiment"] == "ch3-sensor" and summary["seed"] == 0
    # on the honest harness, the adaptive scheme (the book's best trade-off) stays silent on the fault-free run
    assert summary["fault_free_false_alarms"]["adaptive"] == 0
    det = {d["fault"]: d for d in summary["diagnosers"]["recursive"]["detections"]}
    assert det["x3"]["isolated"] == "joint3_pos" and det["x5"]["isolated"] == "joint5_pos"
    assert all(check["pass"] for check in summary["reproduction"])
    assert load(run_dir / "record.h5").diagnosers.keys() == summary["diagnosers"].keys()
    # the lead's residual figure and the estimates; the printout says how to draw the other five
    assert summary["lead"]["diagnoser"] == "adaptive"
    assert sorted(p.name for p in (run_dir / "figures").iterdir()) == ["estimates.png", "residuals_adaptive.png"]
    assert (run_dir / "figures" / "residuals_adaptive.png").stat().st_size > 10_000
    assert f"`robofdi figures {run_dir}` draws the 5 other diagnosers' residual figures" in out.stdout
    html = (run_dir / "replay.html").read_text()
    assert "<script" in html and "src=\"http" not in html
