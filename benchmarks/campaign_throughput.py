"""Campaign throughput: runs per minute of the shipped arm campaign (experiments/campaigns/arm.toml) in this
process (--workers 1), on a 2-process local pool, and on a Dask cluster of two worker processes on 127.0.0.1; the
scaling ratio (rate / (workers × rate of 1 worker), goal ≥ 0.9 on idle cores); the calibration cost per campaign
with an empty cache and with the cache; and whether the three result tables are identical (wall time aside).

    python benchmarks/campaign_throughput.py [--runs 200] [--spec arm] [--out /tmp/campaign-bench]

Runs per minute count the run phase only (after calibration; the pool's workers are started by then). The numbers
depend on the machine and on what else runs on it: on shared cores the scaling ratio says little.
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=200)
    p.add_argument("--spec", default="arm", help="a spec file or shipped spec name (default: arm)")
    p.add_argument("--out", default=None, help="folder for the campaign folders (default: a temporary one)")
    args = p.parse_args(argv)

    from dask.distributed import LocalCluster

    from robofdi.campaign import load_spec

    spec = load_spec(args.spec)
    root = Path(args.out or tempfile.mkdtemp(prefix="campaign-bench-"))
    cache = root / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    os.environ["ROBOFDI_CACHE"] = str(cache)          # an empty cache: the first campaign calibrates

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
    return 0 if all(same.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
