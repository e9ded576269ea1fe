"""Metrics and summary.json from hand-made records (robofdi.evaluate)."""
import json
import math

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.evaluate import evaluate_diagnoser, results_table, summarize, write_summary
from robofdi.evaluate.metrics import peak_ratios
from robofdi.record import DiagnoserTrace, FaultLabels, Record

DT_RECORD, DT_DIAG, DURATION = 0.001, 0.002, 4.0
T_RECORD = np.round(np.arange(int(DURATION / DT_RECORD)) * DT_RECORD, 9)
T_DIAG = np.round(np.arange(int(DURATION / DT_DIAG)) * DT_DIAG, 9)
COMPONENTS = ["joint3_tau", "joint5_tau"]


def labels(onset, end=None, value=lambda t: 2.0 * (t - 1.0)):
    active = (T_RECORD >= onset) & ((T_RECORD < end) if end is not None else True)
    return FaultLabels(active=active, value=np.where(active, value(T_RECORD), 0.0))


def spec(name, target, onset, end=None):
    return {"name": name, "kind": "actuator_additive", "target": target, "onset": onset, "end": end, "magnitude": 2.0}


def trace(alarm_on, isolated_from=(), estimate=None):
    """alarm_on: list of (component, start, stop) windows; isolated_from: list of (name, time)."""
    alarm = np.zeros((T_DIAG.size, len(COMPONENTS)), dtype=bool)
    for j, start, stop in alarm_on:
        alarm[(T_DIAG >= start - 1e-9) & (T_DIAG < stop - 1e-9), j] = True
    isolated = np.array(["+".join(n for n, t0 in isolated_from if t >= t0 - 1e-9) for t in T_DIAG], dtype=object)
    est = np.zeros((T_DIAG.size, 1)) if estimate is None else estimate.reshape(-1, 1)
    return DiagnoserTrace(
        time=T_DIAG, residual=alarm * 2.0, threshold=np.ones(2), alarm=alarm, isolated=isolated,
        estimate=est, components=list(COMPONENTS), estimate_components=["joint3"],
    )


def record(faults, diagnosers):
    return Record(
        system="arm6", scenario="test", seed=0, rates={"control": 1000, "diagnosis": 500},
        time=T_RECORD, truth_state=np.zeros((T_RECORD.size, 2)), faults=faults, diagnosers=diagnosers,
    )


def single_fault_record():
    iso_time = 1.010
    err = 0.5 * np.where(np.arange(T_DIAG.size) % 2 == 0, 1.0, -1.0)  # |error| = 0.5 at every sample
    estimate = np.where(T_DIAG >= iso_time - 1e-9, 2.0 * (T_DIAG - 1.0) + err, 0.0)
    tr = trace(
        alarm_on=[(0, 0.500, 0.504), (0, 1.006, DURATION)],  # a 2-sample false-alarm episode, then the fault
        isolated_from=[("joint3", iso_time)],
        estimate=estimate,
    )
    return record({"tau3": labels(1.0)}, {"recursive": tr}), [spec("tau3", "joint3", 1.0)]


def test_detection_delay_isolation_and_false_alarm_episode():
    rec, faults = single_fault_record()
    m = evaluate_diagnoser(rec, "recursive", faults)
    assert m["false_alarms"] == 1
    assert m["first_false_alarm_time"] == pytest.approx(0.5)
    (d,) = m["detections"]
    assert d["fault"] == "tau3" and d["isolated"] == "joint3"
    assert d["time"] == pytest.approx(1.006) and d["delay"] == pytest.approx(0.006)
    assert m["missed_detections"] == 0
    assert m["isolation_correct"] == {"tau3": True}
    assert m["time_to_isolation"]["tau3"] == pytest.approx(0.010)


def test_time_to_correct_isolation_follows_a_revised_isolation():
    """A wrong first call (joint5 at 1.010 s) revised to the true target at 1.200 s: the first isolation stays
    wrong, the time to correct isolation and the final call see the revision."""
    tr = trace(alarm_on=[(0, 1.006, DURATION)])
    tr.isolated = np.where(T_DIAG >= 1.2 - 1e-9, "joint3", np.where(T_DIAG >= 1.01 - 1e-9, "joint5", "")).astype(object)
    m = evaluate_diagnoser(record({"tau3": labels(1.0)}, {"recursive": tr}), "recursive", [spec("tau3", "joint3", 1.0)])
    assert m["isolation_correct"] == {"tau3": False} and m["time_to_isolation"]["tau3"] == pytest.approx(0.010)
    assert m["time_to_correct_isolation"]["tau3"] == pytest.approx(0.200)
    assert m["final_isolation_correct"] == {"tau3": True}
    first = evaluate_diagnoser(*single_fault_record()[:1], "recursive", single_fault_record()[1])
    assert first["time_to_correct_isolation"]["tau3"] == pytest.approx(first["time_to_isolation"]["tau3"])


def test_estimate_rmse_after_isolation_is_exact():
    rec, faults = single_fault_record()
    assert evaluate_diagnoser(rec, "recursive", faults)["estimate_rmse"]["tau3"] == pytest.approx(0.5, abs=1e-12)


def test_estimate_rmse_none_without_estimate_component_or_wrong_isolation():
    rec, _ = single_fault_record()
    m = evaluate_diagnoser(rec, "recursive", [spec("tau3", "joint4", 1.0)])  # isolated "joint3" is wrong
    assert m["isolation_correct"]["tau3"] is False and m["estimate_rmse"]["tau3"] is None
    rec.diagnosers["recursive"].estimate_components = ["joint1"]
    assert evaluate_diagnoser(rec, "recursive", [spec("tau3", "joint3", 1.0)])["estimate_rmse"]["tau3"] is None


def test_missed_detection_gives_none():
    tr = trace(alarm_on=[(0, 0.2, 0.3)])
    rec = record({"tau3": labels(1.0, end=2.0)}, {"d": tr})
    m = evaluate_diagnoser(rec, "d", [spec("tau3", "joint3", 1.0, 2.0)])
    assert m["detections"] == [{"fault": "tau3", "time": None, "delay": None, "isolated": None}]
    assert m["missed_detections"] == 1 and m["estimate_rmse"] == {"tau3": None}
    assert m["false_alarms"] == 1


def test_alarm_already_on_at_onset_is_not_a_detection():
    tr = trace(alarm_on=[(0, 0.8, DURATION)])  # false alarm that is still on when the fault starts
    rec = record({"tau3": labels(1.0)}, {"d": tr})
    m = evaluate_diagnoser(rec, "d", [spec("tau3", "joint3", 1.0)])
    assert m["false_alarms"] == 1 and m["detections"][0]["time"] is None


def test_second_fault_detected_by_new_rising_edge_on_another_component():
    tr = trace(
        alarm_on=[(0, 1.006, DURATION), (1, 3.004, DURATION)],  # first alarm still on at the second onset
        isolated_from=[("joint3", 1.010), ("joint5", 3.008)],
    )
    rec = record({"tau3": labels(1.0), "tau5": labels(3.0)}, {"d": tr})
    m = evaluate_diagnoser(rec, "d", [spec("tau3", "joint3", 1.0), spec("tau5", "joint5", 3.0)])
    first, second = m["detections"]
    assert first["time"] == pytest.approx(1.006) and first["isolated"] == "joint3"
    assert second["time"] == pytest.approx(3.004) and second["delay"] == pytest.approx(0.004)
    assert second["isolated"] == "joint5"  # "joint3" was already isolated before 3.0
    assert m["false_alarms"] == 0


def test_second_fault_without_new_edge_is_missed():
    tr = trace(alarm_on=[(0, 1.006, DURATION)], isolated_from=[("joint3", 1.010)])
    rec = record({"tau3": labels(1.0), "tau5": labels(3.0)}, {"d": tr})
    m = evaluate_diagnoser(rec, "d", [spec("tau3", "joint3", 1.0), spec("tau5", "joint5", 3.0)])
    assert m["detections"][1]["time"] is None and m["missed_detections"] == 1


def test_alarm_after_fault_end_is_a_false_alarm():
    tr = trace(alarm_on=[(0, 1.006, 1.5), (1, 2.5, 2.6)])
    rec = record({"tau3": labels(1.0, end=2.0)}, {"d": tr})
    m = evaluate_diagnoser(rec, "d", [spec("tau3", "joint3", 1.0, 2.0)])
    assert m["false_alarms"] == 1 and m["first_false_alarm_time"] == pytest.approx(2.5)


def test_bad_inputs_are_named():
    rec, faults = single_fault_record()
    with pytest.raises(RobofdiError, match="nobody"):
        evaluate_diagnoser(rec, "nobody", faults)
    with pytest.raises(RobofdiError, match="tau9"):
        evaluate_diagnoser(rec, "recursive", [spec("tau9", "joint3", 1.0)])
    with pytest.raises(RobofdiError, match="onset"):
        evaluate_diagnoser(rec, "recursive", [{"name": "tau3", "kind": "k", "target": "joint3", "end": None}])


def test_summarize_has_contract_keys_and_writes_json(tmp_path):
    rec, faults = single_fault_record()
    rec.diagnosers["other"] = trace(alarm_on=[])
    s = summarize(rec, "ch3-actuator", faults, reproduction=[{"quantity": "x", "paper": 1.0, "ours": math.nan}])
    assert {"experiment", "system", "seed", "duration", "faults", "diagnosers", "reproduction"} <= set(s)
    assert s["system"] == "arm6" and s["seed"] == 0 and s["duration"] == pytest.approx(DURATION)
    assert s["faults"] == [{"name": "tau3", "kind": "actuator_additive", "target": "joint3", "onset": 1.0, "end": None}]
    assert set(s["diagnosers"]) == {"recursive", "other"}
    for metrics in s["diagnosers"].values():
        assert {"false_alarms", "first_false_alarm_time", "detections", "estimate_rmse"} <= set(metrics)
        assert {"fault", "time", "delay", "isolated"} == set(metrics["detections"][0])
    # the metrics of the hand-made trace (see test_detection_delay_isolation_and_false_alarm_episode) and of an
    # alarm-free one: no false alarm, the fault missed
    assert s["diagnosers"]["recursive"]["false_alarms"] == 1
    assert s["diagnosers"]["recursive"]["detections"][0]["time"] == pytest.approx(1.006)
    assert s["diagnosers"]["other"]["false_alarms"] == 0 and s["diagnosers"]["other"]["missed_detections"] == 1
    # units: times in s, the RMSE in the unit of the fault's ground-truth label
    assert s["units"]["delay"] == "s" and s["units"]["estimate_rmse"] == {"tau3": ""}
    rec.faults["tau3"].unit = "N·m"
    assert summarize(rec, "x", faults)["units"]["estimate_rmse"] == {"tau3": "N·m"}
    assert set(summarize(rec, "x", faults, diagnosers=["other"])["diagnosers"]) == {"other"}

    path = write_summary(s, tmp_path / "out" / "summary.json")
    loaded = json.loads(path.read_text())
    assert loaded["reproduction"][0]["ours"] is None  # NaN -> null
    assert loaded["diagnosers"]["recursive"]["detections"][0]["isolated"] == "joint3"
    assert loaded["diagnosers"]["other"]["detections"][0]["time"] is None


def test_results_table_lists_every_diagnoser_and_fault():
    tr = trace(alarm_on=[(0, 1.006, DURATION), (1, 3.004, DURATION)], isolated_from=[("joint3", 1.010)])
    rec = record({"tau3": labels(1.0), "tau5": labels(3.0)}, {"recursive": tr, "momentum": trace(alarm_on=[])})
    s = summarize(rec, "two-faults", [spec("tau3", "joint3", 1.0), spec("tau5", "joint5", 3.0)])
    table = results_table(s)
    assert "delay [ms]" in table and table.splitlines()[0] == "two-faults  system=arm6  seed=0"
    lines = table.splitlines()
    assert len(lines) == 3 + 4 + 1  # title, header, rule, one row per (diagnoser, fault), the lead
    assert len({len(line) for line in lines[1:3]}) == 1  # header and rule are aligned
    # tau3: alarm rises at 1.006 (6 ms), joint3 isolated at 1.010; the estimate stays 0, so the RMSE over
    # t = 1.010, 1.012, …, 3.998 against the true 2(t − 1) is sqrt(mean(4 s²)), s = 0.010 … 2.998 step 0.002.
    # tau5: component 2 rises at 3.004 (4 ms) but nothing new is isolated. momentum never alarms.
    s_grid = 0.010 + 0.002 * np.arange(1495)
    rmse = f"{np.sqrt(np.mean(4 * s_grid**2)):.4g}"       # 3.468
    assert [line.split() for line in lines[3:-1]] == [
        ["recursive", "*", "tau3", "yes", "6.0", "joint3", "yes", rmse, "0"],
        ["recursive", "*", "tau5", "yes", "4.0", "-", "no", "-", "0"],
        ["momentum", "tau3", "no", "-", "-", "-", "-", "0"],
        ["momentum", "tau5", "no", "-", "-", "-", "-", "0"],
    ]
    assert lines[-1] == "* lead: recursive (best outcome: 1 of 2 faults isolated correctly, 0 false alarms)"


def test_results_table_leads_with_the_named_or_health_source_diagnoser():
    """The lead goes first: the one the summary names, else the accommodation's health source, else the best."""
    tr = trace(alarm_on=[(0, 1.006, DURATION)], isolated_from=[("joint3", 1.010)])
    rec = record({"tau3": labels(1.0)}, {"adaptive": trace(alarm_on=[]), "consistency": tr})
    s = summarize(rec, "lead", [spec("tau3", "joint3", 1.0)])
    assert [line.split()[0] for line in results_table(s).splitlines()[3:5]] == ["consistency", "adaptive"]
    s["accommodation"] = {"health_source": "adaptive"}
    lines = results_table(s).splitlines()
    assert lines[3].split()[:2] == ["adaptive", "*"] and lines[-1] == "* lead: adaptive (its health drives the accommodation)"
    s["lead"] = {"diagnoser": "consistency", "reason": "the recommended scheme"}
    assert results_table(s).splitlines()[-1] == "* lead: consistency (the recommended scheme)"


def test_peak_ratios_are_the_threshold_scale_below_which_the_diagnoser_alarms():
    """peak_ratios: the largest |r_j|/threshold_j at fault-free samples and inside F's window;
    thresholds scaled by s alarm exactly where the ratio passes s."""
    threshold = np.array([2.0, 0.5])
    residual = np.zeros((T_DIAG.size, 2))
    residual[(T_DIAG >= 0.3) & (T_DIAG < 0.31), 1] = -0.4        # 0.8 of the threshold: no alarm
    residual[(T_DIAG >= 0.5) & (T_DIAG < 0.504), 0] = 3.0        # a false-alarm episode at 1.5
    residual[T_DIAG >= 1.0, 1] = np.where(T_DIAG[T_DIAG >= 1.0] < 2.0, 0.6, 1.6)   # the fault: up to 3.2
    tr = DiagnoserTrace(time=T_DIAG, residual=residual, threshold=threshold, alarm=np.abs(residual) > threshold,
                        isolated=np.array([""] * T_DIAG.size, dtype=object), estimate=np.zeros((T_DIAG.size, 0)),
                        components=list(COMPONENTS))
    rec, faults = record({"tau3": labels(1.0)}, {"momentum": tr}), [spec("tau3", "joint3", 1.0)]
    assert peak_ratios(rec, "momentum", faults) == (pytest.approx(1.5), {"tau3": pytest.approx(3.2)})
    m = evaluate_diagnoser(rec, "momentum", faults)
    assert m["false_alarms"] == 1 and m["detections"][0]["delay"] == pytest.approx(0.0)
    # at twice the thresholds: no false alarm (1.5 < 2), the fault detected once it grows past 2 (1.2 → 3.2 at 2 s)
    scaled = DiagnoserTrace(**{**tr.__dict__, "threshold": 2 * threshold, "alarm": np.abs(residual) > 2 * threshold})
    rec2 = record({"tau3": labels(1.0)}, {"momentum": scaled})
    m2 = evaluate_diagnoser(rec2, "momentum", faults)
    assert m2["false_alarms"] == 0 and m2["detections"][0]["delay"] == pytest.approx(1.0)
    assert peak_ratios(rec2, "momentum", faults) == (pytest.approx(0.75), {"tau3": pytest.approx(1.6)})


def test_peak_ratios_are_none_where_the_alarms_are_not_the_threshold_test():
    rec, faults = single_fault_record()
    tr = rec.diagnosers["recursive"]
    tr.alarm[:5] = True          # alarms with no residual above the threshold (e.g. a windowed or sequential test)
    assert peak_ratios(rec, "recursive", faults) == (None, {"tau3": None})
