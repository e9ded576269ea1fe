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
from typing import NamedTuple

import numpy as np

from robofdi.campaign.spec import CampaignSpec
from robofdi.evaluate.metrics import evaluate_diagnoser, peak_ratios
from robofdi.faults import Fault
from robofdi.faults.profiles import profile_from_dict
from robofdi.seeding import rng, stream

__all__ = ["run_seed", "faulty_indices", "draw_fault", "execute_run", "execute_batch", "COLUMNS", "UNITS"]

#: Columns of the results table (one row per run × diagnoser × fault; fault-free runs: one row per diagnoser).
COLUMNS = ("index", "run_seed", "robot_seed", "faulty", "diagnoser", "fault", "kind", "target", "profile", "magnitude",
           "unit", "limit", "size", "onset", "end", "duration", "detected", "detection_time", "delay", "isolated",
           "correct", "time_to_isolation", "estimate_error", "false_alarms", "first_false_alarm_time", "wall_time",
           "error", "mission", "time_to_correct_isolation", "final_correct", "isolable", "peak_ratio_free",
           "peak_ratio_fault")
#: Unit of each numeric column (``unit`` names the unit of magnitude, limit and estimate_error per row).
UNITS = {"magnitude": "column 'unit'", "limit": "column 'unit'", "size": "fraction of the target's limit (|magnitude|/limit)",
         "onset": "s", "end": "s", "duration": "s", "detection_time": "s", "delay": "s", "time_to_isolation": "s",
         "time_to_correct_isolation": "s (first time the true target is isolated, after detection)",
         "estimate_error": "column 'unit' (RMSE of the estimate after correct isolation)",
         "false_alarms": "alarm episodes starting while no fault is active", "first_false_alarm_time": "s",
         "wall_time": "s (the run's wall-clock time on its worker; in a lockstep batch, its simulation plus its share "
                      "of the batch's diagnosis)",
         "isolable": "whether the diagnoser can name the fault's target at all (one of its residual components or "
                     "identified faults): a mass fault on a link no diagnoser names is not isolable",
         "peak_ratio_free": "1 (the largest max_j |r_j|/threshold_j at the run's fault-free samples: the diagnoser "
                            "alarms there at thresholds scaled by less than it; empty unless its alarms are that test)",
         "peak_ratio_fault": "1 (the same inside the fault's window: detected at thresholds scaled by less than it)"}


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
        free_peak, fault_peak = peak_ratios(record, d, faults)
        row = {**base, "diagnoser": d, "false_alarms": m["false_alarms"], "first_false_alarm_time": m["first_false_alarm_time"],
               "peak_ratio_free": free_peak}
        if fault is not None:
            det = m["detections"][0]
            row.update(detected=det["time"] is not None, detection_time=det["time"], delay=det["delay"],
                       isolated=det["isolated"], correct=bool(m["isolation_correct"][fault.name]),
                       time_to_isolation=m["time_to_isolation"][fault.name], estimate_error=m["estimate_rmse"][fault.name],
                       time_to_correct_isolation=m["time_to_correct_isolation"][fault.name],
                       final_correct=bool(m["final_isolation_correct"][fault.name]),
                       isolable=isolable(record.diagnosers[d], fault.target), peak_ratio_fault=fault_peak[fault.name])
        rows.append(row)
    return rows


def _error(exc: BaseException) -> str:
    """A failed run's ``error``: the exception's type and one-line message, and where it was raised."""
    error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    frame = traceback.extract_tb(exc.__traceback__)[-1]
    return error + f" ({Path(frame.filename).name}:{frame.lineno})"


def _draw(spec: CampaignSpec, index: int) -> tuple:
    """Run ``index``'s calibration key, seed, mission and fault (with its limit info; None, None fault-free) — what
    :func:`execute_run` draws step by step (there, a draw that fails keeps what it drew in the error row)."""
    system = spec.campaign_system
    keys = system.calibration_keys(spec.options)
    key = keys[index % len(keys)]
    seed = run_seed(spec.seed, index)
    mission = system.mission(spec.options, key, rng(seed, "mission"))
    fault, info = draw_fault(spec, seed, mission.duration) if faulty_indices(spec)[index] else (None, None)
    return key, seed, mission, fault, info


def _save(spec: CampaignSpec, index: int, record, out: str | None) -> None:
    if spec.records and out is not None:
        folder = Path(out) / "records"
        folder.mkdir(parents=True, exist_ok=True)
        record.save(folder / f"run-{index:06d}.h5")


def _entry(spec, index, seed, key, fault, info, record, mission, error) -> dict:
    """The run's journal entry (its ``wall_time`` set by :func:`_timed`)."""
    rows = _rows(spec, index, seed, key, fault, info, record, mission)
    for r in rows:
        r["wall_time"], r["error"] = None, error
    return {"index": index, "rows": rows, "wall_time": None}


def execute_run(spec: CampaignSpec, index: int, calibrations: dict, out: str | None = None) -> dict:
    """Run ``index`` of the campaign; never raises: a failure becomes rows with its ``error`` message.
    Returns {"index", "rows", "wall_time"}. ``out``: the campaign folder, where ``records/`` goes if asked."""
    start = time.perf_counter()
    system = spec.campaign_system
    keys = system.calibration_keys(spec.options)
    key = keys[index % len(keys)]
    seed = run_seed(spec.seed, index)
    fault = info = mission = record = None
    error = None
    try:
        mission = system.mission(spec.options, key, rng(seed, "mission"))
        if faulty_indices(spec)[index]:
            fault, info = draw_fault(spec, seed, mission.duration)
        record = system.run(spec.options, calibrations[key], key, mission, [] if fault is None else [fault], seed,
                            spec.diagnosers)
        _save(spec, index, record, out)
    except Exception as exc:          # a failing run is an error row; the campaign goes on
        error, record = _error(exc), None
    if mission is None:
        from robofdi.protocols import Mission

        mission = Mission(float("nan"), None)
    entry = _entry(spec, index, seed, key, fault, info, record, mission, error)
    return _timed(entry, time.perf_counter() - start)


def _timed(entry: dict, wall: float) -> dict:
    """``entry`` with its run's wall-clock time [s] (in every row too)."""
    entry["wall_time"] = wall
    for r in entry["rows"]:
        r["wall_time"] = wall
    return entry


class _Simulated(NamedTuple):
    """A run of a batch, simulated and waiting for its lockstep diagnosis."""

    index: int
    key: object
    seed: int
    mission: object
    fault: Fault | None
    info: dict | None
    diagnoses: dict
    record: object
    seconds: float          # wall-clock time of its draw, build and simulation [s]


#: Most bytes of simulated records a worker holds before it diagnoses them (:func:`execute_batch`): a batch of long
#: runs is diagnosed in parts, so memory stays bounded whatever the runs' duration (a 2.7 s arm run: 1.7 MB).
BATCH_MEMORY = 256 * 2**20


def _nbytes(record) -> int:
    """Bytes of a record's series."""
    arrays = [record.time, record.truth_state, record.u_applied, *record.signals.values()]
    arrays += [a for labels in record.faults.values() for a in (labels.active, labels.value)]
    return sum(a.nbytes for a in arrays if a is not None)


def execute_batch(spec: CampaignSpec, indices, calibrations: dict, out: str | None = None) -> list[dict]:
    """Runs ``indices`` of the campaign in this worker, each entry the one :func:`execute_run` gives (its
    ``wall_time`` aside): every run is simulated without stepping its diagnoses, then all are diagnosed in lockstep
    (:func:`robofdi.lockstep.diagnose_lockstep`: each diagnoser once per sample for the whole batch; in parts when
    the records would hold more than :data:`BATCH_MEMORY`). A run's ``wall_time`` is then its simulation plus its
    share of the diagnosis and rows. A run that cannot be (its loop's accommodation follows a diagnosis, its
    diagnosis rates differ from the batch's) or whose simulation fails is run alone (:func:`execute_run`), and so is
    every run of a lockstep diagnosis that fails: the same rows, errors included. A system whose ``run`` is its own
    (not ``build(...).run()``, as :class:`robofdi.systems.RobotInstances` runs) runs every run alone."""
    from robofdi.loop import ORACLE, ClosedLoop
    from robofdi.systems import RobotInstances

    indices = list(indices)
    system = spec.campaign_system
    if len(indices) < 2 or getattr(type(system), "run", None) is not RobotInstances.run:
        return [execute_run(spec, i, calibrations, out) for i in indices]
    entries, simulated, rates, held = {}, [], None, 0
    for index in indices:
        start = time.perf_counter()
        try:
            key, seed, mission, fault, info = _draw(spec, index)
            parts = system.build(spec.options, calibrations[key], key, mission, [] if fault is None else [fault], seed,
                                 spec.diagnosers)
            loop = parts.loop
            if (isinstance(loop, ClosedLoop) and loop.diagnoses and (rates is None or loop.rates == rates)
                    and (loop.accommodation is None or loop.health_source in (None, ORACLE))):
                rates = loop.rates
                record = parts.run(diagnose=False)
                simulated.append(_Simulated(index, key, seed, mission, fault, info, parts.diagnoses, record,
                                            time.perf_counter() - start))
                held += _nbytes(record)
                if held >= BATCH_MEMORY:
                    _diagnose(spec, simulated, rates, calibrations, out, entries)
                    simulated, held = [], 0
                continue
        except Exception:              # alone, where its error row is made
            pass
        entries[index] = execute_run(spec, index, calibrations, out)
    _diagnose(spec, simulated, rates, calibrations, out, entries)
    return [entries[i] for i in indices]


def _diagnose(spec, simulated: list[_Simulated], rates, calibrations: dict, out, entries: dict) -> None:
    """Diagnose the ``simulated`` runs in lockstep and put their entries into ``entries`` (by index); if that
    fails, every one of them is run alone."""
    from robofdi.lockstep import diagnose_lockstep

    if not simulated:
        return
    start = time.perf_counter()
    try:
        traces = diagnose_lockstep([s.record for s in simulated], [s.diagnoses for s in simulated], rates)
    except Exception:                  # e.g. a non-finite measurement: every run alone, each with its own outcome
        for s in simulated:
            entries[s.index] = execute_run(spec, s.index, calibrations, out)
        return
    for s, trace in zip(simulated, traces):
        s.record.diagnosers = trace
        try:
            _save(spec, s.index, s.record, out)
        except Exception as exc:       # as execute_run: an error row
            entries[s.index] = _entry(spec, s.index, s.seed, s.key, s.fault, s.info, None, s.mission, _error(exc))
            continue
        entries[s.index] = _entry(spec, s.index, s.seed, s.key, s.fault, s.info, s.record, s.mission, None)
    share = (time.perf_counter() - start) / len(simulated)
    for s in simulated:
        _timed(entries[s.index], s.seconds + share)
