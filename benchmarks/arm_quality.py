"""Arm diagnosis quality, measured by campaigns (issue 10): benchmarks/arm_quality.toml on arm6 and arm7.

    python benchmarks/arm_quality.py [--robots arm6.xml arm7.xml] [--workers 2] [--out runs/arm-quality]
                                     [--runs N] [--seed S] [--diagnosers momentum consistency]
                                     [--set NAME=VALUE …]

--seed draws another campaign of the same design (the robot instance and its calibration stay those of the TOML:
the faults and motions are new), the check that nothing was tuned to the shipped campaign's seed.

Each robot's campaign is resumable (re-running the command continues it). Per diagnoser it prints:
- fault-free runs with a false alarm, with the 95 % Clopper–Pearson upper bound of the rate;
- detection and correct isolation of the faults at or above twice the minimum detectable size of their
  (kind, target) — the size at which that diagnoser's isotonic detection curve reaches 90 %;
- the median detection delay of abrupt actuator faults, in diagnosis samples (2 ms, or the campaign's
  ``diagnosis_hz``): additive steps and intermittent faults (their onset is a jump; until 2026-12-07 the column
  also held the 2 s ramps, which are detected as they grow: class ``actuator_slow`` now, with its own delay), and
  of the steps alone ("step delay", the issue's "abrupt actuator steps"), all detected and those at ≥ 2× their
  minimum detectable size;
- the detection rate of incipient actuator faults (exponential rises; against the momentum baseline's), also at
  equal false alarms: every diagnoser's thresholds × the smallest factor at which only as many of its fault-free
  runs alarm as the best one's at its own thresholds (:func:`robofdi.campaign.at_equal_false_alarms`, a point of
  each ROC curve chosen on the same runs; "×s" is the factor);
- for encoder drifts: the accumulated offset at detection and the smallest detectable encoder bias of the same
  joint (medians over the drifts; the bias MDF is an upper bound when the smallest bias drawn was detected), and
  how many of the drifts whose offset reached DRIFT_FACTOR × that bias by the end of the run were detected; and
  how many of the drifts that an oracle could have detected by the end of the run were: the test that knows the
  onset and the rate d, on the mean of the velocity noise over the t seconds since onset, has z = d·√(t/T)/σ_v;
  "could" is z ≥ DRIFT_ORACLE_Z. No detector does better: a drift is caught after an offset of about
  z²σ_v²T/d, more as it slows down (docs/systems/arm.md, "Slow encoder drifts").
Also the robot's calibration cost (one calibration per robot, computed before the campaign and timed; a cached
one costs the time to load it: empty ROBOFDI_CACHE to measure it).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

try:
    import tomllib
except ModuleNotFoundError:        # Python 3.10
    import tomli as tomllib

from robofdi.campaign import at_equal_false_alarms, clopper_pearson, detection_curve, run_campaign
from robofdi.campaign.results import load
from robofdi.sims.arm import SensorModel

HERE = Path(__file__).resolve().parent
SAMPLE = 0.002          # diagnosis period of the shipped arms [s]
DRIFT_FACTOR = 3.0      # a drift "should be detected" once its accumulated offset reaches this × the bias MDF
DRIFT_ORACLE_Z = 5.0    # the z an oracle test needs (one-sided Gaussian tail 3e-7 per test)
VELOCITY_NOISE = SensorModel().velocity_noise       # σ_v of the campaign's (default) sensors [rad/s]


def drift_oracle_z(rate: float, seconds: float, sample: float = SAMPLE) -> float:
    """z of the known-onset, known-rate test for an encoder drift of ``rate`` [rad/s] after ``seconds``: its offset
    over the standard deviation of the integrated velocity noise, σ_v·√(T·t), with T = ``sample`` [s] the period
    of the velocity readings the diagnosis integrates."""
    return abs(rate) * np.sqrt(seconds / sample) / VELOCITY_NOISE


def _class(row) -> str:
    kind, target, profile = row["kind"], str(row["target"]), str(row["profile"])
    if kind == "actuator_additive":
        return {"exponential_rise": "actuator_incipient", "ramp": "actuator_slow"}.get(profile, "actuator_abrupt")
    if kind.startswith("sensor"):
        return f"{kind}_{'vel' if target.endswith('_vel') else 'pos'}"
    return kind


def minimum_detectable(rows: pd.DataFrame, level: float = 0.9) -> dict:
    """(class, target) → smallest size at which the detection curve reaches ``level`` (None: never)."""
    out = {}
    for key, g in rows.groupby(["class", "target"]):
        s, p = detection_curve(g["size"].to_numpy(float), g["detected"].fillna(False).to_numpy(bool))
        hit = np.flatnonzero(p >= level)
        out[key] = float(s[hit[0]]) if hit.size else None
    return out


def quality(table: pd.DataFrame, sample: float = SAMPLE) -> pd.DataFrame:
    """The per-diagnoser quality table (module docstring); delays in diagnosis samples of ``sample`` [s]."""
    table = table[table["error"].isna()] if "error" in table else table
    faulty = table[table["faulty"]].copy()
    faulty["class"] = faulty.apply(_class, axis=1)
    equal = at_equal_false_alarms(table) or {"diagnosers": {}}
    rows = []
    for name, d in table.groupby("diagnoser", sort=False):
        free = d[~d["faulty"]]
        fa = int((free["false_alarms"].fillna(0) > 0).sum())
        f = faulty[faulty["diagnoser"] == name]
        mdf = minimum_detectable(f)
        limit = pd.Series([mdf.get(k) for k in zip(f["class"], f["target"])], index=f.index, dtype=float)
        big = f[limit.notna() & (f["size"] >= 2 * limit.fillna(np.inf))]
        det = big["detected"].fillna(False).astype(bool)
        correct = big["correct"].fillna(False).astype(bool) & det
        final = (big["final_correct"].fillna(False).astype(bool) & det if "final_correct" in big
                 else pd.Series(False, index=big.index))
        abrupt = f[(f["class"] == "actuator_abrupt") & f["detected"].fillna(False).astype(bool)]
        steps = abrupt[abrupt["profile"].astype(str) == "step"]
        big_steps = steps[steps.index.isin(big.index)]
        incipient = f[f["class"] == "actuator_incipient"]
        slow = f[(f["class"] == "actuator_slow") & f["detected"].fillna(False).astype(bool)]
        scale = equal["diagnosers"].get(name, {}).get("threshold_scale")
        drift = f[f["class"] == "sensor_drift_pos"]
        offsets, biases = [], []      # [rad]: a drift's accumulated offset at detection; the joint's MDF bias
        reached = caught = 0          # drifts whose final offset reached DRIFT_FACTOR × the MDF bias; detected
        detectable = [bool(r["detected"]) if pd.notna(r["detected"]) else False for _, r in drift.iterrows()
                      if drift_oracle_z(r["magnitude"], r["duration"] - r["onset"], sample) >= DRIFT_ORACLE_Z]
        for _, r in drift.iterrows():
            bias = mdf.get(("sensor_bias_pos", r["target"]))
            if not bias:
                continue
            detected = bool(r["detected"]) if pd.notna(r["detected"]) else False
            if detected:
                offsets.append(abs(r["magnitude"]) * r["delay"])
                biases.append(bias * r["limit"])
            if abs(r["magnitude"]) * (r["duration"] - r["onset"]) >= DRIFT_FACTOR * bias * r["limit"]:
                reached += 1
                caught += detected
        rows.append({
            "diagnoser": name,
            "false-alarm runs": f"{fa}/{len(free)}",
            "FA rate 95% upper": f"{100 * clopper_pearson(fa, len(free))[1]:.1f} %" if len(free) else "-",
            "≥2×MDF detected": f"{int(det.sum())}/{len(big)}",
            "≥2×MDF correct first": f"{int(correct.sum())}/{len(big)}",
            "≥2×MDF correct at the end": f"{int(final.sum())}/{len(big)}" if "final_correct" in big else "-",
            "abrupt delay [samples]": f"{np.median(abrupt['delay']) / sample:.1f}" if len(abrupt) else "-",
            "step delay, all / ≥2×MDF [samples]": " / ".join(f"{np.median(g['delay']) / sample:.1f}" if len(g) else "-"
                                                              for g in (steps, big_steps)),
            "ramp delay [samples]": f"{np.median(slow['delay']) / sample:.1f}" if len(slow) else "-",
            "incipient detected": f"{int(incipient['detected'].fillna(False).sum())}/{len(incipient)}",
            "incipient at equal FA": "-" if scale is None else
                f"{int((incipient['peak_ratio_fault'] > scale).sum())}/{len(incipient)} (×{scale:.3g})",
            "drift offset at detection / MDF bias [mrad]":
                f"{1e3 * np.median(offsets):.3f} / {1e3 * np.median(biases):.3f}" if offsets else "-",
            f"drifts reaching {DRIFT_FACTOR:g}×MDF bias detected": f"{caught}/{reached}",
            f"oracle-detectable drifts (z≥{DRIFT_ORACLE_Z:g}) detected": f"{sum(detectable)}/{len(detectable)}",
        })
    return pd.DataFrame(rows).set_index("diagnoser")


def per_class_at_equal_false_alarms(table: pd.DataFrame) -> pd.DataFrame | None:
    """Faults detected per class (detected/faults) by every diagnoser at equal false alarms (the quality table's
    "×s"); None when the table has no peak ratios (campaigns before 2026-12-07) or one diagnoser."""
    table = table[table["error"].isna()] if "error" in table else table
    equal = at_equal_false_alarms(table)
    if equal is None:
        return None
    f = table[table["faulty"]].copy()
    f["class"] = f.apply(_class, axis=1)
    out = {}
    for name, e in equal["diagnosers"].items():
        g = f[f["diagnoser"] == name].assign(hit=lambda x, s=e["threshold_scale"]: x["peak_ratio_fault"] > s)
        count = g.groupby("class")["hit"].agg(["sum", "size"])
        out[f"{name} (×{e['threshold_scale']:.3g})"] = pd.Series(
            [f"{int(a)}/{int(b)}" for a, b in count.to_numpy()], index=count.index)
    return pd.DataFrame(out)


def per_class(table: pd.DataFrame, diagnoser: str) -> pd.DataFrame:
    f = table[table["faulty"] & (table["diagnoser"] == diagnoser)].copy()
    f["class"] = f.apply(_class, axis=1)
    g = f.groupby("class")
    out = pd.DataFrame({"faults": g.size(), "detected": g["detected"].sum(), "correct": g["correct"].sum()})
    if "final_correct" in f:
        out["correct at the end"] = g["final_correct"].sum()
    return out.assign(**{"median size": g["size"].median()})


def settings_option(items) -> dict:
    """--set NAME=VALUE … as [system] fields (e.g. the diagnosers' ``consistency_tail=exponential``): each VALUE
    read as a TOML value, else as a string."""
    out = {}
    for item in items or ():
        name, eq, value = item.partition("=")
        if not eq or not name.strip():
            raise SystemExit(f"--set: expected NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out[name.strip()] = value
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=["arm6.xml", "arm7.xml"])
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", default="runs/arm-quality")
    ap.add_argument("--runs", type=int, default=None, help="only the first N runs (a prefix of the campaign)")
    ap.add_argument("--seed", type=int, default=None, help="campaign seed (default: the TOML's)")
    ap.add_argument("--diagnosers", nargs="+", default=None, help="a subset of the TOML's diagnosers")
    ap.add_argument("--set", nargs="+", default=None, metavar="NAME=VALUE",
                    help="more [system] fields, e.g. consistency_calibration_motions=6")
    args = ap.parse_args()
    spec = tomllib.loads((HERE / "arm_quality.toml").read_text())
    spec["system"].update(settings_option(args.set))
    if args.seed is not None:
        spec["seed"] = args.seed
    if args.diagnosers:
        unknown = sorted(set(args.diagnosers) - set(spec["diagnosers"]))
        if unknown:
            ap.error(f"--diagnosers: {unknown} not in {spec['diagnosers']}")
        spec["diagnosers"] = args.diagnosers
    for robot in args.robots:
        spec["system"]["robot"] = robot
        out = Path(args.out) / Path(robot).stem
        t0 = time.perf_counter()
        resume = (out / "runs.jsonl").is_file()
        run_campaign(spec, out, workers=args.workers, resume=resume, runs=args.runs, progress=True)
        table = load(out).table
        print(f"\n## {robot}: {table['index'].nunique()} runs, {time.perf_counter() - t0:.0f} s wall this session")
        calibration = (json.loads((out / "campaign.json").read_text()).get("execution") or {}).get("calibration")
        for key, info in ((calibration or {}).get("per_key") or {}).items():
            how = "from the cache" if info["cached"] else "computed"
            print(f"calibration (robot seed {key}): {info['seconds']:.1f} s, {how}")
        print(quality(table).to_string())
        if "consistency" in spec["diagnosers"]:
            print("\nconsistency by fault class:")
            print(per_class(table, "consistency").to_string())


if __name__ == "__main__":
    main()
