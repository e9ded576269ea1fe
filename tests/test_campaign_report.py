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
