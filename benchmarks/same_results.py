"""Same seed, same result: run every experiment and a small campaign per system, then compare two such sets.

    python benchmarks/same_results.py collect OUT [--robofdi PATH] [--runs N] [--only NAME ...]
    python benchmarks/same_results.py compare BEFORE AFTER

``collect`` runs ``robofdi run NAME --seed 0 --quiet`` for every experiment ``robofdi list`` shows and
``robofdi campaign SPEC --runs N --workers 1`` for every shipped campaign spec, in a fresh calibration cache
(``OUT/cache``), and keeps each ``summary.json`` and each campaign's ``results.parquet`` (as CSV) under OUT.
``--robofdi`` chooses the console script, so a second virtual environment can hold the code before a change.

``compare`` prints every difference between the two sets: summary fields (wall times and paths ignored),
results-table cells, experiments or campaigns present on one side only. Exit code 1 when anything differs.
This is how a restructuring shows that it did not change results (Core 3's acceptance).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

#: summary / table fields that measure the machine, not the result
IGNORED = {"wall_time", "created", "elapsed", "calibration_seconds", "cached", "from_cache", "robofdi_version",
           "calibration_cached", "calibration_wall_time", "path", "run_dir", "execution"}


def _campaign_specs() -> list[str]:
    root = Path(__file__).resolve().parents[1] / "experiments" / "campaigns"
    return sorted(p.stem for p in root.glob("*.toml"))


def collect(out: Path, robofdi: str, runs: int, only: list[str]) -> int:
    out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "ROBOFDI_CACHE": str(out / "cache"), "MPLBACKEND": "Agg"}
    listing = subprocess.run([robofdi, "list"], capture_output=True, text=True, env=env, check=True).stdout
    experiments = [line.split()[0] for line in listing.split("\n\n")[0].splitlines() if line.strip()]   # not the systems
    jobs = [("run", e) for e in experiments] + [("campaign", c) for c in _campaign_specs()]
    if only:
        jobs = [j for j in jobs if j[1] in only]
    failed = 0
    log = (out / "collect.log").open("a")
    for what, name in jobs:
        dest = out / what / name
        shutil.rmtree(dest, ignore_errors=True)
        work = out / "work" / what / name
        shutil.rmtree(work, ignore_errors=True)
        if what == "run":
            cmd = [robofdi, "run", name, "--seed", "0", "--quiet", "--out", str(work)]
        else:
            cmd = [robofdi, "campaign", name, "--runs", str(runs), "--workers", "1", "--quiet", "--out", str(work)]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        print(f"{what} {name}: rc={proc.returncode} in {wall:.0f} s", flush=True)
        log.write(f"$ {' '.join(cmd)}\nrc={proc.returncode} {wall:.1f} s\n{proc.stdout}\n{proc.stderr}\n")
        log.flush()
        dest.mkdir(parents=True)
        (dest / "stdout.txt").write_text(proc.stdout)
        if proc.returncode != 0:
            failed += 1
            (dest / "stderr.txt").write_text(proc.stderr)
            continue
        if what == "run":
            for summary in sorted(work.rglob("summary.json")):
                rel = summary.relative_to(work)
                (dest / str(rel).replace(os.sep, "__")).write_text(summary.read_text())
        else:
            import pandas as pd

            pd.read_parquet(work / "results.parquet").to_csv(dest / "results.csv", index=False)
            shutil.copy(work / "campaign.json", dest / "campaign.json")
    shutil.rmtree(out / "work", ignore_errors=True)
    return 1 if failed else 0


def _diff(a, b, where: str, out: list[str], rtol: float) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if k in IGNORED:
                continue
            if k not in a or k not in b:
                out.append(f"{where}.{k}: only {'after' if k in b else 'before'}")
            else:
                _diff(a[k], b[k], f"{where}.{k}", out, rtol)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{where}: length {len(a)} -> {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            _diff(x, y, f"{where}[{i}]", out, rtol)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if not (a == b or (math.isnan(a) and math.isnan(b)) or abs(a - b) <= rtol * max(abs(a), abs(b))):
            out.append(f"{where}: {a!r} -> {b!r}")
    elif a != b:
        out.append(f"{where}: {a!r} -> {b!r}")


def compare(before: Path, after: Path, rtol: float = 0.0) -> int:
    import pandas as pd

    differences: list[str] = []
    names = sorted({p.relative_to(before).as_posix() for p in before.glob("*/*/*") if p.suffix in (".json", ".csv")}
                   | {p.relative_to(after).as_posix() for p in after.glob("*/*/*") if p.suffix in (".json", ".csv")})
    for name in names:
        a, b = before / name, after / name
        if not a.is_file() or not b.is_file():
            differences.append(f"{name}: only {'after' if b.is_file() else 'before'}")
            continue
        if a.suffix == ".json":
            _diff(json.loads(a.read_text()), json.loads(b.read_text()), name, differences, rtol)
        else:
            ta, tb = pd.read_csv(a), pd.read_csv(b)
            ta, tb = ta.drop(columns=[c for c in ta if c in IGNORED]), tb.drop(columns=[c for c in tb if c in IGNORED])
            _diff(ta.to_dict("records"), tb.to_dict("records"), name, differences, rtol)
    for line in differences:
        print(line)
    print(f"{len(names)} files compared, {len(differences)} differences")
    return 1 if differences else 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("collect")
    c.add_argument("out", type=Path)
    c.add_argument("--robofdi", default=shutil.which("robofdi") or "robofdi")
    c.add_argument("--runs", type=int, default=6, help="runs per campaign (a prefix: fault-free and faulty mixed)")
    c.add_argument("--only", nargs="*", default=[], help="experiment or campaign names")
    d = sub.add_parser("compare")
    d.add_argument("before", type=Path)
    d.add_argument("after", type=Path)
    d.add_argument("--rtol", type=float, default=0.0, help="relative tolerance on numbers (default: exact)")
    args = p.parse_args(argv)
    if args.command == "collect":
        return collect(args.out, args.robofdi, args.runs, args.only)
    return compare(args.before, args.after, args.rtol)


if __name__ == "__main__":
    sys.exit(main())
