"""What the output leads with (robofdi.evaluate.headline): the lead diagnoser in the table and the replay, and
the recovery table ``robofdi run`` prints."""
from __future__ import annotations

import numpy as np

from robofdi.evaluate import summarize
from robofdi.evaluate.headline import (best_outcome, lead_diagnoser, record_lead, recovery_section, recovery_table,
                                       run_report, settle_lead)
from robofdi.record import DiagnoserTrace, FaultLabels, Record

T = np.round(np.arange(2000) * 0.001, 9)          # 2 s at 1 kHz; diagnosers at 500 Hz
TD = T[::2]
FAULT = {"name": "tau2", "kind": "actuator_additive", "target": "joint2", "onset": 1.0, "end": None,
         "magnitude": 20.0}


def _trace(isolated_at: float | None, alarm_at: float | None = None, false_alarm: bool = False) -> DiagnoserTrace:
    alarm = np.zeros((TD.size, 2), dtype=bool)
    if alarm_at is not None:
        alarm[TD >= alarm_at - 1e-9, 1] = True
    if false_alarm:
        alarm[(TD >= 0.2) & (TD < 0.21), 0] = True
    iso = np.array(["joint2" if isolated_at is not None and t >= isolated_at - 1e-9 else "" for t in TD], dtype=object)
    return DiagnoserTrace(time=TD, residual=alarm * 2.0, threshold=np.ones(2), alarm=alarm, isolated=iso,
                          estimate=np.zeros((TD.size, 1)), components=["joint1", "joint2"],
                          estimate_components=["joint2"])


def _record(meta=None) -> Record:
    """The arm's situation: ``adaptive`` (the scenario's primary) misses the fault, ``consistency`` isolates it,
    ``momentum`` isolates it earlier but with a false alarm."""
    active = T >= 1.0
    return Record(system="arm6", scenario="test", seed=0, rates={"control_hz": 1000.0}, time=T,
                  truth_state=np.zeros((T.size, 4)),
                  faults={"tau2": FaultLabels(active, np.where(active, 20.0, 0.0), "N·m")},
                  diagnosers={"adaptive": _trace(None), "consistency": _trace(1.030, 1.020),
                              "momentum": _trace(1.004, 1.002, false_alarm=True)},
                  meta={"faults": [FAULT], "primary_diagnoser": "adaptive", **(meta or {})})


def test_best_outcome_isolated_correctly_then_fewest_false_alarms():
    rec = _record()
    s = summarize(rec, "arm", [FAULT])
    assert best_outcome(s["diagnosers"], s["faults"]) == "consistency"
    assert lead_diagnoser(s)[0] == "consistency"
    assert record_lead(rec) == "consistency"        # the primary (adaptive) missed: not shown first
    # among equally good ones the scenario's primary wins, else the earliest isolation
    good = {"a": s["diagnosers"]["consistency"], "b": s["diagnosers"]["consistency"]}
    assert best_outcome(good, s["faults"]) == "a" and best_outcome(good, s["faults"], prefer="b") == "b"


def test_health_source_leads_and_settle_lead_writes_summary_and_record():
    rec = _record()
    s = summarize(rec, "arm", [FAULT])
    s["accommodation"] = {"health_source": "momentum"}
    assert lead_diagnoser(s) == ("momentum", "its health drives the accommodation")
    assert settle_lead(s, rec) == "momentum"
    assert s["lead"] == {"diagnoser": "momentum", "reason": "its health drives the accommodation"}
    assert rec.meta["lead_diagnoser"] == "momentum" and record_lead(rec) == "momentum"
    # a record whose own run was accommodated names its health source; the oracle never leads
    assert record_lead(_record({"health_source": "momentum"})) == "momentum"
    assert record_lead(_record({"health_source": "oracle"})) == "consistency"
    # the experiment may name its lead
    s = summarize(rec, "arm", [FAULT])
    s["lead"] = {"diagnoser": "adaptive", "reason": "the book's scheme"}
    assert lead_diagnoser(s) == ("adaptive", "the book's scheme")


def test_replay_draws_the_lead():
    from robofdi.viz.replay import _choose_diagnoser

    rec = _record()
    assert _choose_diagnoser(rec, None) == "consistency"
    assert _choose_diagnoser(rec, "adaptive") == "adaptive"
    rec.meta["lead_diagnoser"] = "momentum"
    assert _choose_diagnoser(rec, None) == "momentum"


def test_replay_of_other_systems_by_record_system_not_columns():
    from robofdi.viz.auv_replay import build_auv_replay
    from robofdi.viz.replay import _system_replay

    rec = _record()
    assert _system_replay(rec) is None                # an arm: drawn from its model file
    rec.columns["truth/state"] = ["x", "y", "z", "qw", "qx", "qy", "qz"]
    assert _system_replay(rec) is None                # column names decide nothing
    rec.system = "auv"
    assert _system_replay(rec) is build_auv_replay
    rec.system, rec.meta["replay"] = "my_auv", "auv"
    assert _system_replay(rec) is build_auv_replay


def test_recovery_table_and_run_report():
    s = summarize(_record(), "arm", [FAULT])
    s["accommodation"] = {"health_source": "consistency"}
    s["recovery"] = recovery_section(
        ("no accommodation", "compensation", "oracle compensation"),
        [{"quantity": "joint tracking RMS for t >= 1 s", "unit": "rad",
          "values": {"no accommodation": 0.0213, "compensation": 0.00412, "oracle compensation": 0.00398}},
         {"quantity": "task success", "unit": None,
          "values": {"no accommodation": False, "compensation": True, "oracle compensation": None}}],
        health_source="consistency")
    table = recovery_table(s).splitlines()
    assert table[0] == "recovery (accommodation fed by consistency)"
    assert table[1].split() == ["quantity", "unit", "no", "accommodation", "compensation", "oracle", "compensation"]
    assert table[3].split()[-4:] == ["rad", "0.0213", "0.00412", "0.00398"]
    assert table[4].split()[-4:] == ["-", "no", "yes", "-"]
    assert len({len(line) for line in table[1:3]}) == 1
    s["reproduction"] = [{"quantity": "a published number", "pass": True}]
    report = run_report(s)
    lines = report.splitlines()
    assert lines[3].split()[:2] == ["consistency", "*"]            # the lead first
    assert "* lead: consistency (its health drives the accommodation)" in lines
    assert report.index("recovery (") < report.index("checks") and "  [pass] a published number" in lines
    assert recovery_table({"diagnosers": {}}) == ""
