"""After its onset, does a velocity-gain error leave evidence in ν? (issue 24, docs/systems/arm.md)

    python benchmarks/gain_evidence.py [--tau 0.5] [--faults SPEC ...] [--fault-free-seeds 7 8 9]

A gain error g on a velocity sensor makes the reading (1 + g) q̇, so after its onset every change of the true
velocity Δq̇ adds g Δq̇ to the reading: the velocity innovation ν of the consistency scheme should follow g Δq̇
(ν is the velocity step on one joint that explains the torque impulse; a reading's step of b makes ν = b). This
script runs arm6 (seed 5 motion, its default calibration) with each fault and fault-free motions (seeds
--fault-free-seeds), regresses ν on the reading's own change Δq̇ per joint over an exponential window (--tau),
both in units of the step row's bound, from 20 ms after the onset (the onset's step is the step row's), and
prints the regression's statistic |Σ ν Δq̇| / √(Σ Δq̇²) (largest per joint) and its slope ĝ there, against the
largest fault-free statistic.
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from robofdi.faults.spec import parse_fault_spec
from robofdi.loop import diagnoser_inputs
from robofdi.observers.consistency import ConsistencyResidual
from robofdi.systems.arm import arm_scenario, calibration, run_scenario

SKIP = 55       # start-up samples left out (the blanking and the first ν)


def regression(model, design, Y, U, tau: float, start: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(statistic, slope), each (N, n): ν on Δq̇ over an exponential window of ``tau`` s from sample ``start``."""
    n, lam = model.n, 1.0 - design.T / tau
    diagnoser = ConsistencyResidual(model, design)
    sxw, sww = np.zeros(n), np.zeros(n)
    stat, slope = np.zeros((len(Y), n)), np.zeros((len(Y), n))
    previous = None
    for k, (y, u) in enumerate(zip(Y, U)):
        diagnoser.update(y, u)
        v = y[n:]
        change = np.zeros(n) if previous is None else v - previous
        previous = v
        if k < start:
            continue
        bound = design.step_bound(np.abs(v), diagnoser.spread)
        x, w = diagnoser.innovation / bound, change / bound
        sxw, sww = lam * sxw + x * w, lam * sww + w * w
        stat[k] = np.abs(sxw) / np.sqrt(np.maximum(sww, 1e-300))
        slope[k] = sxw / np.maximum(sww, 1e-300)
    return stat, slope


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tau", type=float, default=0.5, help="the window's time constant [s]")
    ap.add_argument("--faults", nargs="+", default=["sensor_scale:joint3_vel:0.1@1.0", "sensor_scale:joint3_vel:-0.2@1.0",
                                                    "sensor_scale:joint5_vel:0.1@1.0", "sensor_scale:joint5_vel:-0.2@1.0",
                                                    "sensor_drift:joint3_pos:0.01@1.0"])
    ap.add_argument("--fault-free-seeds", type=int, nargs="+", default=[5, 7, 8, 9])
    args = ap.parse_args(argv)

    base = arm_scenario("arm6.xml", seed=5, schemes=("consistency",))
    cal = calibration(base)[0]
    design = cal.designs["consistency"]
    sim = base.simulator()
    model, rates = base.nominal_model(sim), base.loop_rates(sim)
    free = []
    for seed in args.fault_free_seeds:
        sc = replace(arm_scenario("arm6.xml", seed=seed, schemes=("consistency",)), faults=())
        Y, U = diagnoser_inputs(run_scenario(sc, calibration(sc)[0]), rates)
        free.append(regression(model, design, Y, U, args.tau)[0][SKIP:].max(axis=0))
    free = np.array(free)
    print(f"# arm6, window tau {args.tau} s; fault-free motions (seeds {args.fault_free_seeds}): largest statistic "
          f"per joint {np.round(free.max(axis=0), 2).tolist()}")
    for spec in args.faults:
        fault = parse_fault_spec(spec)
        j = list(model.joint_names).index(fault.target.rsplit("_", 1)[0])
        sc = replace(base, faults=(fault,))
        Y, U = diagnoser_inputs(run_scenario(sc, calibration(sc)[0]), rates)
        start = int(round((fault.onset + 0.02) / design.T))
        stat, slope = regression(model, design, Y, U, args.tau, start)
        k = start + int(np.argmax(stat[start:, j]))
        print(f"{spec}: joint {j + 1} statistic {stat[k, j]:.2f} (fault-free up to {free[:, j].max():.2f}), "
              f"slope there {slope[k, j]:+.2f} (the gain: {fault.magnitude if fault.kind == 'sensor_scale' else 0:+.2f})")


if __name__ == "__main__":
    main()
