"""The campaign report says when its numbers are thin: a prefix of the spec, few fault-free runs, few faults."""
from __future__ import annotations

from robofdi.campaign.metrics import clopper_pearson
from robofdi.campaign.results import report_markdown


def _summary(fault_free: int, faulty: int, spec_runs: tuple[int, int], faults_on_target: int) -> dict:
    rate = {"count": 0, "of": fault_free, "rate": 0.0, "ci95": clopper_pearson(0, fault_free)}
    det = {"count": faulty, "of": faulty, "rate": 1.0, "ci95": clopper_pearson(faulty, faulty)}
    block = {"faults": faulty, "detection": det, "isolation_accuracy": det, "correctly_isolated": det,
             "delay_median": 0.01, "delay_p90": 0.02, "runs_with_false_alarm_before_onset": 0}
    diag = {"false_alarm_rate": rate, "faulty": block, "by_kind": {"actuator_additive": block},
            "by_kind_profile": {"actuator_additive~step": block}, "confusion": {},
            "detectability": {"actuator_additive": {"joint2": {
                "faults": faults_on_target, "detected": faults_on_target, "size_range": [0.2, 0.2],
                "min_detectable_size": 0.2, "min_detectable_magnitude": 20.0, "min_detectable_at_most": True,
                "unit": "N·m", "limit": 100.0}}}}
    return {"spec": {"system": "arm", "seed": 0, "system_options": {}, "detection_level": 0.9,
                     "fault_free_runs": spec_runs[0], "faulty_runs": spec_runs[1]},
            "runs": {"finished": fault_free + faulty, "fault_free": fault_free, "faulty": faulty, "errors": 0},
            "diagnosers": {"momentum": diag}, "execution": {}}


def test_a_small_prefix_is_flagged():
    text = report_markdown(_summary(5, 15, (100, 100), 1))
    assert "## Read with care" in text
    assert "20 of the spec's 200 runs (run indices 0–19" in text
    assert "Few fault-free runs:** 5 (even 0 false-alarm runs give a 95 % interval of [0, 52.2] %)" in text
    assert "actuator_additive on joint2 (n=1)" in text and "(n=1) ⚠" in text


def test_a_full_campaign_reads_plainly():
    text = report_markdown(_summary(100, 100, (100, 100), 20))
    assert "Read with care" not in text and "⚠" not in text


def test_the_confusion_counts_are_the_crosstab_cells_in_its_order():
    """campaign.json's confusion per kind: the non-zero cells of pd.crosstab(true target, what was said), true
    targets and columns in crosstab's sorted order (json keeps that order)."""
    import numpy as np
    import pandas as pd

    from robofdi.campaign.metrics import MISSED, UNISOLATED, _confusion

    rng = np.random.default_rng(7)
    targets = ["joint10", "joint2", "joint1_pos", "joint1", "payload"]
    said = [*targets, "joint2+joint3", "", None]
    rows = pd.DataFrame({"target": pd.array(rng.choice(targets, 300), dtype="string"),
                         "detected": pd.array(rng.choice([True, False, None], 300), dtype="boolean"),
                         "isolated": pd.array([said[i] for i in rng.integers(len(said), size=300)], dtype="string")})
    truth = rows["target"].astype(str)
    detected = rows["detected"].fillna(False).astype(bool)
    isolated = rows["isolated"].astype(object).where(rows["isolated"].notna(), UNISOLATED)
    matrix = pd.crosstab(truth, pd.Series(np.where(detected, isolated.astype(str), MISSED), index=rows.index))
    expected = {t: {c: int(v) for c, v in matrix.loc[t].items() if v} for t in matrix.index}
    got = _confusion(rows)
    assert got == expected
    assert list(got) == list(expected) and all(list(got[t]) == list(expected[t]) for t in got)


def test_what_the_calibrations_identified_is_reported_where_it_is_not_zero():
    summary = _summary(100, 100, (100, 100), 20)
    per_key = {"20": {"cached": False, "seconds": 9.0, "identified": {"consistency_payload_kg": 0.912}},
               "21": {"cached": True, "seconds": 0.2, "identified": {"consistency_payload_kg": 0.0}}}
    summary["execution"] = {"calibration": {"keys": ["20", "21"], "wall_time": 9.2, "per_key": per_key}}
    assert "Identified at calibration: 20: consistency_payload_kg 0.912." in report_markdown(summary)
    per_key["20"]["identified"]["consistency_payload_kg"] = 0.0
    assert "Identified at calibration" not in report_markdown(summary)


def _peaks_table(free: dict, faulty: dict):
    """A results table of fault-free and faulty rows per diagnoser with the given peak ratios."""
    import pandas as pd

    rows = []
    for name, peaks in free.items():
        rows += [{"diagnoser": name, "faulty": False, "kind": "none", "profile": None, "peak_ratio_free": p,
                  "peak_ratio_fault": None, "error": None} for p in peaks]
    for name, peaks in faulty.items():
        rows += [{"diagnoser": name, "faulty": True, "kind": "actuator_additive", "profile": profile,
                  "peak_ratio_free": 0.1, "peak_ratio_fault": p, "error": None} for profile, p in peaks]
    return pd.DataFrame(rows)


def test_at_equal_false_alarms_puts_every_diagnoser_at_the_fewest_false_alarm_runs():
    from robofdi.campaign.metrics import at_equal_false_alarms

    faults = [("step", 1.4), ("step", 1.6), ("exponential_rise", 3.0), ("exponential_rise", 0.9)]
    table = _peaks_table({"a": [0.5, 1.5, 0.7, 1.2], "b": [0.3, 0.4, 0.6, 0.9], "c": [2.0, 0.2, 0.3, 0.1]},
                         {"a": faults, "b": faults, "c": faults})
    eq = at_equal_false_alarms(table)
    assert eq["false_alarm_runs"] == 0 and eq["fault_free_runs"] == 4          # b has none at its own thresholds
    a, b, c = (eq["diagnosers"][n] for n in "abc")
    assert a["threshold_scale"] == 1.5 and a["false_alarm_runs"] == 0      # raised to its largest fault-free peak
    assert a["detection"]["count"] == 2                                      # 1.6 and 3.0 pass 1.5; 1.4 does not
    assert a["by_kind_profile"] == {"actuator_additive~exponential_rise": {"detected": 1, "faults": 2},
                                    "actuator_additive~step": {"detected": 1, "faults": 2}}
    assert b["threshold_scale"] == 0.9 and b["false_alarm_runs"] == 0      # lowered to its largest: its spare
    assert b["detection"]["count"] == 3                                      # 0.9 does not pass 0.9
    assert c["threshold_scale"] == 2.0 and c["detection"]["count"] == 1
    # without b: a's two false-alarm runs are the count; a's third largest peak and c's are the scales
    eq2 = at_equal_false_alarms(_peaks_table({"a": [0.5, 1.5, 0.7, 1.2], "c": [2.0, 1.3, 0.3, 1.1]},
                                             {"a": faults, "c": faults}))
    a2, c2 = eq2["diagnosers"]["a"], eq2["diagnosers"]["c"]
    assert eq2["false_alarm_runs"] == 2 and a2["threshold_scale"] == 0.7 and a2["false_alarm_runs"] == 2
    assert c2["threshold_scale"] == 1.1 and c2["false_alarm_runs"] == 2 and c2["detection"]["count"] == 3
    assert a2["detection"]["count"] == 4


def test_at_equal_false_alarms_needs_two_diagnosers_with_peak_ratios():
    import numpy as np

    from robofdi.campaign.metrics import at_equal_false_alarms

    faults = [("step", 1.4)]
    table = _peaks_table({"a": [0.5, 1.5], "b": [np.nan, 0.4]}, {"a": faults, "b": faults})
    assert at_equal_false_alarms(table) is None        # b's alarms are not a threshold test on every run
    assert at_equal_false_alarms(table.drop(columns="peak_ratio_fault")) is None     # a table from before the columns
