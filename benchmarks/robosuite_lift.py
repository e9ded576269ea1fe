"""robosuite Lift (Panda, OSC_POSE, scripted grasp): false alarms, what contacts do to the residuals, detection and
task success without vs with compensation — the robosuite figures of docs/systems/robosuite.md.

    python benchmarks/robosuite_lift.py [--fault-free 50] [--faulty 20] [--out runs/robosuite-lift-benchmark.json]

1. Calibration: the experiment's (30 fault-free episodes, seeds 1000–1029; cached, timed when computed).
2. Held-out fault-free episodes (seeds 0 … N−1; 7 s, every one with approach, grasp, lift and hold): false-alarm
   episodes per episode for each diagnoser (alarm episodes starting while no fault is active), task success, and
   max |r_j| / threshold_j per scripted phase — approach (free motion) against descend / grasp (fingers and cube on
   the table) and lift / hold (carrying the cube).
3. Faulty episodes (seeds 100 … 100+M−1): ``actuator_loss_of_effectiveness:joint2:0.6@1.0`` without and with the
   effectiveness compensation (health from ``momentum``): success rate, detection delay, isolated joint, false
   alarms, the identified loss k̂ at the end of the compensated episode.
Also the wall time per 7 s episode (both diagnosers at every 2 ms substep) against robosuite alone.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from robofdi.adapters import robosuite_diagnosis as rd
from robofdi.evaluate import summarize

FAULT = "actuator_loss_of_effectiveness:joint2:0.6@1.0"
GROUPS = {"approach": ("approach",), "descend+grasp": ("descend", "grasp"), "lift+hold": ("lift", "hold")}


def phase_ratios(ep, record, name: str) -> dict:
    """max |r_j| / threshold_j over the samples of each phase group (after the start-up blanking)."""
    trace = record.diagnosers[name]
    k = np.clip(np.searchsorted(ep.step_times, trace.time, side="right") - 1, 0, len(ep.phases) - 1)
    phase = np.array(ep.phases)[k]
    keep = trace.time >= rd.BLANKING
    out = {}
    for group, phases in GROUPS.items():
        m = keep & np.isin(phase, phases)
        out[group] = (np.abs(trace.residual[m]).max(axis=0) / trace.threshold).tolist() if m.any() else None
    return out


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--fault-free", type=int, default=50)
    p.add_argument("--faulty", type=int, default=20)
    p.add_argument("--out", default="runs/robosuite-lift-benchmark.json")
    args = p.parse_args(argv)

    t0 = time.perf_counter()
    cal, cached = rd.lift_calibration(rd.CALIBRATION_SEEDS)
    cal_time = time.perf_counter() - t0
    env = rd.make_lift()
    names = list(cal.thresholds)
    result = {"calibration": {"episodes": len(cal.seeds), "successes": cal.success, "cached": cached,
                              "wall_time_s": None if cached else cal_time, "thresholds_Nm": cal.thresholds}}

    # robosuite alone: one scripted 7 s episode without the wrapper, for the cost ratio
    t0 = time.perf_counter()
    obs = env.reset()
    script = rd.LiftScript(0)
    for _ in range(rd.EPISODE_STEPS):
        obs, *_ = env.step(script(obs, 1.0 / env.control_freq))
    raw_time = time.perf_counter() - t0

    fa = {n: [] for n in names}
    ratios = {n: {g: [] for g in GROUPS} for n in names}
    success, walls = [], []
    for seed in range(args.fault_free):
        t0 = time.perf_counter()
        ep, record = rd.run_lift(cal, [], seed, env=env)
        walls.append(time.perf_counter() - t0)
        success.append(ep.success)
        s = summarize(record, "robosuite-lift", [])
        for n in names:
            fa[n].append(s["diagnosers"][n]["false_alarms"])
            for g, v in phase_ratios(ep, record, n).items():
                if v is not None:
                    ratios[n][g].append(v)
        print(f"fault-free {seed}: success {ep.success}, false alarms {[fa[n][-1] for n in names]}", flush=True)
    result["fault_free"] = {
        "episodes": args.fault_free, "successes": int(sum(success)),
        "false_alarms": {n: {"total": int(sum(v)), "episodes_with_alarm": int(sum(x > 0 for x in v)),
                             "per_episode": float(np.mean(v))} for n, v in fa.items()},
        "max_residual_over_threshold": {n: {g: {"max": np.max(v, axis=0).round(3).tolist(),
                                                "median": np.median(v, axis=0).round(3).tolist()}
                                            for g, v in groups.items() if v} for n, groups in ratios.items()},
        "wall_time_per_episode_s": float(np.median(walls)), "robosuite_alone_per_episode_s": raw_time,
    }

    faulty = {}
    for variant, acc in (("none", False), ("compensation", True)):
        rows = []
        for seed in range(100, 100 + args.faulty):
            ep, record = rd.run_lift(cal, [FAULT], seed, accommodation=acc, env=env)
            s = summarize(record, "robosuite-lift")
            diag = {n: s["diagnosers"][n] for n in names}
            rows.append({"seed": seed, "success": ep.success, "max_cube_height": float(ep.cube_height.max()),
                         "detections": {n: d["detections"][0] for n, d in diag.items()},
                         "false_alarms": {n: d["false_alarms"] for n, d in diag.items()},
                         "identified_loss": record.meta["identified_loss"]})
            print(f"{variant} {seed}: success {ep.success}, "
                  f"{[(n, r['isolated'], r['delay']) for n, r in rows[-1]['detections'].items()]}", flush=True)
        per = {"episodes": len(rows), "successes": int(sum(r["success"] for r in rows))}
        for n in names:
            delays = [r["detections"][n]["delay"] for r in rows if r["detections"][n]["delay"] is not None]
            isolated = [r["detections"][n]["isolated"] for r in rows]
            per[n] = {"detected": len(delays), "delay_ms_median": 1e3 * float(np.median(delays)) if delays else None,
                      "delay_ms_max": 1e3 * float(np.max(delays)) if delays else None,
                      "isolated": {str(k): isolated.count(k) for k in set(isolated)},
                      "false_alarms": int(sum(r["false_alarms"][n] for r in rows))}
        if acc:
            k = [r["identified_loss"]["momentum"].get("joint2", np.nan) for r in rows]
            per["identified_loss_joint2"] = {"median": float(np.nanmedian(k)), "min": float(np.nanmin(k)),
                                             "max": float(np.nanmax(k)),
                                             "other_joints_compensated": int(sum(len(r["identified_loss"]["momentum"]) > 1
                                                                                 for r in rows))}
        per["runs"] = rows
        faulty[variant] = per
    result["faulty"] = {"fault": FAULT, **faulty}
    env.close()

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1, default=float))
    summary = {k: v for k, v in result["fault_free"].items()}
    print(json.dumps(result["calibration"], default=float))
    print(json.dumps(summary, indent=1, default=float))
    for variant in ("none", "compensation"):
        print(variant, json.dumps({k: v for k, v in faulty[variant].items() if k != "runs"}, default=float))
    return result


if __name__ == "__main__":
    main()
