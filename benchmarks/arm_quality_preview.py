"""A first measurement of arm diagnosis quality before the campaign engine: one calibration per robot, then
N fault-free and N faulty online runs on random two-segment motions (each run with its own noise streams),
one random fault per faulty run. Prints, per diagnoser, fault-free runs with an alarm and detection /
correct isolation per fault class. The README's "First measurement" table comes from

    python benchmarks/arm_quality_preview.py arm6.xml 30
    python benchmarks/arm_quality_preview.py arm7.xml 30

(about 3 minutes each on 2 cores). The campaign engine (`robofdi campaign`) supersedes it.
"""
from __future__ import annotations

import argparse
import collections
import time
from dataclasses import replace

import numpy as np

from robofdi.control import MotionLimits, random_point_to_point
from robofdi.evaluate import summarize
from robofdi.faults import Fault
from robofdi.faults.profiles import ExponentialRise
from robofdi.systems.arm import arm_scenario, calibration, run_scenario


def draw_fault(g: np.random.Generator, names, torque_limit, end: float) -> tuple[str, Fault]:
    kind = str(g.choice(["step", "incipient", "encoder_bias", "encoder_drift", "velocity_bias"]))
    j = int(g.integers(len(names)))
    onset = round(float(g.uniform(0.3, 0.7) * end), 3)
    lim = float(torque_limit[j])
    if kind == "step":
        return kind, Fault("f", "actuator_additive", names[j], onset=onset, magnitude=round(g.uniform(0.03, 0.2) * lim, 2))
    if kind == "incipient":
        return kind, Fault("f", "actuator_additive", names[j], onset=onset, magnitude=round(g.uniform(0.05, 0.2) * lim, 2),
                           profile=ExponentialRise(0.3))
    if kind == "encoder_bias":
        return kind, Fault("f", "sensor_bias", f"{names[j]}_pos", onset=onset, magnitude=round(g.uniform(2e-4, 5e-3), 5))
    if kind == "encoder_drift":
        return kind, Fault("f", "sensor_drift", f"{names[j]}_pos", onset=onset, magnitude=round(g.uniform(2e-3, 1e-2), 5))
    return kind, Fault("f", "sensor_bias", f"{names[j]}_vel", onset=onset, magnitude=round(g.uniform(5e-3, 5e-2), 4))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("robot")
    ap.add_argument("runs", type=int, help="fault-free runs (and as many faulty ones)")
    args = ap.parse_args()
    base = arm_scenario(args.robot, faults=["actuator_additive:joint1:0@0.5"], seed=0)
    sim = base.simulator()
    model = sim.nominal_model()
    limits = MotionLimits.from_ranges(sim.joint_range[:, 0], sim.joint_range[:, 1], model.torque_limit)
    t0 = time.time()
    cal, _ = calibration(base)
    print(f"calibration {time.time() - t0:.0f} s")
    fa = collections.Counter()
    stats = collections.defaultdict(lambda: [0, 0, 0])          # (scheme, class) -> runs, detected, correct
    delays = collections.defaultdict(list)
    for i in range(2 * args.runs):
        motion = random_point_to_point(model, limits, 5000 + i, n_segments=2)
        kind, fault = (None, None) if i % 2 == 0 else draw_fault(np.random.default_rng(10000 + i), sim.joint_names,
                                                                 model.torque_limit, motion.end)
        faults = () if fault is None else (fault,)
        sc = replace(base, motion=motion, faults=faults, duration=motion.end + 0.5, name=f"preview{i}")
        summary = summarize(run_scenario(sc, cal, run_key=f"run{i}"), "preview", faults=[f.to_dict() for f in faults])
        for scheme, result in summary["diagnosers"].items():
            if fault is None:
                fa[scheme] += result["false_alarms"] > 0
                continue
            det = result["detections"][0]
            st = stats[scheme, kind]
            st[0] += 1
            st[1] += det["time"] is not None
            st[2] += det["isolated"] == fault.target
            if kind == "step" and det["time"] is not None:
                delays[scheme].append(det["delay"])
        print(f"run {i + 1}/{2 * args.runs} ({time.time() - t0:.0f} s)", end="\r", flush=True)
    print()
    for scheme in summary["diagnosers"]:
        classes = sorted(k for s, k in stats if s == scheme)
        cells = "  ".join(f"{k} {stats[scheme, k][1]}/{stats[scheme, k][0]} ({stats[scheme, k][2]} correct)" for k in classes)
        med = f"{1e3 * np.median(delays[scheme]):.0f} ms" if delays[scheme] else "-"
        print(f"{scheme:14s} false-alarm runs {fa[scheme]}/{args.runs}  step delay median {med}  {cells}")


if __name__ == "__main__":
    main()
