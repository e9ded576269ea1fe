"""What a run's output leads with: the lead diagnoser, and the recovery (accommodation and task) results.

**The lead diagnoser** is the one the table lists first and the replay lights up. It is, in this order:

1. the one the experiment names (``summary["lead"]["diagnoser"]`` / ``record.meta["lead_diagnoser"]``);
2. the one whose health drives the accommodation (``summary["recovery"]["health_source"]``,
   ``summary["accommodation"]["health_source"]``, ``record.meta["health_source"]``; never the oracle);
3. the one with the best outcome on the run's labels: most faults isolated to the right target, then fewest
   false alarms, most faults detected; among equals the scenario's ``record.meta["primary_diagnoser"]``, else the
   earliest isolation, else the first in order.

:func:`settle_lead` decides once per run folder and writes the answer into both the summary (``"lead"``) and
the record's meta (``"lead_diagnoser"``), so that the printed table and the replay always agree.

**The recovery section** ``summary["recovery"]`` is one shape for every experiment that accommodates a fault or
runs a task::

    {"health_source": "consistency", "method": "...",
     "variants": ["no accommodation", "compensation", "oracle compensation"],
     "quantities": [{"quantity": "tracking RMS after the first actuator fault (t ≥ 1.2 s)", "unit": "rad",
                     "values": {"no accommodation": 0.021, "compensation": 0.004, "oracle compensation": 0.003}}]}

:func:`recovery_table` prints it; :func:`lead_line` and :func:`order_lead_first` serve the results table.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

__all__ = ["lead_diagnoser", "record_lead", "settle_lead", "best_outcome", "recovery_section", "recovery_table",
           "lead_line", "order_lead_first", "run_report"]

ORACLE = "oracle"


def _outcome_key(metrics: Mapping, faults: Sequence[Mapping]):
    """(correct isolations, false alarms, detections), time to isolation: sort keys of one diagnoser's metrics
    (smaller is better)."""
    targets = {f["name"]: f.get("target") for f in faults}
    detections = metrics.get("detections", [])
    correct = metrics.get("isolation_correct")
    if correct is None:
        correct = {d["fault"]: d.get("time") is not None and d.get("isolated") == targets.get(d["fault"])
                   for d in detections}
    n_correct = sum(bool(v) for v in correct.values())
    detected = sum(d.get("time") is not None for d in detections)
    times = metrics.get("time_to_isolation") or {}
    delays = [times.get(f) if times.get(f) is not None else next((d.get("delay") for d in detections
                                                                  if d["fault"] == f), None)
              for f, ok in correct.items() if ok]
    spent = sum(v for v in delays if v is not None and math.isfinite(v))
    return (-n_correct, int(metrics.get("false_alarms") or 0), -detected), spent


def best_outcome(diagnosers: Mapping[str, Mapping], faults: Sequence[Mapping] = (),
                 prefer: str | None = None) -> str | None:
    """The diagnoser with the best outcome (module docstring, rule 3); ``prefer`` wins a tie."""
    if not diagnosers:
        return None
    names = list(diagnosers)
    keys = {n: _outcome_key(diagnosers[n], faults) for n in names}
    ranked = sorted(names, key=lambda n: (keys[n][0], n != prefer, keys[n][1], names.index(n)))
    return ranked[0]


def _health_source(summary: Mapping) -> str | None:
    for key in ("recovery", "accommodation", "allocation"):
        section = summary.get(key)
        if isinstance(section, Mapping) and isinstance(section.get("health_source"), str):
            return section["health_source"]
    return None


def lead_diagnoser(summary: Mapping, prefer: str | None = None) -> tuple[str | None, str]:
    """(the lead diagnoser of a summary, why it leads) — the module docstring's rules; ``prefer``: the
    scenario's primary diagnoser, if known."""
    diagnosers = summary.get("diagnosers") or {}
    lead = summary.get("lead")
    named = lead.get("diagnoser") if isinstance(lead, Mapping) else lead if isinstance(lead, str) else None
    if named in diagnosers:
        reason = lead.get("reason") if isinstance(lead, Mapping) else None
        return named, reason or "named by the experiment"
    source = _health_source(summary)
    if source in diagnosers and source != ORACLE:
        return source, "its health drives the accommodation"
    faults = summary.get("faults", [])
    best = best_outcome(diagnosers, faults, prefer)
    if best is None:
        return None, ""
    key, _ = _outcome_key(diagnosers[best], faults)
    reason = f"best outcome: {-key[0]} of {len(faults)} faults isolated correctly, {key[1]} false alarms"
    if best == prefer and best_outcome(diagnosers, faults) != prefer:
        reason += "; the scenario's primary diagnoser among equals"
    return best, reason


def settle_lead(summary: dict, record) -> str | None:
    """Decide the lead of a run (its summary and its main record) and write it into both:
    ``summary["lead"] = {"diagnoser", "reason"}`` and ``record.meta["lead_diagnoser"]``. Returns the name."""
    meta = record.meta if record.meta is not None else {}
    if meta.get("lead_diagnoser") in (summary.get("diagnosers") or {}) and "lead" not in summary:
        summary["lead"] = {"diagnoser": meta["lead_diagnoser"], "reason": "named by the experiment"}
    if "lead" not in summary and _health_source(summary) is None:
        source = meta.get("health_source")
        if source in (summary.get("diagnosers") or {}) and source != ORACLE:
            summary["lead"] = {"diagnoser": source, "reason": "its health drives the accommodation"}
    lead, reason = lead_diagnoser(summary, meta.get("primary_diagnoser"))
    if lead is None:
        return None
    summary["lead"] = {"diagnoser": lead, "reason": reason}
    meta["lead_diagnoser"] = lead
    record.meta = meta
    return lead


def record_lead(record, diagnosers: Mapping[str, Mapping] | None = None) -> str | None:
    """The lead diagnoser of a record (the same rules on ``record.meta``; rule 3 evaluates the record's labels
    unless ``diagnosers`` gives the metrics)."""
    names = list(record.diagnosers or {})
    meta = record.meta or {}
    for key in ("lead_diagnoser", "health_source"):
        if meta.get(key) in names and meta.get(key) != ORACLE:
            return meta[key]
    if not names:
        return None
    faults = meta.get("faults") or []
    if diagnosers is None:
        from robofdi.evaluate.metrics import evaluate_diagnoser

        try:
            diagnosers = {n: evaluate_diagnoser(record, n, faults) for n in names}
        except Exception:        # a record without labels for its faults: no outcome to rank
            diagnosers = {}
    prefer = meta.get("primary_diagnoser")
    return best_outcome(diagnosers, faults, prefer) or (prefer if prefer in names else names[0])


def order_lead_first(names: Sequence[str], lead: str | None) -> list[str]:
    """``names`` with ``lead`` first (the others in their order)."""
    return ([lead] if lead in names else []) + [n for n in names if n != lead]


def lead_line(summary: Mapping) -> str:
    """``lead: consistency (its health drives the accommodation)`` — empty without diagnosers."""
    lead, why = lead_diagnoser(summary)
    return f"lead: {lead} ({why})" if lead else ""


def recovery_section(variants: Mapping[str, str] | Sequence[str], quantities: Sequence[Mapping],
                     health_source: str | None = None, method: str | None = None, **extra) -> dict:
    """``summary["recovery"]`` (module docstring); ``quantities`` are ``{"quantity", "unit", "values": {variant:
    value}}``, ``variants`` the column order."""
    return {"health_source": health_source, "method": method, "variants": list(variants),
            "quantities": [dict(q) for q in quantities], **extra}


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return "-" if not math.isfinite(value) else f"{value:.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_cell(v) for v in value) + "]"
    return str(value)


def recovery_table(summary: Mapping) -> str:
    """The recovery section as a small fixed-width table (one row per quantity, one column per variant, units);
    empty when the summary has none."""
    section = summary.get("recovery")
    if not isinstance(section, Mapping) or not section.get("quantities"):
        return ""
    variants = list(section.get("variants") or dict.fromkeys(v for q in section["quantities"] for v in q["values"]))
    header = ["quantity", "unit", *variants]
    rows = [[str(q["quantity"]), str(q.get("unit") or "-"), *(_cell(q["values"].get(v)) for v in variants)]
            for q in section["quantities"]]
    widths = [max(len(r[i]) for r in [header] + rows) for i in range(len(header))]

    def line(cells):
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))).rstrip()

    source = section.get("health_source")
    title = "recovery" + (f" (accommodation fed by {source})" if source else "")
    return "\n".join([title, line(header), line(["-" * w for w in widths]), *(line(r) for r in rows)])


def _checks(summary: Mapping) -> list[str]:
    """``[pass] quantity`` per entry of the summary's reproduction (a published result) and acceptance lists."""
    out = []
    for key in ("reproduction", "acceptance"):
        for check in summary.get(key) or []:
            if isinstance(check, Mapping) and "quantity" in check:
                out.append(f"  [{'pass' if check.get('pass') else 'FAIL'}] {check['quantity']}")
    return out


def run_report(summary: Mapping) -> str:
    """What ``robofdi run`` prints: the results table (lead diagnoser first), the recovery table, the checks."""
    from robofdi.evaluate.summary import results_table

    parts = [results_table(summary)]
    recovery = recovery_table(summary)
    if recovery:
        parts.append(recovery)
    checks = _checks(summary)
    if checks:
        parts.append("\n".join(["checks"] + checks))
    return "\n\n".join(parts)
