"""The consistency scheme's thresholds under other tail laws, checked on a campaign's own runs.

    python benchmarks/arm_equal_far.py --robots kinova3 --speed normal --seed 7211 \
        --set "robot_seeds=[70,71,72,73]" segments=5 --classes component_mass --out runs/efar
    python benchmarks/threshold_tails.py --robots kinova3 --speed normal --seed 7211 \
        --set "robot_seeds=[70,71,72,73]" segments=5 --csv runs/efar/kinova3-normal.csv [--rows payload]

Every consistency row's threshold is fitted to the 0.25 s block maxima of its residual on the held-out calibration
motions (:func:`robofdi.decision.extreme_value_thresholds`, 0.1 false alarms per hour). Whether another law would
be safe cannot be told from those ~40 s themselves: this script re-makes each robot instance's calibration (the
same code and options as the campaign, so the same thresholds), keeps the held-out residuals, fits each law to the
chosen rows, and rescales the peak ratios that ``arm_equal_far.py`` stored for the same campaign's runs (the
fault-free runs and the faulty runs of its --classes): a row's new ratio is its stored peak × old / new threshold.
Printed per law: the new threshold over the old one per robot instance (range), the fault-free runs' largest
ratio and how many would alarm, and the faulty runs these rows alone would detect, per class.

The laws (each never below the held-out maximum, as the calibration does):
- ``gumbel``: the calibration's own fit (a check: its ratios are the stored ones);
- ``exponential``: the excesses of the largest 30 % of the block maxima (Coles 2001 eq. 4.13, shape 0);
- ``gev``: the generalised extreme-value law with its shape fitted too (Coles 2001 Sec. 3.3);
- ``gumbel-1s``: the Gumbel fit to 1 s blocks;
- ``margin-1.5``: 1.5 × the held-out maximum (momentum's rule, with its 1.2 raised).
Rows: ``payload`` (default), ``dynamic``, ``kin`` or ``step``; a set of several rows needs the per-row columns
that ``arm_equal_far.py`` writes since 2026-12-07.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from arm_acceptance import acceptance_spec, mission_speed  # noqa: E402
from arm_equal_far import _row_set  # noqa: E402
from arm_quality import settings_option  # noqa: E402

LAWS = ("gumbel", "exponential", "gev", "gumbel-1s", "margin-1.5")
BLOCK = 0.25          # [s], the calibration's block (extreme_value_thresholds' default)


def block_maxima(residuals, column: int, T: float, skip: int, block: float = BLOCK) -> np.ndarray:
    """The maxima of |r_column| over whole blocks of ``block`` s of every run (samples before ``skip`` left out)."""
    size = int(round(block / T))
    out = []
    for r in residuals:
        x = np.abs(np.asarray(r)[skip:, column])
        whole = x.size // size
        if whole:
            out.append(x[: whole * size].reshape(whole, size).max(axis=1))
    return np.concatenate(out)


def levels(residuals, column: int, T: float, skip: int, rate_per_hour: float) -> dict[str, float]:
    """Each law's threshold for one row (module docstring), never below the held-out maximum: the Gumbel and
    exponential fits and the 1 s blocks are the calibration's own function, the GEV and the margin added here."""
    from scipy.stats import genextreme

    from robofdi.decision.thresholds import extreme_value_thresholds

    rows = [np.asarray(r)[:, [column]] for r in residuals]
    fit = {law: float(extreme_value_thresholds(rows, T, rate_per_hour, block=block, skip=skip, tail=tail)[0])
           for law, block, tail in (("gumbel", BLOCK, "gumbel"), ("exponential", BLOCK, "exponential"),
                                    ("gumbel-1s", 1.0, "gumbel"))}
    maxima = block_maxima(residuals, column, T, skip)
    top = float(maxima.max())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # genextreme.fit's optimiser on short samples
        gev = float(genextreme.isf(rate_per_hour * BLOCK / 3600.0, *genextreme.fit(maxima)))
    return {**fit, "gev": max(gev, top), "margin-1.5": 1.5 * top}


def held_out_residuals(system, options, key):
    """The consistency scheme's calibration (thresholds as the campaign has them, re-made: the calibration cache
    keeps thresholds, not the runs) and its residuals on the held-out calibration motions, for robot instance
    ``key`` (what :func:`robofdi.systems.arm.calibrate` fits). ``system._scenario``: the campaign's own scenario."""
    from robofdi.decision.isolation import startup_samples
    from robofdi.loop import Diagnosis, diagnose_record
    from robofdi.observers.arm_schemes import arm_schemes
    from robofdi.systems.arm import calibrate, calibration_records, design_split

    scenario = system._scenario(options, key, ("consistency",))
    records = calibration_records(scenario)
    cal = calibrate(scenario, records)
    sim = scenario.simulator()
    model, rates = scenario.nominal_model(sim), scenario.loop_rates(sim)
    settings = scenario.scheme_settings(rates)
    _, held = design_split(records)
    diagnoser = arm_schemes(model, settings, cal.theta0, ["consistency"], designs=cal.designs)["consistency"]
    residuals = [diagnose_record(records[k], Diagnosis(diagnoser), rates).residual for k in held]
    return cal, residuals, diagnoser.components, settings, startup_samples(settings.T, scenario.startup_blanking)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", required=True)
    ap.add_argument("--speed", type=mission_speed, default="fast", help="as benchmarks/arm_acceptance.py")
    ap.add_argument("--drive-inertia", default="auto", help='as in arm_acceptance.py: [s²] or "auto"')
    ap.add_argument("--seed", type=int, default=None, help="campaign seed (default: the TOML's)")
    ap.add_argument("--set", nargs="+", default=None, metavar="NAME=VALUE", help="more [system] fields")
    ap.add_argument("--csv", nargs="+", required=True, help="arm_equal_far.py's CSV of the same campaign, per robot")
    ap.add_argument("--rows", default="payload", choices=("payload", "dynamic", "kin", "step"))
    args = ap.parse_args()
    if len(args.csv) != len(args.robots):
        raise SystemExit(f"--csv: expected one CSV per robot ({len(args.robots)}), got {len(args.csv)}")
    from robofdi.campaign.spec import parse_spec

    for robot, csv in zip(args.robots, args.csv):
        table = pd.read_csv(csv)
        if args.rows != "payload" and not any(c.startswith("consistency:") for c in table.columns):
            raise SystemExit(f"--csv {csv}: no per-row columns (consistency:<component>) for the {args.rows} rows; "
                             f"re-run benchmarks/arm_equal_far.py, which writes them since 2026-12-07")
        spec = parse_spec(acceptance_spec(robot, args.speed, args.drive_inertia, args.seed, diagnosers=["consistency"],
                                          system=settings_option(args.set)))
        system = spec.campaign_system
        keys = system.calibration_keys(spec.options)
        old, new, components = [], [], None
        for key in keys:
            cal, residuals, components, settings, skip = held_out_residuals(system, spec.options, key)
            rows = [j for j, c in enumerate(components) if _row_set(c) == args.rows]
            threshold = np.asarray(cal.thresholds["consistency"])
            old.append(threshold[rows])
            fits = [levels(residuals, j, settings.T, skip, settings.consistency_false_alarm_rate) for j in rows]
            new.append({law: np.array([f[law] for f in fits]) for law in LAWS})
        names = [components[j] for j, c in enumerate(components) if _row_set(c) == args.rows]
        per_row = [f"consistency:{c}" for c in names]
        if not set(per_row) <= set(table.columns):
            per_row = [f"consistency[{args.rows}]"]          # the payload row: its set's column is the row
        instance = (table["index"] % len(keys)).to_numpy()
        stored = table[per_row].to_numpy()
        free = ~table["faulty"].to_numpy(bool)
        classes = sorted(c for c in table.get("class", pd.Series(dtype=str)).dropna().unique() if c)
        print(f"\n## {robot}, {args.speed}: the {args.rows} rows ({len(names)}), {len(keys)} robot instances, "
              f"{int(free.sum())} fault-free runs")
        for law in LAWS:
            scale = np.array([old[i] / new[i][law] for i in range(len(keys))])     # (instances, rows)
            ratio = (stored * scale[instance]).max(axis=1)
            span = np.array([new[i][law] / old[i] for i in range(len(keys))])
            line = (f"{law:12s} new/old threshold {span.min():.2f}–{span.max():.2f}   fault-free peak "
                    f"{ratio[free].max():.3f}, alarmed {int((ratio[free] > 1).sum())}/{int(free.sum())}")
            for c in classes:
                mask = (table["class"] == c).to_numpy()
                line += f"   {c} {int((ratio[mask] > 1).sum())}/{int(mask.sum())}"
            print(line)


if __name__ == "__main__":
    main()
