"""The run's summary.json (a contract read by scripts and tools) and a terminal table of it."""
from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from robofdi import RobofdiError
from robofdi.evaluate.metrics import evaluate_diagnoser, fault_windows
from robofdi.record import Record

__all__ = ["summarize", "write_summary", "results_table"]


def _duration(record: Record) -> float:
    if "duration" in record.meta:
        return float(record.meta["duration"])
    time = np.asarray(record.time, dtype=float)
    if time.size == 0:
        return 0.0
    dt = float(np.median(np.diff(time))) if time.size > 1 else 0.0
    return float(time[-1] - time[0] + dt)


def summarize(
    record: Record,
    experiment: str,
    faults: Sequence[Mapping] | None = None,
    diagnosers: Sequence[str] | None = None,
    **extra,
) -> dict:
    """The summary.json contract: experiment, system, seed, duration, faults and metrics per diagnoser.

    ``faults`` defaults to the faults the record's run injected (``record.meta["faults"]``); ``diagnosers`` to
    every diagnoser in the record; ``extra`` (e.g. ``reproduction=[...]``) is merged at the top level.
    """
    if faults is None:
        faults = record.meta.get("faults", [])
    if not isinstance(experiment, str) or not experiment:
        raise RobofdiError(f"experiment: expected a non-empty name such as 'ch3-actuator', got {experiment!r}")
    windows = fault_windows(faults)
    names = list(record.diagnosers) if diagnosers is None else list(diagnosers)
    clash = sorted(set(extra) & {"experiment", "system", "seed", "duration", "faults", "diagnosers", "units"})
    if clash:
        raise RobofdiError(f"extra: {clash[0]!r} is a contract key of summary.json and cannot be overridden")
    summary = {
        "experiment": experiment,
        "system": record.system,
        "seed": None if record.seed is None else int(record.seed),
        "duration": _duration(record),
        "faults": [w.as_dict() for w in windows],
        "diagnosers": {n: evaluate_diagnoser(record, n, faults) for n in names},
        "units": {
            "duration": "s", "onset": "s", "end": "s", "time": "s", "delay": "s", "time_to_isolation": "s",
            "first_false_alarm_time": "s", "false_alarms": "alarm episodes",
            "estimate_rmse": {w.name: record.faults[w.name].unit if w.name in record.faults else "" for w in windows},
        },
    }
    summary.update(extra)
    return summary


def _jsonable(obj):
    """Plain JSON types; NaN/inf become None (null)."""
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    raise RobofdiError(f"summary: value {obj!r} of type {type(obj).__name__} cannot be written as JSON")


def write_summary(summary: Mapping, path: str | Path) -> Path:
    """Write the summary as indented JSON (NaN -> null; parents created; atomically: a temporary file renamed);
    returns the path."""
    from robofdi.interrupts import atomic_path

    path = Path(path)
    text = json.dumps(_jsonable(summary), indent=2, allow_nan=False) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def _fmt(value, spec: str = "", none: str = "-") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return none
    return format(value, spec)


def results_table(summary: Mapping) -> str:
    """Plain-text table, one row per (diagnoser, fault), fixed-width columns; the lead diagnoser
    (:func:`robofdi.evaluate.headline.lead_diagnoser`) first, marked ``*`` and named under the table."""
    from robofdi.evaluate.headline import lead_diagnoser, lead_line, order_lead_first

    targets = {f["name"]: str(f["target"]) for f in summary.get("faults", [])}
    header = ["diagnoser", "fault", "detected", "delay [ms]", "isolated", "correct", "estimate RMSE", "false alarms"]
    rows = []
    diagnosers = summary.get("diagnosers", {})
    lead, _ = lead_diagnoser(summary)
    for dname in order_lead_first(list(diagnosers), lead):
        metrics = diagnosers[dname]
        shown = f"{dname} *" if dname == lead and len(diagnosers) > 1 else dname
        detections = metrics.get("detections", [])
        false_alarms = str(metrics.get("false_alarms", "-"))
        if not detections:
            rows.append([shown, "-", "-", "-", "-", "-", "-", false_alarms])
        for d in detections:
            fault = d["fault"]
            detected = d.get("time") is not None
            correct = metrics.get("isolation_correct", {}).get(fault)
            if correct is None:
                correct = d.get("isolated") is not None and d.get("isolated") == targets.get(fault)
            delay = d.get("delay")
            rows.append([
                shown,
                fault,
                "yes" if detected else "no",
                _fmt(None if delay is None else 1e3 * delay, ".1f"),
                _fmt(d.get("isolated")),
                ("yes" if correct else "no") if detected else "-",
                _fmt(metrics.get("estimate_rmse", {}).get(fault), ".4g"),
                false_alarms,
            ])
    widths = [max(len(r[i]) for r in [header] + rows) for i in range(len(header))]
    numeric = {3, 6, 7}

    def line(cells):
        return "  ".join(c.rjust(w) if i in numeric else c.ljust(w) for i, (c, w) in enumerate(zip(cells, widths))).rstrip()

    title = f"{summary.get('experiment', '')}  system={summary.get('system', '')}  seed={summary.get('seed')}"
    out = [title, line(header), line(["-" * w for w in widths])] + [line(r) for r in rows]
    if len(diagnosers) > 1 and lead:
        out.append(f"* {lead_line(summary)}")
    return "\n".join(out)
