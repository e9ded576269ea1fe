"""Campaign throughput: runs per minute of the shipped arm campaign (experiments/campaigns/arm.toml) in this
process (--workers 1), on a 2-process local pool, and on a Dask cluster of two worker processes on 127.0.0.1; the
scaling ratio (rate / (workers × rate of 1 worker), goal ≥ 0.9 on idle cores); the calibration cost per campaign
with an empty cache and with the cache; and whether the three result tables are identical (wall time aside).

    python benchmarks/campaign_throughput.py [--runs 200] [--spec arm] [--out /tmp/campaign-bench]

Runs per minute count the run phase only (after calibration; the pool's workers are started by then). The numbers
depend on the machine and on what else runs on it: on shared cores the scaling ratio says little.

The last line, ``campaign/floor ratio: R``, is the CPU time (this process's, ``time.process_time``) per run·tick of a
one-worker campaign of ``--ratio-runs`` runs (the whole ``run_campaign``: the calibration read from the cache, filled
first, the runs — in lockstep batches as ``robofdi campaign`` runs them, or ``--batch N`` runs per batch, 1 = each
alone — then the analysis, figures and report; ticks = each run's duration × the robot's control rate) over
the raw floor of one control tick measured in the same process: 2 × mujoco.mj_step + Pinocchio rnea + aba on the
robot (as benchmarks/arm_loop.py). The line before it splits that CPU into the outputs (written again on the
finished folder and timed: a cost per campaign, not per run) and the rest. ``--ratio-only`` measures only that (the
cache of the folder is filled first).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path


def _campaign(spec, out: Path, runs: int, **backend) -> tuple[dict, object]:
    from robofdi.campaign import run_campaign

    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    result = run_campaign(spec, out, runs=runs, progress=False, **backend)
    total = time.perf_counter() - start
    execution = json.loads((out / "campaign.json").read_text())["execution"]
    execution["total_wall_time"] = total
    return execution, result


def floor_us(robot: str = "arm6.xml", number: int = 2000, repeats: int = 7) -> float:
    """CPU µs of 2 × mj_step + rnea + aba on ``robot`` (the median of ``repeats``), from states of a resting arm
    with random torques (mj_step) and random configurations (Pinocchio)."""
    import statistics

    import mujoco
    import numpy as np
    import pinocchio as pin

    import robofdi
    from robofdi.models.manipulator import ManipulatorModel

    m = mujoco.MjModel.from_xml_path(str(robofdi.ASSETS / robot))
    d = mujoco.MjData(m)
    nominal = ManipulatorModel(robofdi.ASSETS / robot)
    pm, pd = nominal.model, nominal.data
    rng = np.random.default_rng(0)
    qs = [pin.randomConfiguration(pm) for _ in range(64)]
    vs = [rng.standard_normal(pm.nv) for _ in range(64)]
    ts = [rng.standard_normal(pm.nv) * 20 for _ in range(64)]

    def per_call(fn) -> float:
        samples = []
        for rep in range(repeats + 1):
            t0 = time.process_time()
            for i in range(number):
                fn(i)
            if rep:
                samples.append((time.process_time() - t0) / number * 1e6)
        return statistics.median(samples)

    def step(i):
        if i % 200 == 0:
            mujoco.mj_resetData(m, d)
            d.ctrl[:] = rng.uniform(-1, 1, m.nu) * 10
        mujoco.mj_step(m, d)

    return (2 * per_call(step) + per_call(lambda i: pin.rnea(pm, pd, qs[i % 64], vs[i % 64], ts[i % 64]))
            + per_call(lambda i: pin.aba(pm, pd, qs[i % 64], vs[i % 64], ts[i % 64])))


def outputs_us(out: Path, ticks: float) -> float:
    """CPU µs per run·tick of a finished campaign folder's outputs (results.parquet, the analysis, campaign.json,
    figures, report.md), written again by :func:`robofdi.campaign.results.write_outputs`: the part of the campaign's
    CPU that does not grow with the runs (its share falls as a campaign gets longer)."""
    from robofdi.campaign.results import load, write_outputs

    result = load(out)
    execution = json.loads((out / "campaign.json").read_text())["execution"]
    start = time.process_time()
    write_outputs(result, execution)
    return (time.process_time() - start) / ticks * 1e6


def campaign_floor_ratio(spec, root: Path, runs: int, batch: int | None = None) -> tuple[float, float, float]:
    """(CPU µs per run·tick of a one-worker campaign of ``runs`` runs, the floor [µs], their ratio); the
    calibration must be cached already (ROBOFDI_CACHE). Also prints the outputs' part (:func:`outputs_us`)."""
    from robofdi.sims import ArmSimulator

    plant = getattr(spec.options, "plant", None)
    robot = str(getattr(plant, "robot", "arm6.xml"))
    control_hz = 1.0 / (plant.simulator(0).control_dt if plant is not None else ArmSimulator(robot).control_dt)
    out = root / "ratio"
    shutil.rmtree(out, ignore_errors=True)
    from robofdi.campaign import run_campaign

    start = time.process_time()
    result = run_campaign(spec, out, runs=runs, workers=1, progress=False, batch=batch)
    cpu = time.process_time() - start
    ticks = float((result.table.groupby("index")["duration"].first() * control_hz).round().sum())
    per_tick = cpu / ticks * 1e6
    floor = floor_us(robot)
    outputs = outputs_us(out, ticks)
    print(f"of which the outputs (analysis, figures, report; written again): {outputs:.1f} µs per run·tick; the runs "
          f"(calibration from the cache, missions, loops, rows): {per_tick - outputs:.1f} µs, "
          f"{(per_tick - outputs) / floor:.2f} × the floor")
    return per_tick, floor, per_tick / floor


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=200)
    p.add_argument("--spec", default="arm", help="a spec file or shipped spec name (default: arm)")
    p.add_argument("--out", default=None, help="folder for the campaign folders (default: a temporary one)")
    p.add_argument("--ratio-runs", type=int, default=20, help="runs of the campaign/floor measurement (default 20)")
    p.add_argument("--ratio-only", action="store_true", help="measure only the campaign/floor ratio")
    p.add_argument("--batch", type=int, default=None,
                   help="runs per lockstep batch of the campaign/floor measurement (default: robofdi's; 1: each alone)")
    args = p.parse_args(argv)

    from dask.distributed import LocalCluster

    from robofdi.campaign import load_spec

    spec = load_spec(args.spec)
    root = Path(args.out or tempfile.mkdtemp(prefix="campaign-bench-"))
    cache = root / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    os.environ["ROBOFDI_CACHE"] = str(cache)          # an empty cache: the first campaign calibrates

    if args.ratio_only:
        from robofdi.campaign import run_campaign

        shutil.rmtree(root / "fill-cache", ignore_errors=True)
        run_campaign(spec, root / "fill-cache", runs=1, workers=1, progress=False)     # calibrates into the cache
        per_tick, floor, ratio = campaign_floor_ratio(spec, root, args.ratio_runs, args.batch)
        print(f"campaign {spec.source or spec.system}: {args.ratio_runs} runs, one worker, batch "
              f"{args.batch or 'automatic'}: {per_tick:.1f} µs CPU per "
              f"run·tick, floor {floor:.2f} µs; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        print(f"campaign/floor ratio: {ratio:.2f}")
        return 0

    rows, tables = [], {}
    cold, tables["workers=1"] = _campaign(spec, root / "w1", args.runs, workers=1)
    rows.append(("this process (--workers 1)", 1, cold))
    warm, tables["workers=2"] = _campaign(spec, root / "w2", args.runs, workers=2)
    rows.append(("local pool (--workers 2)", 2, warm))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None) as cl:
        dask, tables["dask"] = _campaign(spec, root / "dask", args.runs, scheduler=cl.scheduler_address)
    rows.append(("Dask, 2 workers on 127.0.0.1", 2, dask))

    base = cold["runs_per_minute"]
    print(f"campaign {spec.source or spec.system}: {args.runs} runs, {os.cpu_count()} cores visible")
    print("| backend | workers | runs/min | scaling ratio | run phase [s] | total [s] |")
    print("|---|---|---|---|---|---|")
    for name, workers, ex in rows:
        ratio = ex["runs_per_minute"] / (workers * base)
        print(f"| {name} | {workers} | {ex['runs_per_minute']:.1f} | {ratio:.2f} | {ex['run_phase_wall_time']:.1f} | "
              f"{ex['total_wall_time']:.1f} |")
    print(f"\ncalibration per campaign: {cold['calibration']['wall_time']:.2f} s with an empty cache, "
          f"{warm['calibration']['wall_time']:.2f} s from the cache (local pool), "
          f"{dask['calibration']['wall_time']:.2f} s (Dask)")
    ref = tables["workers=1"].table.drop(columns="wall_time")
    same = {k: ref.equals(v.table.drop(columns="wall_time")) for k, v in tables.items()}
    print(f"identical result tables (wall time aside): {same}")
    print(f"campaign folders: {root}")
    per_tick, floor, ratio = campaign_floor_ratio(spec, root, args.ratio_runs, args.batch)
    print(f"one worker, {args.ratio_runs} runs, batch {args.batch or 'automatic'}: {per_tick:.1f} µs CPU per run·tick, "
          f"floor {floor:.2f} µs; load average "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print(f"campaign/floor ratio: {ratio:.2f}")
    return 0 if all(same.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
