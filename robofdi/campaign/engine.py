"""Running a campaign: calibrate (cached, in parallel), run what is not done yet, journal every finished run,
then the results table, campaign.json, figures and report.md.

The journal ``runs.jsonl`` gets one line per finished run, flushed and synced as it arrives, so a killed campaign
loses at most the runs in flight and ``resume=True`` skips the rest. The final table is sorted by run index, so it
does not depend on the order runs finished in, nor on the backend.
"""
from __future__ import annotations

import json
import os
import signal
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from robofdi.campaign.backends import backend
from robofdi.campaign.runs import COLUMNS, execute_batch
from robofdi.campaign.spec import CampaignSpec, load_spec
from robofdi.errors import RobofdiError
from robofdi.interrupts import signal_of, stop_on_signals

__all__ = ["run_campaign", "CampaignInterrupted", "read_journal", "results_table", "JOURNAL", "TABLE"]

JOURNAL = "runs.jsonl"
TABLE = "results.parquet"
STATE = "spec.json"


class CampaignInterrupted(RuntimeError):
    """SIGTERM or Ctrl-C: the finished runs are journaled (the runs in flight are not: they are not failures);
    ``resume=True`` continues. ``signum``: the signal."""

    def __init__(self, done: int, total: int, out: Path, signum: int = signal.SIGTERM):
        super().__init__(f"campaign interrupted by {signal.Signals(signum).name} after {done} of {total} runs; what "
                         f"finished is kept in {out / JOURNAL} (run again with --resume to complete it)")
        self.done, self.total, self.out, self.signum = done, total, out, int(signum)


def _calibrate(spec: CampaignSpec, key) -> tuple:
    start = time.perf_counter()
    cal, cached = spec.campaign_system.calibrate(spec.options, key, spec.diagnosers)
    return key, cal, cached, time.perf_counter() - start


def read_journal(out: str | Path, repair: bool = False) -> dict[int, dict]:
    """Finished runs by index from ``out/runs.jsonl``. A torn last line (killed while writing) is dropped — and cut
    from the file when ``repair``."""
    path = Path(out) / JOURNAL
    done: dict[int, dict] = {}
    if not path.is_file():
        return done
    good = 0
    with path.open("rb") as fh:
        for line in fh:
            try:
                entry = json.loads(line)
            except json.JSONDecodeError:
                break
            if not line.endswith(b"\n"):
                break
            done[int(entry["index"])] = entry
            good += len(line)
    if repair and good != path.stat().st_size:
        with path.open("r+b") as fh:
            fh.truncate(good)
    return done


def results_table(entries, diagnosers=None) -> pd.DataFrame:
    """The results table from journal entries: COLUMNS, sorted by run index then diagnoser (spec order)."""
    rows = [r for e in entries for r in e["rows"]]
    table = pd.DataFrame(rows, columns=list(COLUMNS))
    for col in ("index", "run_seed", "robot_seed"):
        table[col] = table[col].astype("int64")
    for col in ("faulty",):
        table[col] = table[col].astype(bool)
    for col in ("detected", "correct", "final_correct", "isolable"):
        table[col] = table[col].astype("boolean")
    table["false_alarms"] = table["false_alarms"].astype("Int64")
    for col in ("magnitude", "limit", "size", "onset", "end", "duration", "detection_time", "delay", "time_to_isolation",
                "time_to_correct_isolation", "estimate_error", "first_false_alarm_time", "wall_time", "peak_ratio_free",
                "peak_ratio_fault"):
        table[col] = table[col].astype("float64")
    for col in ("diagnoser", "fault", "kind", "target", "profile", "unit", "isolated", "error", "mission"):
        table[col] = table[col].astype("string")
    order = {d: i for i, d in enumerate(diagnosers or sorted(set(table["diagnoser"])))}
    table = table.assign(_d=table["diagnoser"].map(order)).sort_values(["index", "_d"], kind="stable").drop(columns="_d")
    return table.reset_index(drop=True)


def _prepare(out: Path, spec: CampaignSpec, resume: bool) -> dict[int, dict]:
    out.mkdir(parents=True, exist_ok=True)
    state = out / STATE
    journal = read_journal(out, repair=resume)
    if state.is_file():
        previous = json.loads(state.read_text())
        if resume and previous.get("fingerprint") != spec.fingerprint():
            raise RobofdiError(f"--resume: {out} holds a campaign of another spec (fingerprint {previous.get('fingerprint')}, "
                               f"this spec {spec.fingerprint()}); use another --out")
        if not resume and journal:
            raise RobofdiError(f"--out: {out} already holds {len(journal)} runs of a campaign; pass --resume to "
                               "continue it, or choose another folder")
    elif journal:
        raise RobofdiError(f"--out: {out} holds {JOURNAL} but no {STATE}; choose another folder")
    if not resume:
        (out / JOURNAL).unlink(missing_ok=True)
        journal = {}
    state.write_text(json.dumps({"fingerprint": spec.fingerprint(), "spec": spec.to_dict()}, indent=2, default=str) + "\n")
    return journal


@dataclass
class _Session:
    """What this invocation did (campaign.json "execution")."""

    backend: str = ""
    workers: int = 0
    runs: int = 0
    seconds: float = 0.0
    calibration: dict | None = None

    def as_dict(self) -> dict:
        rate = 60.0 * self.runs / self.seconds if self.seconds > 0 and self.runs else None
        return {"backend": self.backend, "workers": self.workers, "runs_this_session": self.runs,
                "run_phase_wall_time": self.seconds, "runs_per_minute": rate, "calibration": self.calibration,
                "units": {"run_phase_wall_time": "s", "runs_per_minute": "runs/min", "seconds": "s"}}


#: Most runs a worker diagnoses in lockstep (:func:`batches`): beyond it the gain levels off and more is lost
#: when a worker stops mid-batch.
MAX_BATCH = 32


def batches(todo: list[int], workers: int, batch: int | None = None) -> list[list[int]]:
    """``todo`` cut into consecutive batches, each run by one worker in lockstep
    (:func:`robofdi.campaign.runs.execute_batch`). ``batch``: runs per batch (1: every run alone). None: even
    batches (their sizes differ by one at most) of at most :data:`MAX_BATCH` runs, as many as a multiple of
    ``workers``, so that every worker gets as many."""
    if batch is not None:
        if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
            raise RobofdiError(f"--batch: expected an integer >= 1 (runs diagnosed in lockstep), got {batch!r}")
        return [todo[i:i + batch] for i in range(0, len(todo), batch)]
    if not todo:
        return []
    count = min(len(todo), -(-len(todo) // (MAX_BATCH * workers)) * workers)
    return [part.tolist() for part in np.array_split(np.asarray(todo, dtype=int), count)]


def run_campaign(spec, out: str | Path, *, workers: int | None = None, scheduler: str | None = None,
                 resume: bool = False, runs: int | None = None, progress: bool = True, report: bool = True,
                 batch: int | None = None):
    """Run (or resume) a campaign into folder ``out`` and analyse it; returns a
    :class:`robofdi.campaign.CampaignResult`.

    spec: a path, a shipped spec name, TOML text, a dict or a CampaignSpec. workers: local processes (default: the
    cores available; 1 = this process); scheduler: a Dask scheduler address instead. runs: only the first ``runs``
    run indices (a prefix of the full campaign). batch: runs a worker diagnoses in lockstep (:func:`batches`; the
    results are the same whatever it is; a run is journaled when its batch ends). Everything is checked (spec,
    scheduler, folder, batch) before any run.
    """
    from robofdi.campaign.results import CampaignResult, write_outputs
    from robofdi.progress import Progress

    spec = load_spec(spec)
    total = spec.runs
    if runs is not None:
        if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
            raise RobofdiError(f"--runs: expected an integer >= 1, got {runs!r}")
        total = min(total, runs)
    out = Path(out)
    pool = backend(workers, scheduler)
    try:
        journal = _prepare(out, spec, resume)
    except BaseException:
        if hasattr(pool, "client"):
            pool.client.close()
        raise
    todo = [i for i in range(total) if i not in journal]
    try:
        tasks = batches(todo, pool.workers, batch)
    except BaseException:
        if hasattr(pool, "client"):
            pool.client.close()
        raise
    session = _Session(pool.description, pool.workers)
    try:
        with stop_on_signals(), pool:
            keys = spec.campaign_system.calibration_keys(spec.options)
            start = time.perf_counter()
            calibrations, cal_info = {}, {}
            bars = Progress.of(progress, f"campaign {spec.system}")
            if todo:
                with bars.stage("calibration", len(keys), unit="calibration") as tick:
                    notes = getattr(spec.campaign_system, "calibration_notes", None)
                    for key, cal, cached, seconds in pool.map_unordered(_calibrate, [(spec, k) for k in keys]):
                        calibrations[key] = cal
                        cal_info[str(key)] = {"cached": bool(cached), "seconds": seconds} \
                            | ({"identified": notes(cal)} if notes else {})
                        tick(1)
            session.calibration = {"keys": [str(k) for k in keys], "wall_time": time.perf_counter() - start,
                                   "per_key": cal_info}
            start = time.perf_counter()
            errors = 0
            with (out / JOURNAL).open("a") as fh, bars.stage("runs", total, unit="run",
                                                             initial=total - len(todo)) as bar:
                for entries in pool.map_unordered(execute_batch, [(spec, b, calibrations, str(out)) for b in tasks]):
                    for entry in entries:
                        fh.write(json.dumps(entry, allow_nan=True) + "\n")
                        journal[entry["index"]] = entry
                        session.runs += 1
                        errors += entry["rows"][0].get("error") is not None if entry["rows"] else 0
                    fh.flush()
                    os.fsync(fh.fileno())
                    bar(len(entries))
                    if errors:
                        bar.set_postfix(errors=errors)
            session.seconds = time.perf_counter() - start
    except KeyboardInterrupt as exc:      # SIGINT or SIGTERM, here or inside a run in this process (RunInterrupted)
        raise CampaignInterrupted(len([i for i in journal if i < total]), total, out, signal_of(exc)) from None
    table = results_table([journal[i] for i in sorted(journal) if i < total], spec.diagnosers)
    result = CampaignResult(out, spec, table)
    if report:
        write_outputs(result, session.as_dict())
    else:
        table.to_parquet(out / TABLE, index=False)
    return result

