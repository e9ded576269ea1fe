"""Can the consistency scheme tell a friction rise from an actuator fault? (issue 24, docs/systems/arm.md)

    python benchmarks/friction_evidence.py [--robot arm6.xml] [--fault SPEC] [--joint J] [--segments S]
                                           [--mission-seed M] [--every 0.1] [--tau 0.25]

Runs one arm run (seed 0, its default calibration) with one fault, replays the consistency scheme's dynamic row
of joint J (1-based; default: the fault's target) and prints, every --every seconds, how much of its normalised
residual ρ = r / bound each explanation accounts for: the weighted least-squares fit of ρ over an exponential
window (time constant --tau) to a constant, a constant and a linear trend, the identified friction's shape
φ(q̇) (Coulomb, viscous and Stribeck terms, no offset, filtered by the residual's first-order dynamics), a
constant and the friction shape, and the filtered command ū (a loss of effectiveness). Each column is the
explained mean square in units of the bound squared; a friction hypothesis needs the friction shape to explain
clearly more than every actuator explanation. ``--segments S`` replaces the default one-move motion by a random
S-segment point-to-point mission (the campaigns' generator, ``--mission-seed``).
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from robofdi.config import evolve
from robofdi.faults.spec import parse_fault_spec
from robofdi.loop import diagnoser_inputs
from robofdi.observers.consistency import ConsistencyResidual
from robofdi.seeding import rng
from robofdi.systems.arm import ArmOptions, ArmSystem, arm_scenario, calibration, run_scenario


def explained(columns: list[np.ndarray], rho: np.ndarray, weight: np.ndarray) -> float:
    """ρ's weighted mean square explained by its least-squares fit on ``columns`` (the normal equations)."""
    X = np.column_stack(columns)
    Xw = X * weight[:, None]
    g = Xw.T @ rho
    c = np.linalg.lstsq(X.T @ Xw, g, rcond=1e-10)[0]
    return float(c @ g) / float(weight.sum())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="arm6.xml")
    ap.add_argument("--fault", default="component_friction:joint2:1.0@1.2")
    ap.add_argument("--joint", type=int, default=None, help="1-based joint index (default: the fault's target)")
    ap.add_argument("--segments", type=int, default=0, help="a random mission of this many segments (0: default)")
    ap.add_argument("--mission-seed", type=int, default=0)
    ap.add_argument("--every", type=float, default=0.1, help="print interval [s]")
    ap.add_argument("--tau", type=float, default=0.25, help="the window's time constant [s]")
    args = ap.parse_args(argv)

    fault = parse_fault_spec(args.fault)
    sc = arm_scenario(args.robot, faults=[fault], seed=0)
    if args.segments:        # a campaign's mission (its generator, tail 0.5 s), robot instance 0
        options = evolve(ArmOptions(), robot=args.robot, segments=args.segments, tail=0.5)
        mission = ArmSystem().mission(options, "0", rng(args.mission_seed, "mission"))
        sc = replace(sc, motion=mission.plan, duration=mission.duration)
    cal = calibration(sc)[0]
    record = run_scenario(sc, cal)
    trace, design = record.diagnosers["consistency"], cal.designs["consistency"]
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    n = model.n
    j = (args.joint - 1) if args.joint else list(model.joint_names).index(fault.target)
    Y, U = diagnoser_inputs(record, sc.loop_rates(sim))
    diagnoser = ConsistencyResidual(model, design)
    bound = np.empty(len(Y))
    for k, (y, u) in enumerate(zip(Y, U)):
        diagnoser.update(y, u)
        bound[k] = diagnoser.bound()[j]
    shape = design.friction.torque(Y[:, n:])[:, j] - design.friction.offset[j]
    a = design.gain * design.T                 # the residual's own first-order dynamics, per sample
    friction, command = np.zeros(len(Y)), np.zeros(len(Y))
    for k in range(1, len(Y)):
        friction[k] = friction[k - 1] + a * (shape[k - 1] - friction[k - 1])
        command[k] = command[k - 1] + a * (U[k, j] - command[k - 1])
    rho, t = trace.residual[:, j], trace.time
    print(f"# {args.robot}, {args.fault}, joint {j + 1} ({model.joint_names[j]}), window tau {args.tau} s")
    print("t [s]  q̇ [rad/s]     ρ  constant  const+trend  friction  const+friction  command  isolated")
    span = int(5 * args.tau / design.T)
    for k in range(0, len(t), max(1, int(round(args.every / design.T)))):
        window = slice(max(0, k - span), k + 1)
        age = (k - np.arange(window.start, k + 1)) * design.T
        weight = np.exp(-age / args.tau)
        inv = 1.0 / bound[window]
        r = rho[window]
        f, c = friction[window] * inv, command[window] * inv
        cols = (explained([inv], r, weight), explained([inv, age * inv], r, weight), explained([f], r, weight),
                explained([inv, f], r, weight), explained([c], r, weight))
        print(f"{t[k]:5.2f}  {Y[k, n + j]:+9.2f}  {rho[k]:+5.2f}  " + "  ".join(f"{v:8.2f}" for v in cols)
              + f"  {trace.isolated[k]}")


if __name__ == "__main__":
    main()
