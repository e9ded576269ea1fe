"""Soak test: one fault-free arm run of M simulated minutes with every arm diagnoser, memory and false alarms.

    PYTHONPATH=. python benchmarks/arm_soak.py --minutes 10 [--seed 0] [--out DIR]

The shipped arm6 with the honest harness (ripple harmonics, Stribeck friction, encoder quantisation, velocity
noise), every arm scheme (:data:`robofdi.observers.arm_schemes.SCHEMES`) with its calibrated threshold decision
(the calibration of ``arm_scenario(seed)``, cached), on a seeded random point-to-point motion
(:func:`robofdi.control.random_point_to_point`, "normal" speed, 0.25 s rests) long enough to fill the run. The
record is streamed to ``DIR/record.h5`` chunk by chunk (:meth:`robofdi.loop.ClosedLoop.run_to_file`), so memory
does not grow with the run; the alarms are then read back from the file in slices.

Printed per diagnoser: false-alarm episodes (rising edges of the any-component alarm; the run has no fault, so
every one is false), the first one (time, the components, |r|/threshold), what is isolated at the end, and the
normalised RMS of the residual (|r_j| / threshold_j, RMS over components) in the first and the last simulated
minute (residual drift). The last two lines are ``peak_rss_mb: X`` (the process's peak resident set,
calibration included) and ``false_alarm_episodes: N`` (summed over the diagnosers).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from robofdi.config import compose
from robofdi.control import MotionLimits, random_point_to_point
from robofdi.observers.arm_schemes import SCHEMES
from robofdi.sims import ArmSimulator
from robofdi.systems.arm import ArmScenario, build_loop, calibration

SLICE = 50_000            # diagnosis samples read from the file at a time


def soak_scenario(minutes: float, seed: int) -> ArmScenario:
    """The fault-free scenario: arm6, every scheme, a random motion of at least ``minutes`` of simulated time."""
    duration = 60.0 * minutes
    sim = ArmSimulator("arm6.xml", seed=seed)
    model = sim.nominal_model()
    limits = MotionLimits.from_ranges(sim.joint_range[:, 0], sim.joint_range[:, 1], model.torque_limit)
    probe = random_point_to_point(model, limits, seed, 20)
    segments = int(math.ceil(1.1 * duration / (probe.end / 20))) + 5
    motion = random_point_to_point(model, limits, seed, segments)
    return compose(ArmScenario, name=f"soak-{minutes:g}min", motion=motion, duration=duration, faults=(),
                   robot="arm6.xml", joints=tuple(sim.joint_names), seed=seed, schemes=SCHEMES)


def alarm_report(path: Path, name: str, diagnosis_hz: float) -> dict:
    """False-alarm episodes of one diagnoser, read from the record in slices (memory: one slice)."""
    with h5py.File(path, "r") as f:
        g = f[f"diagnosers/{name}"]
        t_ds, a_ds, r_ds, iso_ds = g["time"], g["alarm"], g["residual"], g["isolated"]
        threshold = g["threshold"][()]
        components = json.loads(g.attrs["components"])
        n = t_ds.shape[0]
        minute = int(round(60.0 * diagnosis_hz))
        episodes, first, previous = 0, None, False
        for k0 in range(0, n, SLICE):
            alarm = a_ds[k0:k0 + SLICE]
            any_alarm = alarm.any(axis=1)
            rises = np.flatnonzero(any_alarm & ~np.concatenate([[previous], any_alarm[:-1]]))
            episodes += rises.size
            if first is None and rises.size:
                k = k0 + int(rises[0])
                ratio = np.abs(r_ds[k]) / threshold
                first = {"time": float(t_ds[k]), "components": [c for c, a in zip(components, a_ds[k]) if a],
                         "ratio": float(ratio.max())}
            if any_alarm.size:
                previous = bool(any_alarm[-1])

        def nrms(k0, k1):
            r = r_ds[k0:k1] / threshold
            return float(np.sqrt(np.mean(r ** 2))) if r.size else float("nan")

        last = iso_ds[n - 1] if n else b""
        return {"episodes": episodes, "first": first, "isolated_at_end": last.decode() if isinstance(last, bytes)
                else str(last), "nrms_first_minute": nrms(0, min(minute, n)),
                "nrms_last_minute": nrms(max(0, n - minute), n), "samples": n}


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0          # KiB on Linux


def _rss_mb() -> float:
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:
        return float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="simulated minutes (default 10)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", help="keep the record in this folder (default: a temporary one, removed)")
    args = ap.parse_args(argv)
    if not (math.isfinite(args.minutes) and args.minutes > 0):
        print("arm_soak: --minutes must be > 0", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    sc = soak_scenario(args.minutes, args.seed)
    cal, cached = calibration(sc)
    t_cal = time.perf_counter() - t0
    loop = build_loop(sc, cal)
    tmp = None
    if args.out:
        out = Path(args.out)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="robofdi-soak-")
        out = Path(tmp.name)
    print(f"calibration {'from the cache' if cached else 'computed'}; peak {_peak_mb():.0f} MB before the run",
          flush=True)
    t1 = time.perf_counter()
    c1 = time.process_time()
    ticks_per_minute = int(round(60.0 * loop.rates.control_hz))
    done = [0]

    def progress(k: int) -> None:       # the resident set every simulated minute: flat when memory is bounded
        done[0] += k
        if done[0] % ticks_per_minute == 0:
            print(f"  t = {done[0] / loop.rates.control_hz:6.0f} s simulated, {time.perf_counter() - t1:6.0f} s wall: "
                  f"rss {_rss_mb():.0f} MB, peak {_peak_mb():.0f} MB", flush=True)

    path = loop.run_to_file(out / "record.h5", sc.run_duration, sc.start_pose, seed=sc.seed, scenario=sc.name,
                            progress=progress)
    wall, cpu = time.perf_counter() - t1, time.process_time() - c1
    ticks = int(round(sc.run_duration * loop.rates.control_hz)) + 1
    reports = {name: alarm_report(path, name, loop.rates.diagnosis_hz) for name in loop.diagnoses}
    size_mb = path.stat().st_size / 2**20
    peak = _peak_mb()

    print(__doc__.splitlines()[0])
    print(f"arm6, seed {sc.seed}, {sc.run_duration:g} s simulated ({ticks} control ticks, motion of "
          f"{len(sc.motion.segments)} segments), diagnosers: {', '.join(loop.diagnoses)}")
    print(f"calibration {'from the cache' if cached else 'computed'} in {t_cal:.0f} s; run {wall:.0f} s wall, "
          f"{cpu:.0f} s CPU ({cpu / ticks * 1e6:.0f} µs CPU per tick, RTF {sc.run_duration / wall:.2f}); "
          f"record {size_mb:.0f} MB; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print()
    print(f"{'diagnoser':<14} {'false alarms':>12}  {'first (t s, components, |r|/thr)':<44} "
          f"{'isolated at end':<18} {'nRMS 1st min':>12} {'nRMS last min':>13}")
    for name, r in reports.items():
        first = (f"{r['first']['time']:.3f}, {'+'.join(r['first']['components'])}, {r['first']['ratio']:.3f}"
                 if r["first"] else "-")
        print(f"{name:<14} {r['episodes']:>12}  {first:<44} {r['isolated_at_end'] or '-':<18} "
              f"{r['nrms_first_minute']:>12.3f} {r['nrms_last_minute']:>13.3f}")
    if tmp is not None:
        tmp.cleanup()
    print()
    print(f"peak_rss_mb: {peak:.0f}")
    print(f"false_alarm_episodes: {sum(r['episodes'] for r in reports.values())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
