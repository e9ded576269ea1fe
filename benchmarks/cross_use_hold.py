"""Cross-use comparison on one scenario (docs/systems/linear.md, "Cross-use on the arm"): arm6 holding q₀, a 20 N·m step on
joint 2 at 1.5 s. The linearised adaptive fault estimator (robofdi.systems.arm_linearized) against the native arm
schemes, both calibrated on fault-free runs of the same hold (native: margin 1.2, their own calibration machinery).

    python benchmarks/cross_use_hold.py
"""
from __future__ import annotations

import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from robofdi.control import Quintic
from robofdi.evaluate import summarize
from robofdi.systems.arm import calibration, run_scenario
from robofdi.systems.arm_linearized import run_linearized

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_cross_use import Q0, hold_scenario  # noqa: E402


def main() -> None:
    warnings.filterwarnings("ignore", "Convergence was not reached")
    sc = hold_scenario()
    rows = []
    rec = run_linearized(sc)
    s = summarize(rec, "hold")["diagnosers"]["adaptive_fe"]
    est = rec.diagnosers["adaptive_fe"]
    rows.append(("adaptive_fe (linearised)", s, float(est.estimate[est.time > 2.8, 1].mean())))
    native = replace(sc, calibration={"hold": Quintic(Q0, (0.0,) * 6, 3.0)})
    cal, _ = calibration(native)
    rec = run_scenario(native, cal)
    for name, s in summarize(rec, "hold")["diagnosers"].items():
        tr = rec.diagnosers[name]
        j = tr.estimate_components.index("joint2") if "joint2" in tr.estimate_components else None
        rows.append((name, s, float(tr.estimate[tr.time > 2.8, j].mean()) if j is not None else np.nan))
    print(f"{'diagnoser':26s} {'detected [s]':>12s} {'isolated':>9s} {'false alarms':>12s} {'estimate [N·m]':>15s}")
    for name, s, e in rows:
        d = s["detections"][0]
        t = "-" if d["time"] is None else f"{d['time']:.3f}"
        print(f"{name:26s} {t:>12s} {str(d['isolated']):>9s} {s['false_alarms']:12d} {e:15.2f}")


if __name__ == "__main__":
    main()
