"""Book chapter 3 — Caccavale & Villani, "Fault Diagnosis for Industrial Robots" (in Caccavale & Villani eds.,
Fault Diagnosis and Fault Tolerance for Mechatronic Systems, Springer STAR 1, 2003), Sec. 7.

A 6R industrial arm of the SMART-3 S class moves q₀ → q₀ + Δq in 4 s (quintic) under joint-space inverse
dynamics control at 1 kHz; the diagnosers run at 500 Hz with K₁ = K₂ = 0.1 I₆, Γ_η and Q = 2Γ_η⁻¹ as printed.
The book's faults, emulated as the book did (offline: added to the recorded torque / position):

    ch3-actuator   δτ₃ = 60 (1 − e^{−(t−1)/0.002}),  δτ₅ = 40 (1 − e^{−(t−3)/0.08})   N·m
    ch3-sensor     δx₁,₃ = 0.006 (…),                δx₁,₅ = 0.004 (…)                  rad

Thresholds are calibrated on fault-free low-velocity and high-acceleration runs (the book's worst-case rule),
not copied from the book. Writes record.h5, summary.json, figures and replay.html into the run folder.

    python experiments/ch3_industrial_robot.py ch3-actuator --out runs --seed 0
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from robofdi.config import accepted, compose
from robofdi.control import Quintic, Sequence
from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.evaluate.headline import run_report
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, write_run_folder
from robofdi.faults import ExponentialRise, Fault
from robofdi.loop import Rates
from robofdi.progress import Progress, run_ticks
from robofdi.systems.arm import ArmScenario, calibration, calibration_steps, check_scenario, run_scenario

Q0 = (np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0)
DQ = (np.pi / 4, np.pi / 4, -np.pi / 4, 0.0, -np.pi / 2, np.pi / 2)
BOOK_THRESHOLDS = [3e-5, 2e-5, 4e-5, 2e-5, 1e-4, 2e-4, 3e-3, 2e-3, 2.5e-3, 1e-3, 5e-3, 1e-2]

FAULTS = {
    "ch3-actuator": (
        Fault("tau3", "actuator_additive", "joint3", onset=1.0, magnitude=60.0, profile=ExponentialRise(0.002)),
        Fault("tau5", "actuator_additive", "joint5", onset=3.0, magnitude=40.0, profile=ExponentialRise(0.08)),
    ),
    "ch3-sensor": (
        Fault("x3", "sensor_bias", "joint3_pos", onset=1.0, magnitude=0.006, profile=ExponentialRise(0.002)),
        Fault("x5", "sensor_bias", "joint5_pos", onset=3.0, magnitude=0.004, profile=ExponentialRise(0.08)),
    ),
}
EXPERIMENTS = {
    "ch3-actuator": "Book ch. 3, actuator faults δτ₃ (abrupt) and δτ₅ (incipient) on a 6R arm; 5 schemes + momentum baseline",
    "ch3-sensor": "Book ch. 3, position-sensor faults δx₁,₃ (abrupt) and δx₁,₅ (incipient); same schemes",
}
BOOK_SCHEMES = ("time_delayed", "recursive", "adaptive")


def book_calibration(q0=Q0, dq=DQ, slow: float = 20.0) -> dict[str, Sequence]:
    """The book's worst-case fault-free runs around the start pose (Sec. 6): low velocity q₀ → q₀ + Δq/4 and
    back, ``slow`` s each way; high acceleration q₀ → q₀ + [−π/2, π/4, −π/3, π/2, −π/2, 0.9π] and back, 1.5 s
    each. The book trajectory itself is not among them: the fault-free run then tests the thresholds."""
    q0 = np.asarray(q0)
    wide = np.array([-np.pi / 2, np.pi / 4, -np.pi / 3, np.pi / 2, -np.pi / 2, 0.9 * np.pi])
    return {
        "low_velocity": Sequence.through([q0, q0 + 0.25 * np.asarray(dq), q0], [slow, slow]),
        "high_acceleration": Sequence.through([q0, q0 + wide, q0], [1.5, 1.5]),
    }


def scenario(name: str, seed: int = 0, calibration_low_velocity_time: float = 20.0, **overrides) -> ArmScenario:
    """The book's scenario ``name`` ("ch3-actuator" or "ch3-sensor"); keyword overrides go to ArmScenario and
    are checked at once (unknown fields, invalid values, fault targets)."""
    if name not in FAULTS:
        raise RobofdiError(f"unknown experiment {name!r}; expected one of {sorted(FAULTS)}")
    fields = {k for k, path in accepted(ArmScenario).items() if path} - {"name"}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise RobofdiError(f"{name}: unknown override(s) {', '.join(unknown)}; "
                           f"expected fields of ArmScenario or its parts: {', '.join(sorted(fields))}")
    base = dict(motion=Quintic(Q0, DQ, 4.0), duration=4.0, faults=FAULTS[name], injection="offline", seed=seed,
                rates=Rates(1000.0, 500.0), calibration=book_calibration(slow=calibration_low_velocity_time))
    base.update(overrides)
    sc = compose(ArmScenario, base, name=name)
    check_scenario(sc)
    return sc


def _fault_free_rms(record, name: str) -> float:
    """RMS over time and torque/velocity rows of a fault-free residual normalised by its thresholds, after 2 s."""
    tr = record.diagnosers[name]
    n = len(tr.components) // 2
    keep = tr.time >= 2.0
    return float(np.sqrt(np.mean((tr.residual[keep, n:] / tr.threshold[n:]) ** 2)))


def _peak_ratio(record, name: str, fault: dict) -> float:
    """Largest residual-to-threshold ratio on the faulty joint's torque component within 0.3 s of onset."""
    tr = record.diagnosers[name]
    comp = tr.components.index(fault["target"]) if fault["target"] in tr.components else None
    if comp is None:
        return float("nan")
    win = (tr.time >= fault["onset"]) & (tr.time < fault["onset"] + 0.3)
    return float(np.max(np.abs(tr.residual[win, comp]) / tr.threshold[comp]))


def torque_space_isolation(record, fault_free, fault: dict, scheme: str = "time_delayed", window: float = 0.3) -> dict:
    """Digest check 6 (isolation in torque space, r_τ = (M̂/T) r₂): per joint, the peak |r_τ| [N·m] of ``scheme`` over
    ``window`` s from the fault onset, in the faulty run and in the fault's own contribution (faulty − fault-free:
    offline injection gives both runs the same motion and noise); the faulty joint's peak over the largest other."""
    a, b = record.diagnosers[scheme], fault_free.diagnosers[scheme]
    joints = [c for c in a.components if not c.endswith("_pos")]
    cols = [a.components.index(c) for c in joints]
    win = (a.time >= fault["onset"]) & (a.time < fault["onset"] + window)
    raw = np.abs(a.residual[win][:, cols]).max(axis=0)
    own = np.abs(a.residual[win][:, cols] - b.residual[win][:, cols]).max(axis=0)
    i = joints.index(fault["target"])

    def ratio(x):
        return float(x[i] / max(np.delete(x, i).max(), 1e-300))

    return {"joints": joints, "faulty_peak": raw.tolist(), "contribution_peak": own.tolist(),
            "argmax_contribution": joints[int(np.argmax(own))], "argmax_faulty": joints[int(np.argmax(raw))],
            "contribution_ratio": ratio(own), "faulty_ratio": ratio(raw),
            "threshold": [float(a.threshold[c]) for c in cols],
            "units": {"faulty_peak": "N·m", "contribution_peak": "N·m", "threshold": "N·m"}}


def reproduction(name: str, summary: dict, record, fault_free) -> list[dict]:
    """The chapter's claims (it prints no numeric results), checked on our runs."""
    out = []
    diag = summary["diagnosers"]
    detected = {d: {x["fault"]: x for x in diag[d]["detections"]} for d in diag}
    targets = {f["name"]: f["target"] for f in summary["faults"]}
    if name == "ch3-actuator":
        tau5 = summary["faults"][1]
        td, rec = _peak_ratio(record, "time_delayed", tau5), _peak_ratio(record, "recursive", tau5)
        out.append({"quantity": "tau5 (incipient) peak |r|/threshold: time_delayed < recursive (TD weak on incipient faults)",
                    "paper": "time-delayed low sensitivity to the incipient fault (Figs. 2, 4)",
                    "ours": {"time_delayed": td, "recursive": rec}, "tolerance": None, "pass": bool(td < rec)})
        tau3 = summary["faults"][0]
        iso = torque_space_isolation(record, fault_free, tau3)
        summary["torque_space_isolation"] = iso
        out.append({"quantity": "tau3: time-delayed torque-space residual r_τ = (M̂/T) r₂ over 0.3 s from onset — argmax "
                                "and ratio to the largest other joint of the fault's contribution (digest check 6)",
                    "paper": "argmax joint3, ratio > 5 (digest harness: 38.6 N·m vs ≤ 2.5 N·m elsewhere)",
                    "ours": {"argmax": iso["argmax_contribution"], "ratio": iso["contribution_ratio"],
                             "faulty_joint_peak": iso["contribution_peak"][iso["joints"].index(tau3["target"])],
                             "raw_ratio_with_noise": iso["faulty_ratio"]},
                    "tolerance": "> 5",
                    "pass": bool(iso["argmax_contribution"] == tau3["target"] and iso["contribution_ratio"] > 5),
                    "note": "faulty_joint_peak in N·m; the contribution is faulty − fault-free (offline injection: same "
                            "motion, same noise). The "
                            "raw peaks are noise-dominated on the heavy joints 1-2 (M̂(q)·Δv/T of the harness's "
                            "velocity noise, tens of N·m), so the raw ratio is not the digest's > 5"})
    rms = {d: _fault_free_rms(fault_free, d) for d in BOOK_SCHEMES}
    out.append({"quantity": "fault-free normalised residual RMS after 2 s: adaptive < recursive (best trade-off)",
                "paper": "adaptive: best trade-off between robustness and sensitivity (Figs. 6, 12)",
                "ours": rms, "tolerance": None, "pass": bool(rms["adaptive"] < rms["recursive"])})
    found = {d: [x for f in summary["faults"] for x in [detected[d][f["name"]]] if x["time"] is not None]
             for d in BOOK_SCHEMES}
    correct = {d: all(x["isolated"] == targets[x["fault"]] for x in hits) for d, hits in found.items()}
    targets_total = len(summary["faults"])
    out.append({"quantity": "every detected fault isolated to its own joint/sensor (book schemes)",
                "paper": "a reliable fault isolation is always ensured (Sec. 6)",
                "ours": {d: {"isolated_correctly": correct[d], "detected": f"{len(found[d])} of {targets_total}"}
                         for d in BOOK_SCHEMES},
                "tolerance": None, "pass": all(correct.values())})
    return out


def run(name: str, out: str | Path = "runs", seed: int = 0, progress: bool = True, replay: bool = True, **overrides):
    """Calibrate (cached), run fault-free and faulty, evaluate, plot; returns (summary, run folder)."""
    sc = scenario(name, seed, **overrides)
    run_dir = prepare_run_dir(out, name, seed)
    progress = Progress.of(progress, name)
    calibration_time = sum(r.end for r in sc.calibration.values())
    rates = sc.rates
    ticks = run_ticks(sc.run_duration, rates.control_hz)
    with keep_partial(run_dir):
        with progress.stage(f"calibration: {len(sc.calibration)} motions",
                            calibration_steps(sc, calibration_time, rates, sc.calibration), skipped="from the cache") as tick:
            cal, cached = calibration(sc, progress=tick)
        with progress.stage("fault-free run", ticks) as tick:
            fault_free = run_scenario(replace(sc, faults=()), cal, progress=tick, run_key="fault_free")
        with progress.stage("faulty run", ticks) as tick:
            record = run_scenario(sc, cal, progress=tick)
    faults = [f.to_dict() for f in sc.faults]
    summary = summarize(record, name, faults)
    fault_free_summary = summarize(fault_free, name, [])["diagnosers"]
    summary["fault_free_false_alarms"] = {d: s["false_alarms"] for d, s in fault_free_summary.items()}
    summary["injection"] = sc.injection
    summary["thresholds"] = {
        "calibrated": {k: v.tolist() for k, v in cal.thresholds.items()},
        "state_space": {k: v.tolist() for k, v in cal.state_thresholds.items()},
        "book": BOOK_THRESHOLDS,
        "units": {"calibrated": "rad (position rows), N·m (torque rows)",
                  "state_space": "rad, rad/s per sample", "book": "rad, rad/s per sample"},
        "calibration_cached": cached,
    }
    summary["reproduction"] = reproduction(name, summary, record, fault_free)
    with progress.stage("run folder: records, figures" + (", replay" if replay else "")):
        write_run_folder(run_dir, record, summary, {"fault_free": fault_free}, replay=replay)
    return summary, run_dir


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("name", choices=sorted(EXPERIMENTS))
    p.add_argument("--out", default="runs")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    summary, run_dir = run(a.name, a.out, a.seed)
    print(run_report(summary))
    print(f"run folder: {run_dir}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
