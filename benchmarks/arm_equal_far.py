"""Incipient actuator faults at equal false-alarm rates: the acceptance campaign's runs, each diagnoser's thresholds
scaled until its fault-free runs are just all quiet.

    python benchmarks/arm_equal_far.py --robots iiwa [--speed fast] [--drive-inertia auto] [--runs N] [--seed S]
                                       [--diagnosers momentum consistency] [--workers W] [--set NAME=VALUE …]
                                       [--classes actuator_incipient component_mass component_friction]

Issue 24 asks that the consistency scheme detect incipient faults "at least as well as momentum at equal FAR".
At their calibrated thresholds the two do not have equal false-alarm rates on every arm (momentum: 14 of 300
fault-free runs on robosuite's panda). This script re-runs the fault-free runs and the incipient actuator faults
(or the faults of --classes) of ``benchmarks/arm_acceptance.toml`` (the same seeds, missions, faults and
calibrations as ``arm_acceptance.py``) and takes from every diagnoser's trace its peak ratio
max_j |r_j| / threshold_j: over the whole run after the start-up blanking for a fault-free run, over [onset, end)
for a faulty one. A diagnoser's *0-FA scale* is its largest fault-free peak ratio: the factor on all its
thresholds (above 1 or below) at which its fault-free runs are just all quiet. At that scale every diagnoser has
the same empirical false-alarm rate, 0 of the fault-free runs, and a fault counts as detected when its peak ratio
exceeds it. (The scale is read off the same fault-free runs it is then applied to: a comparison of detection
power at equal false-alarm rate, not a calibration. Only the thresholds are scaled: a scheme whose decision also
holds evidence would isolate differently, not detect differently.)
Prints per diagnoser: fault-free runs with an alarm at its own thresholds, its 0-FA scale, and the faults detected
at its own thresholds and at its 0-FA scale. For a diagnoser whose rows come in sets (the consistency scheme:
dynamic ``joint<i>``, ``_kin``, ``_step``, ``payload``) also each set's peak ratio, and the faults detected with
every set at its own 0-FA scale ("balanced"): the fault-free runs stay all quiet, and a fault counts when any set
exceeds its scale — what thresholds balanced across the sets could detect at the same empirical rate (a bound,
read off the runs it is applied to, like the 0-FA scale). The CSV of --out also keeps each row's peak ratio
(column ``diagnoser:component``), which benchmarks/threshold_tails.py rescales.
--classes chooses the faulty runs (the fault classes of arm_quality.py; default: the incipient actuator faults):
e.g. ``component_mass`` (payload changes) and ``component_friction`` (friction rises), each summarised on its own.
"""
from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from arm_acceptance import acceptance_spec, drive_inertia, mission_speed  # noqa: E402
from arm_quality import _class, settings_option  # noqa: E402

from robofdi.campaign.runs import draw_fault, faulty_indices, run_seed  # noqa: E402
from robofdi.campaign.spec import parse_spec  # noqa: E402
from robofdi.decision.isolation import startup_samples  # noqa: E402
from robofdi.progress import Progress  # noqa: E402
from robofdi.seeding import rng  # noqa: E402

_SPEC, _CALIBRATIONS = None, {}


INCIPIENT = "actuator_incipient"


def fault_class(fault) -> str:
    """``fault``'s class as arm_quality.py counts it (e.g. "actuator_incipient" for "incipient detected")."""
    return _class({"kind": fault.kind, "target": fault.target, "profile": fault.profile.type_name})


def peak_ratios(data: dict, index: int, classes=(INCIPIENT,)) -> dict:
    """One run: {"index", "faulty", "class", diagnoser: peak ratio} (module docstring); None for a faulty run whose
    fault is not of ``classes``."""
    global _SPEC
    if _SPEC is None:
        _SPEC = parse_spec(data)
    spec = _SPEC
    system = spec.campaign_system
    keys = system.calibration_keys(spec.options)
    key = keys[index % len(keys)]
    if key not in _CALIBRATIONS:         # once per worker: finding a cached one plans the calibration motions
        _CALIBRATIONS[key] = system.calibrate(spec.options, key, spec.diagnosers)[0]
    cal = _CALIBRATIONS[key]
    seed = run_seed(spec.seed, index)
    mission = system.mission(spec.options, key, rng(seed, "mission"))
    fault = draw_fault(spec, seed, mission.duration)[0] if faulty_indices(spec)[index] else None
    if fault is not None and fault_class(fault) not in classes:
        return None
    record = system.run(spec.options, cal, key, mission, [] if fault is None else [fault], seed, spec.diagnosers)
    out = {"index": index, "faulty": fault is not None, "class": "" if fault is None else fault_class(fault)}
    for name in spec.diagnosers:
        trace = record.diagnosers[name]
        t = np.asarray(trace.time)
        ratio = (np.abs(trace.residual) / np.asarray(trace.threshold)).max(axis=1)
        if fault is None:
            window = np.arange(t.size) >= startup_samples(float(t[1] - t[0]))
        else:
            window = (t >= fault.onset) & (t < (np.inf if fault.end is None else fault.end))
        out[name] = float(ratio[window].max()) if window.any() else 0.0
        out[f"{name} alarm"] = bool(np.asarray(trace.alarm)[window].any())     # the decision's own, to check
        sets = [_row_set(c) for c in trace.components]
        if len(set(sets)) > 1:
            rows = np.abs(trace.residual) / np.asarray(trace.threshold)
            for group in sorted(set(sets)):
                columns = [j for j, g in enumerate(sets) if g == group]
                out[f"{name}[{group}]"] = float(rows[np.ix_(window, columns)].max()) if window.any() else 0.0
            peaks = rows[window].max(axis=0) if window.any() else np.zeros(len(sets))
            out.update({f"{name}:{c}": float(v) for c, v in zip(trace.components, peaks)})   # each row's peak ratio
    return out


def _row_set(component: str) -> str:
    """The set of a residual component: its suffix ``kin`` or ``step``, ``payload``, else ``dynamic``."""
    if component == "payload":
        return "payload"
    suffix = component.rsplit("_", 1)[-1]
    return suffix if suffix in ("kin", "step") else "dynamic"


def summary(rows: pd.DataFrame, diagnosers, of_class: str = INCIPIENT) -> pd.DataFrame:
    """Per diagnoser: its fault-free alarms and 0-FA scale, and the faults of class ``of_class`` it detects at its
    own thresholds, at its 0-FA scale and with its row sets balanced (module docstring)."""
    if "class" not in rows:                 # a CSV from before --classes: incipient faults only
        rows = rows.assign(**{"class": np.where(rows["faulty"], INCIPIENT, "")})
    free, faulty = rows[~rows["faulty"]], rows[rows["faulty"] & (rows["class"] == of_class)]
    table = []
    for name in diagnosers:
        disagree = int(((rows[name] > 1) != rows[f"{name} alarm"]).sum())
        if disagree:
            print(f"note: {name}: on {disagree} runs the peak ratio and the decision's alarm disagree (an alarm "
                  f"is more than a threshold crossing there)")
        scale = float(free[name].max())
        sets = [c for c in rows.columns if c.startswith(f"{name}[")]
        balanced = np.zeros(len(faulty), dtype=bool)
        for column in sets:                 # each set at its own 0-FA scale: still no fault-free run alarmed
            balanced |= (faulty[column] > float(free[column].max())).to_numpy()
        table.append({"diagnoser": name,
                      "fault-free runs alarmed": f"{int((free[name] > 1).sum())}/{len(free)}",
                      "0-FA scale": f"{scale:.3f}",
                      "detected": f"{int((faulty[name] > 1).sum())}/{len(faulty)}",
                      "detected at 0-FA scale": f"{int((faulty[name] > scale).sum())}/{len(faulty)}",
                      "sets' 0-FA scales": ", ".join(f"{c[len(name) + 1:-1]} {float(free[c].max()):.3f}" for c in sets)
                      or "-",
                      "balanced": f"{int(balanced.sum())}/{len(faulty)}" if sets else "-"})
    return pd.DataFrame(table).set_index("diagnoser")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=["arm6.xml"])
    ap.add_argument("--speed", type=mission_speed, default="fast", help="as benchmarks/arm_acceptance.py")
    ap.add_argument("--drive-inertia", default="auto", help='as in arm_acceptance.py: [s²] or "auto"')
    ap.add_argument("--diagnosers", nargs="+", default=["momentum", "consistency"])
    ap.add_argument("--runs", type=int, default=None, help="only the first N runs of the campaign")
    ap.add_argument("--seed", type=int, default=None, help="campaign seed (default: the TOML's), as in arm_acceptance.py")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default=None, help="folder for one CSV of peak ratios per robot")
    ap.add_argument("--set", nargs="+", default=None, metavar="NAME=VALUE", help="more [system] fields, as in arm_acceptance.py")
    ap.add_argument("--from-csv", nargs="+", default=None, help="only summarise CSVs an earlier --out wrote")
    ap.add_argument("--classes", nargs="+", default=[INCIPIENT],
                    help="the faulty runs' classes, as arm_quality.py names them (default: actuator_incipient)")
    args = ap.parse_args()
    for path in args.from_csv or ():
        if not Path(path).is_file():
            raise SystemExit(f"--from-csv: no file {path!r} (expected a CSV an earlier --out wrote)")
        for name in args.classes:
            print(f"\n## {Path(path).stem}: {name}")
            print(summary(pd.read_csv(path), args.diagnosers, name).to_string())
    for robot in args.robots if not args.from_csv else ():
        data = acceptance_spec(robot, args.speed, args.drive_inertia, args.seed, diagnosers=args.diagnosers,
                               system=settings_option(args.set))
        spec = parse_spec(data)
        system = spec.campaign_system
        for key in system.calibration_keys(spec.options):      # once, before the workers load them
            system.calibrate(spec.options, key, spec.diagnosers)
        total = spec.fault_free_runs + spec.faulty_runs
        n = total if args.runs is None else min(args.runs, total)
        rows = []
        with Progress(f"{Path(robot).stem}-{args.speed}").stage("runs", total=n, unit="run") as tick, \
                ProcessPoolExecutor(args.workers) as pool:
            for row in pool.map(peak_ratios, [data] * n, range(n), [tuple(args.classes)] * n, chunksize=4):
                tick(1)
                if row is not None:
                    rows.append(row)
        table = pd.DataFrame(rows)
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            table.to_csv(Path(args.out) / f"{Path(robot).stem}-{args.speed}.csv", index=False)
        for name in args.classes:
            print(f"\n## {robot}, {args.speed}, drive inertia {drive_inertia(args.drive_inertia, robot)} s²: {name}")
            print(summary(table, args.diagnosers, name).to_string())


if __name__ == "__main__":
    main()
