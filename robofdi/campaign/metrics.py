"""Campaign metrics from the results table: what judges a diagnoser over many runs.

Per diagnoser: false-alarm rate over fault-free runs (runs with at least one alarm episode) with its exact 95 %
Clopper–Pearson interval; detection rate, isolation accuracy, confusion matrix, delay median and 90th percentile,
all also per fault kind (and per kind and profile); the share of faults whose true target is isolated at
some time after detection (``eventually_correct``: a revisable isolation may reach it after a wrong first
call) with the median time to that correct isolation, next to the median time to (correct) first isolation;
detection probability against fault size per (kind, target) and the minimum detectable
fault read from that curve — only for kinds with a size (not :data:`~robofdi.faults.MAGNITUDE_FREE`: a lock, float,
hard-over or freeze has none). Faults whose target a diagnoser cannot name (column ``isolable``: a mass change on a
link) count as not correctly isolated in ``correctly_isolated`` and ``isolation_accuracy`` as before, and are
counted apart: ``not_isolable`` and ``isolation_accuracy_isolable`` (correct among the detected isolable ones).
Error rows (runs that raised) are counted and left out of every rate.

:func:`at_equal_false_alarms` compares the diagnosers at one false-alarm count (each one's thresholds scaled, read
from the columns ``peak_ratio_free`` / ``peak_ratio_fault``), not each at its own.
"""
from __future__ import annotations

import functools
from collections import Counter

import numpy as np
import pandas as pd
from scipy.optimize import isotonic_regression
from scipy.stats import binomtest

from robofdi.faults import MAGNITUDE_FREE

__all__ = ["clopper_pearson", "detection_curve", "analyse", "at_equal_false_alarms", "MISSED", "UNISOLATED"]

#: Confusion-matrix columns of a missed fault and of a detection with nothing isolated.
MISSED, UNISOLATED = "missed", "unknown"


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> list[float] | None:
    """Exact binomial interval for k successes in n trials — Clopper & Pearson, Biometrika 26(4), 1934."""
    if n == 0:
        return None
    return list(_clopper_pearson(int(k), int(n), float(confidence)))


@functools.lru_cache(maxsize=4096)
def _clopper_pearson(k: int, n: int, confidence: float) -> tuple[float, float]:
    """The interval of :func:`clopper_pearson`, computed once per (k, n, confidence): a campaign's analysis asks for
    the same counts many times (per diagnoser, kind, target), and each is a root search."""
    ci = binomtest(k, n).proportion_ci(confidence, method="exact")
    return float(ci.low), float(ci.high)


def _rate(k: int, n: int) -> dict:
    return {"count": int(k), "of": int(n), "rate": (k / n) if n else None, "ci95": clopper_pearson(k, n)}


def detection_curve(size: np.ndarray, detected: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Monotone detection probability against size: the isotonic (non-decreasing) least-squares fit of the 0/1
    outcomes sorted by size — pool-adjacent-violators, Ayer et al., Ann. Math. Statist. 26(4), 1955.
    Returns (sorted sizes, fitted probability at each)."""
    order = np.argsort(size, kind="stable")
    s, d = np.asarray(size, float)[order], np.asarray(detected, float)[order]
    if s.size == 0:
        return s, d
    return s, isotonic_regression(d, increasing=True).x


def _minimum_detectable(size, detected, level: float):
    s, p = detection_curve(size, detected)
    hit = np.flatnonzero(p >= level)
    return (float(s[hit[0]]) if hit.size else None), s, p


def _fault_metrics(rows: pd.DataFrame) -> dict:
    n = len(rows)
    detected = rows["detected"].fillna(False).astype(bool)
    correct = rows["correct"].fillna(False).astype(bool) & detected
    delays = rows.loc[detected, "delay"].astype(float).to_numpy()
    to_correct = (rows["time_to_correct_isolation"].dropna().astype(float).to_numpy()
                  if "time_to_correct_isolation" in rows else np.array([]))
    eventually = int(to_correct.size)
    able = (rows["isolable"].astype(object).where(rows["isolable"].notna(), True).astype(bool)
            if "isolable" in rows else pd.Series(True, index=rows.index))        # tables before the column
    return {
        "faults": n,
        "detection": _rate(int(detected.sum()), n),
        "isolation_accuracy": _rate(int(correct.sum()), int(detected.sum())),       # correct among detected
        "correctly_isolated": _rate(int(correct.sum()), n),                          # correct among all faults
        "delay_median": float(np.median(delays)) if delays.size else None,
        "delay_p90": float(np.percentile(delays, 90)) if delays.size else None,
        "runs_with_false_alarm_before_onset": int((rows["false_alarms"].fillna(0) > 0).sum()),
        # a revisable isolation: the true target isolated at some time after detection, and how soon
        "eventually_correct": _rate(eventually, n),
        "time_to_correct_isolation_median": float(np.median(to_correct)) if to_correct.size else None,
        "time_to_isolation_median": (float(rows.loc[correct, "time_to_isolation"].dropna().astype(float).median())
                                     if correct.any() and "time_to_isolation" in rows else None),
        "not_isolable": int((~able).sum()),
        "isolation_accuracy_isolable": _rate(int((correct & able).sum()), int((detected & able).sum())),
    }


def _confusion(rows: pd.DataFrame) -> dict:
    """True target → {what was said: the isolated target, "unknown" or "missed" → faults}, the counts that are not
    zero, both levels in sorted order (the cells of ``pd.crosstab(truth, said)``, counted without building it)."""
    truth = rows["target"].astype(str).tolist()
    detected = rows["detected"].fillna(False).astype(bool)
    isolated = rows["isolated"].astype(object).where(rows["isolated"].notna(), UNISOLATED)
    said = np.where(detected, isolated.astype(str), MISSED).tolist()
    counts = Counter(zip(truth, said))
    columns = sorted(set(said))
    return {t: {c: counts[t, c] for c in columns if counts[t, c]} for t in sorted(set(truth))}


def analyse(table: pd.DataFrame, detection_level: float = 0.9, diagnosers=None) -> dict:
    """campaign.json's "diagnosers" block (see the module docstring); ``detection_level``: the detection
    probability at which a fault counts as detectable."""
    ok = table[table["error"].isna()]
    names = list(diagnosers) if diagnosers is not None else list(dict.fromkeys(table["diagnoser"]))
    out = {}
    for name in names:
        mine = ok[ok["diagnoser"] == name]
        free = mine[~mine["faulty"]]
        faulty = mine[mine["faulty"]]
        false_runs = int((free["false_alarms"].fillna(0) > 0).sum())
        entry = {
            "false_alarm_rate": _rate(false_runs, len(free)),
            "faulty": _fault_metrics(faulty),
            "by_kind": {k: _fault_metrics(g) for k, g in faulty.groupby("kind", sort=True)},
            # abrupt and incipient faults of one kind apart: "actuator_additive~exponential_rise"
            "by_kind_profile": {f"{k}~{p}": _fault_metrics(g) for (k, p), g in faulty.groupby(["kind", "profile"], sort=True)},
            "confusion": {k: _confusion(g) for k, g in faulty.groupby("kind", sort=True)},
            "detectability": {},
        }
        for (kind, target), g in faulty.groupby(["kind", "target"], sort=True):
            if kind in MAGNITUDE_FREE:          # no size: detected or not (by_kind), no minimum detectable fault
                continue
            size, det = g["size"].to_numpy(float), g["detected"].fillna(False).astype(bool).to_numpy()
            smallest, _, _ = _minimum_detectable(size, det, detection_level)
            limit = float(g["limit"].iloc[0])
            entry["detectability"].setdefault(kind, {})[target] = {
                "faults": len(g), "detected": int(det.sum()), "size_range": [float(size.min()), float(size.max())],
                "min_detectable_size": smallest,
                "min_detectable_magnitude": None if smallest is None else smallest * limit,
                # the smallest size drawn was already detected at the level: the true minimum may be smaller
                "min_detectable_at_most": smallest is not None and smallest <= float(size.min()),
                "unit": str(g["unit"].iloc[0]), "limit": limit,
            }
        out[name] = entry
    return out


def _scale_for(peaks: np.ndarray, allowed: int) -> float:
    """The smallest threshold scale s at which at most ``allowed`` of ``peaks`` exceed s (an alarm: ratio > s)."""
    ranked = np.sort(peaks)[::-1]
    return float(ranked[allowed]) if allowed < ranked.size else 1.0


def at_equal_false_alarms(table: pd.DataFrame, diagnosers=None) -> dict | None:
    """Every diagnoser at one false-alarm count, a point of each one's ROC curve: k = the fewest fault-free runs
    with an alarm that any diagnoser has at its own thresholds; each diagnoser's thresholds are scaled by the
    smallest s at which only k of its fault-free runs alarm (its (k+1)-th largest ``peak_ratio_free``: above 1 for
    a diagnoser with more false alarms, below 1 for one with spare), and it detects the faults whose
    ``peak_ratio_fault`` exceeds s. Exact for fixed-threshold alarms (an alarm is |r_j| > s·threshold_j; delays and
    isolation are not recomputed). Every s is chosen on the same fault-free runs it is then judged on: a
    comparison of the residuals at one false-alarm count, not thresholds to deploy. Only diagnosers whose every
    error-free row has the peak columns take part; None when fewer than two do.

    Returns {"false_alarm_runs": k, "fault_free_runs": n, "diagnosers": {name: {"threshold_scale", "false_alarm_runs",
    "detection" (a rate), "by_kind_profile": {"kind~profile": {"detected", "faults"}}}}}."""
    if "peak_ratio_free" not in table or "peak_ratio_fault" not in table:
        return None
    ok = table[table["error"].isna()]
    names = list(diagnosers) if diagnosers is not None else list(dict.fromkeys(ok["diagnoser"]))
    usable = {}
    for name in names:
        mine = ok[ok["diagnoser"] == name]
        free = mine.loc[~mine["faulty"], "peak_ratio_free"].to_numpy(float)
        faulty = mine[mine["faulty"]]
        if free.size and np.isfinite(free).all() and np.isfinite(faulty["peak_ratio_fault"].to_numpy(float)).all():
            usable[name] = (free, faulty)
    if len(usable) < 2:
        return None
    k = min(int((free > 1.0).sum()) for free, _ in usable.values())
    out = {}
    for name, (free, faulty) in usable.items():
        scale = _scale_for(free, k)
        hit = faulty["peak_ratio_fault"].to_numpy(float) > scale
        groups = faulty.assign(_hit=hit).groupby(["kind", "profile"], sort=True)["_hit"]
        out[name] = {"threshold_scale": scale, "false_alarm_runs": int((free > scale).sum()),
                     "detection": _rate(int(hit.sum()), len(hit)),
                     "by_kind_profile": {f"{kind}~{profile}": {"detected": int(g.sum()), "faults": int(g.size)}
                                         for (kind, profile), g in groups}}
    return {"false_alarm_runs": k, "fault_free_runs": int(min(free.size for free, _ in usable.values())),
            "diagnosers": out}
