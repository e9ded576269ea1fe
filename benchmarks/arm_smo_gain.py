"""The arm's sliding-mode scheme (robofdi.observers.sliding_mode_arm) against its switching gain Λ and its
equivalent-control filter, offline on the fault-free calibration motions of the shipped arm (seed 0): the largest
|τ̂| per joint (what sets the margin thresholds), the rms, the share of samples where sliding is lost
(|r_eq| ≥ 0.95 Λ over a whole sample), beside the momentum observer. Run from the repository root::

    PYTHONPATH=. python benchmarks/arm_smo_gain.py        # a few minutes

Measured results: docs/systems/ch1-sliding-mode.md (the arm's sliding-mode diagnoser).
"""
from __future__ import annotations

import time

import numpy as np

from robofdi.loop import Diagnosis, diagnose_record
from robofdi.observers.arm_schemes import arm_schemes
from robofdi.observers.sliding_mode_arm import ArmSlidingModeObserver
from robofdi.systems.arm import arm_scenario, calibration_records

GAINS = (20.0, 50.0, 200.0, 1000.0)
FILTERS = (0.0, 0.02)


def main():
    sc = arm_scenario(schemes=("momentum",))
    records = calibration_records(sc)
    sim = sc.simulator()
    model, rates = sc.nominal_model(sim), sc.loop_rates(sim)
    st = sc.scheme_settings(rates)
    skip = 25
    for name, rec in records.items():
        mom = diagnose_record(rec, Diagnosis(arm_schemes(model, st, None, ["momentum"])["momentum"]), rates).residual
        print(name, "momentum max|r|", np.abs(mom[skip:]).max(0).round(1))
        for gain in GAINS:
            for filt in FILTERS:
                d = ArmSlidingModeObserver(model, st.T, gain, st.smo_substep, st.smo_tau, filt)
                lost, inner = [], d.smo.update

                def update(y, u, inner=inner, gain=gain, lost=lost):
                    r = inner(y, u)
                    lost.append(np.abs(r.r) >= 0.95 * gain)
                    return r

                d.smo.update = update
                t0 = time.perf_counter()
                r = diagnose_record(rec, Diagnosis(d), rates).residual[skip:]
                per = (time.perf_counter() - t0) / len(r)
                print(f"  gain {gain:6.0f} filter {filt:.2f}: max|tau| {np.abs(r).max(0).round(1)} rms "
                      f"{np.sqrt((r ** 2).mean(0)).round(2)}, sliding lost {100 * np.mean(lost[skip:]):.1f} % of samples, "
                      f"{1e6 * per:.0f} us per update (with the replay)")


if __name__ == "__main__":
    main()
