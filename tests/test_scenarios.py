"""Scenario tests: the book's chapter-3 experiment on the simulated arm, asserting real diagnosis outcomes."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robofdi.experiments.ch3_industrial_robot import FAULTS
from robofdi.evaluate import evaluate_diagnoser, summarize
from robofdi.observers.arm_schemes import BOOK_SCHEMES as SCHEMES
from robofdi.systems.arm import run_scenario


def _detection(record, diagnoser, fault_name, faults):
    faults = [f.to_dict() for f in faults]
    result = evaluate_diagnoser(record, diagnoser, faults)
    return next(d for d in result["detections"] if d["fault"] == fault_name), result


@pytest.mark.parametrize("scheme", SCHEMES)
def test_fault_free_thresholds_transfer_to_the_book_trajectory(ch3_runs, scheme):
    """Thresholds calibrated on other (worst-case) motions hold on the book trajectory to within 30 %: with the
    honest harness's velocity noise, the torque-row noise grows with M̂(q), and the book trajectory reaches
    configurations the calibration runs did not (measured over seeds 0–3: peak |r|/ρ 0.78–1.25, README)."""
    trace = ch3_runs["fault_free"].diagnosers[scheme]
    peak = (np.abs(trace.residual) / trace.threshold).max()
    assert peak < 1.3, f"{scheme}: peak |r|/threshold {peak:.2f}"
    if scheme == "momentum":                 # the filtered baseline keeps a real margin
        assert peak < 0.9 and not trace.alarm.any()


@pytest.mark.parametrize("scheme", ["recursive", "adaptive"])
def test_abrupt_joint3_actuator_fault_detected_within_20ms_and_isolated(ch3_runs, scheme):
    rec = ch3_runs["actuator"]
    det, result = _detection(rec, scheme, "tau3", FAULTS["ch3-actuator"])
    assert det["time"] is not None and det["delay"] <= 0.020
    assert det["isolated"] == "joint3"
    assert result["false_alarms"] == 0
    trace = rec.diagnosers[scheme]
    before = trace.time < 1.0
    assert not trace.alarm[before].any(), "alarm before the fault onset"


def test_incipient_joint5_actuator_fault_detected_by_adaptive(ch3_runs):
    det, _ = _detection(ch3_runs["actuator"], "adaptive", "tau5", FAULTS["ch3-actuator"])
    assert det["time"] is not None and det["delay"] < 0.1
    assert det["isolated"] == "joint5"


def _peak_over_threshold(record, scheme, component, onset, window=0.3):
    """max |r|/ρ of one residual component over ``window`` s from the fault onset."""
    trace = record.diagnosers[scheme]
    j = trace.components.index(component)
    inside = (trace.time >= onset) & (trace.time < onset + window)
    return float(np.max(np.abs(trace.residual[inside, j])) / trace.threshold[j])


def test_time_delayed_is_less_sensitive_to_the_incipient_fault_than_recursive(ch3_runs):
    """The book's finding (Figs. 2 and 4): time-delayed estimation sees only abrupt faults. For the incipient
    δτ₅ (time constant 80 ms) the time-delayed torque residual is its per-sample increment, at most
    40(1 − e^{−0.025}) ≈ 0.99 N·m, while the recursive one low-passes it with gain up to 1/γ (spec §3.4)."""
    td = _peak_over_threshold(ch3_runs["actuator"], "time_delayed", "joint5", 3.0)
    rec = _peak_over_threshold(ch3_runs["actuator"], "recursive", "joint5", 3.0)
    assert rec > 1.0 and td < rec / 2


def test_torque_space_isolation_of_the_joint3_fault(ch3_runs):
    """Digest check 6: in torque space the time-delayed residual's fault contribution sits on joint 3 (ratio > 5 to
    every other joint; crosstalk is round-off, as r_τ = (M̂/T) r₂ undoes M̂⁻¹ exactly under offline injection), its
    peak the first per-sample increment of δτ₃ within the 2 ms FD step. The raw peaks are noise on joints 1-2."""
    from robofdi.experiments.ch3_industrial_robot import torque_space_isolation

    tau3 = FAULTS["ch3-actuator"][0].to_dict()
    iso = torque_space_isolation(ch3_runs["actuator"], ch3_runs["fault_free"], tau3)
    assert iso["argmax_contribution"] == "joint3" and iso["contribution_ratio"] > 5
    assert 20.0 < iso["contribution_peak"][2] <= 60.0


def test_joint3_actuator_fault_identified(ch3_runs):
    """δτ̂₃ = (M̂/T) η̂ after isolation (Sec. 6) carries the uncertainty bias η (friction, ripple): the spec's
    harness read 64–72 N·m against the true 60 — "fairly accurate" in the book. Zero before isolation."""
    trace = ch3_runs["actuator"].diagnosers["recursive"]
    est = trace.estimate[:, trace.estimate_components.index("joint3")]
    window = (trace.time > 1.2) & (trace.time < 1.9)
    assert np.all((est[window] > 57.0) & (est[window] < 75.0))
    assert np.all(est[trace.time < 1.0] == 0.0)


def test_joint5_position_sensor_fault_isolated_to_its_position_component(ch3_runs):
    rec = ch3_runs["sensor"]
    for scheme in ("time_delayed", "recursive", "adaptive"):
        det, result = _detection(rec, scheme, "x5", FAULTS["ch3-sensor"])
        assert det["isolated"] == "joint5_pos", scheme
        assert det["delay"] <= 0.010, scheme
        trace = rec.diagnosers[scheme]
        k = np.searchsorted(trace.time, det["time"])
        alarmed = {c for c, a in zip(trace.components, trace.alarm[k]) if a}
        assert "joint5_pos" in alarmed and not any(c.endswith("_pos") and c != "joint5_pos" for c in alarmed)
        # identification: the summed position increments track δx₁,₅ within 15 % of its 4 mrad after 1 s
        # (the sum also integrates the position-row uncertainty, ~1e-6 rad per sample)
        est = trace.estimate[-1, trace.estimate_components.index("joint5_pos")]
        assert abs(est - 0.004) < 0.0006, (scheme, est)


def test_position_only_scheme_isolates_sensor_and_actuator_faults(ch3_runs):
    """With backward-difference velocities a position fault also raises its velocity row (eq. (48)); the
    sensor signature requires both, so the incipient δx₁,₅ is not taken for an actuator fault."""
    det, _ = _detection(ch3_runs["sensor"], "position_only", "x5", FAULTS["ch3-sensor"])
    assert det["isolated"] == "joint5_pos"
    for fault, target in (("tau3", "joint3"), ("tau5", "joint5")):
        det, _ = _detection(ch3_runs["actuator"], "position_only", fault, FAULTS["ch3-actuator"])
        assert det["isolated"] == target


def test_momentum_baseline_cannot_see_position_sensor_faults(ch3_runs):
    """The momentum observer uses q only through M, C, g: a 6 mrad position fault stays below its thresholds."""
    det, _ = _detection(ch3_runs["sensor"], "momentum", "x3", FAULTS["ch3-sensor"])
    assert det["time"] is None


def test_online_actuator_fault_in_the_closed_loop(ch3):
    """Faults injected into the loop (the plant gets the faulty torque): δτ₃ still detected and isolated."""
    sc, cal = ch3
    online = replace(sc, injection="online", duration=1.5, faults=sc.faults[:1], schemes=("recursive", "momentum"))
    rec = run_scenario(online, cal)
    for scheme in ("recursive", "momentum"):
        det, result = _detection(rec, scheme, "tau3", online.faults)
        assert det["isolated"] == "joint3" and det["delay"] <= 0.020, scheme
        assert result["false_alarms"] == 0
    # the controller fights the fault: joint 3 is displaced but the loop stays stable
    err = np.abs(rec.truth_state[:, 2] - rec.signals["reference"][:, 2])
    assert err[rec.time < 1.0].max() < 0.02 and 0.005 < err.max() < 0.5


def test_book_run_labels_and_summary(ch3_runs):
    """The record's ground truth is the book's profiles, δτ₃ = 60(1 − e^{−(t−1)/0.002}) from 1 s and
    δτ₅ = 40(1 − e^{−(t−3)/0.08}) from 3 s, over its 4 s trajectory; summary.json (faults read from the record)
    lists those faults, every scheme, the estimate RMSE in N·m, and delay = time − onset for every detection."""
    rec = ch3_runs["actuator"]
    for name, amplitude, onset, tau in (("tau3", 60.0, 1.0, 0.002), ("tau5", 40.0, 3.0, 0.08)):
        label = rec.faults[name]
        np.testing.assert_array_equal(label.active, rec.time >= onset - 1e-9)
        book = np.where(rec.time >= onset - 1e-9, amplitude * (1 - np.exp(-(rec.time - onset) / tau)), 0.0)
        np.testing.assert_allclose(label.value, book, rtol=1e-9, atol=1e-9)
    summary = summarize(rec, "ch3-actuator")
    assert summary["system"] == "arm6" and summary["seed"] == 0
    assert summary["duration"] == pytest.approx(4.0)
    assert [(f["name"], f["target"], f["onset"], f["end"]) for f in summary["faults"]] == [
        ("tau3", "joint3", 1.0, None), ("tau5", "joint5", 3.0, None)]
    assert set(summary["diagnosers"]) == set(SCHEMES)
    assert summary["units"]["estimate_rmse"] == {"tau3": "N·m", "tau5": "N·m"}
    onsets = {"tau3": 1.0, "tau5": 3.0}
    for name, d in summary["diagnosers"].items():
        for det in d["detections"]:
            if det["time"] is not None:
                assert det["delay"] == pytest.approx(det["time"] - onsets[det["fault"]]) and det["delay"] >= 0, name
