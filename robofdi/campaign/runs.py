"""One campaign run: its seed, its draw (mission, fault), its simulation and its rows of the results table.

Everything a run does depends only on (spec, calibration, index): the run's seed is
``stream(campaign seed, "campaign", "run", index)``, its mission and fault come from named streams of that seed,
so a run gives the same rows on any worker, in any order.
"""
from __future__ import annotations

import json
import time
import traceback
from pathlib import Path

import numpy as np

from robofdi.campaign.spec import CampaignSpec
from robofdi.evaluate.metrics import evaluate_diagnoser
from robofdi.faults import Fault
from robofdi.faults.profiles import profile_from_dict
from robofdi.seeding import rng, stream

__all__ = ["run_seed", "faulty_indices", "draw_fault", "execute_run", "COLUMNS", "UNITS"]

#: Columns of the results table (one row per run × diagnoser × fault; fault-free runs: one row per diagnoser).
COLUMNS = ("index", "run_seed", "robot_seed", "faulty", "diagnoser", "fault", "kind", "target", "profile", "magnitude",
           "unit", "limit", "size", "onset", "end", "duration", "detected", "detection_time", "delay", "isolated",
           "correct", "time_to_isolation", "estimate_error", "false_alarms", "first_false_alarm_time", "wall_time",
           "error", "mission", "time_to_correct_isolation", "final_correct", "isolable")
#: Unit of each numeric column (``unit`` names the unit of magnitude, limit and estimate_error per row).
UNITS = {"magnitude": "column 'unit'", "limit": "column 'unit'", "size": "fraction of the target's limit (|magnitude|/limit)",
         "onset": "s", "end": "s", "duration": "s", "detection_time": "s", "delay": "s", "time_to_isolation": "s",
         "time_to_correct_isolation": "s (first time the true target is isolated, after detection)",
         "estimate_error": "column 'unit' (RMSE of the estimate after correct isolation)",
         "false_alarms": "alarm episodes starting while no fault is active", "first_false_alarm_time": "s",
         "wall_time": "s (the run's wall-clock time on its worker)",
         "isolable": "whether the diagnoser can name the fault's target at all (one of its residual components or "
                     "identified faults): a mass fault on a link no diagnoser names is not isolable"}


def run_seed(campaign_seed: int, index: int) -> int:
    """Run ``index``'s seed: the first word of ``stream(campaign_seed, "campaign", "run", str(index))``."""
    return int(stream(campaign_seed, "campaign", "run", str(index)).generate_state(1)[0])


def faulty_indices(spec: CampaignSpec) -> np.ndarray:
    """Boolean per run index: faulty or fault-free, in a seeded order, so any prefix mixes both."""
    order = np.zeros(spec.runs, dtype=bool)
    order[:spec.faulty_runs] = True
    return rng(spec.seed, "campaign", "order").permutation(order)


def draw_fault(spec: CampaignSpec, seed: int, duration: float) -> tuple[Fault, dict]:
    """The run's fault from ``rng(seed, "fault")``: an entry by weight, then target, size, sign, profile, onset,
    end, and last (only for a hard-over drawn from the target's limit) the limit: ± limit_fraction × the target's
    limit, with the drawn sign."""
    g = rng(seed, "fault")
    weights = np.array([d.weight for d in spec.faults])
    dist = spec.faults[int(g.choice(len(weights), p=weights / weights.sum()))]
    target = dist.targets[int(g.integers(len(dist.targets)))]
    limit, unit = dist.limits[target]
    low, high = dist.magnitude_fraction if dist.magnitude_fraction is not None else dist.magnitude
    if dist.magnitude_draw == "log_uniform":
        magnitude = float(np.exp(g.uniform(np.log(low), np.log(high))))
    else:
        magnitude = float(g.uniform(low, high))
    if dist.magnitude_fraction is not None:
        magnitude *= limit
    negative = bool(dist.random_sign and g.random() < 0.5)
    if negative:
        magnitude = -magnitude
    profile = profile_from_dict(dist.profiles[int(g.integers(len(dist.profiles)))])
    onset = round(float(g.uniform(*dist.onset_fraction)) * duration, 3)
    end = None if dist.duration is None else round(onset + float(g.uniform(*dist.duration)), 3)
    params = dist.params
    if dist.limit_fraction is not None:               # hard-over to ± a fraction of this target's own limit
        drawn = float(g.uniform(*dist.limit_fraction)) * limit
        params, magnitude = {**params, "limit": -drawn if negative else drawn}, 0.0
    fault = Fault(f"{dist.kind}:{target}", dist.kind, target, onset=onset, end=end, magnitude=magnitude,
                  profile=profile, params=params)
    return fault, {"unit": unit, "limit": limit}


def isolable(trace, target: str) -> bool:
    """Whether a diagnoser's trace can name ``target``: one of its residual components, identified faults or
    isolated names (its hypotheses)."""
    names = set(trace.components) | set(trace.estimate_components)
    names |= {n for s in set(map(str, trace.isolated)) for n in s.split("+") if n}
    return target in names


def _rows(spec, index, seed, key, fault, info, record, mission) -> list[dict]:
    base = {"index": index, "run_seed": seed, "robot_seed": int(key), "faulty": fault is not None,
            "duration": float(mission.duration), "mission": json.dumps(mission.description, sort_keys=True)}
    if fault is not None:
        base.update(fault=fault.name, kind=fault.kind, target=fault.target, profile=fault.profile.type_name,
                    magnitude=fault.magnitude, unit=info["unit"], limit=info["limit"],
                    size=abs(fault.magnitude) / info["limit"], onset=fault.onset, end=fault.end)
    else:
        base.update(kind="none")
    if record is None:
        return [{**base, "diagnoser": d} for d in spec.diagnosers]
    faults = [] if fault is None else [fault.to_dict()]
    rows = []
    for d in spec.diagnosers:
        m = evaluate_diagnoser(record, d, faults)
        row = {**base, "diagnoser": d, "false_alarms": m["false_alarms"], "first_false_alarm_time": m["first_false_alarm_time"]}
        if fault is not None:
            det = m["detections"][0]
            row.update(detected=det["time"] is not None, detection_time=det["time"], delay=det["delay"],
                       isolated=det["isolated"], correct=bool(m["isolation_correct"][fault.name]),
                       time_to_isolation=m["time_to_isolation"][fault.name], estimate_error=m["estimate_rmse"][fault.name],
                       time_to_correct_isolation=m["time_to_correct_isolation"][fault.name],
                       final_correct=bool(m["final_isolation_correct"][fault.name]),
                       isolable=isolable(record.diagnosers[d], fault.target))
        rows.append(row)
    return rows


def execute_run(spec: CampaignSpec, index: int, calibrations: dict, out: str | None = None) -> dict:
    """Run ``index`` of the campaign; never raises: a failure becomes rows with its ``error`` message.
    Returns {"index", "rows", "wall_time"}. ``out``: the campaign folder, where ``records/`` goes if asked."""
    start = time.perf_counter()
    system = spec.campaign_system
    keys = system.calibration_keys(spec.options)
    key = keys[index % len(keys)]
    seed = run_seed(spec.seed, index)
    faulty = bool(faulty_indices(spec)[index])
    fault = info = mission = record = None
    error = None
    try:
        mission = system.mission(spec.options, key, rng(seed, "mission"))
        if faulty:
            fault, info = draw_fault(spec, seed, mission.duration)
        record = system.run(spec.options, calibrations[key], key, mission, [] if fault is None else [fault], seed,
                            spec.diagnosers)
        if spec.records and out is not None:
            folder = Path(out) / "records"
            folder.mkdir(parents=True, exist_ok=True)
            record.save(folder / f"run-{index:06d}.h5")
    except Exception as exc:          # a failing run is an error row; the campaign goes on
        error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        error += f" ({Path(frame.filename).name}:{frame.lineno})"
        record = None
    if mission is None:
        from robofdi.protocols import Mission

        mission = Mission(float("nan"), None)
    rows = _rows(spec, index, seed, key, fault, info, record, mission)
    wall = time.perf_counter() - start
    for r in rows:
        r["wall_time"] = wall
        r["error"] = error
    return {"index": index, "rows": rows, "wall_time": wall}
