"""How often does the encoder jump under a velocity-gain error, and under a noisy encoder? (issue 24, GAIN_JUMPS)

    python benchmarks/gain_jumps.py --robot arm6.xml --speed fast --campaign OUT/arm6-fast
    python benchmarks/gain_jumps.py --robot arm7.xml --speed fast --seed 907 --robot-seeds 20 21 22 23 --runs 43 445

The consistency scheme's gain evidence (``robofdi.observers.consistency._gain_evidence``) fits the increments of
the samples that were not position steps. It counts only where at most ``GAIN_JUMPS`` of the window's moving
samples were position steps. This script re-runs campaign runs of ``benchmarks/arm_acceptance.py``'s design (the
same robot, speed, seed and robot instances) with the consistency scheme alone. Give the runs by index
(``--runs``), or give a finished campaign folder (``--campaign``) to take its velocity-gain errors and noisy
encoders. Per run, for the faulted joint after the onset, it prints:

- the largest gain evidence over its scale, with the rule ("counted") and without it ("raw");
- the share of position steps in the window where the raw evidence peaked, and the largest share.

Then, per fault kind, the range of the share over the samples where the raw evidence was above the row's scale (1).
"""
from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np

from arm_acceptance import acceptance_spec
from robofdi.campaign.results import load
from robofdi.campaign.runs import draw_fault, run_seed
from robofdi.campaign.spec import parse_spec
from robofdi.loop import diagnoser_inputs
from robofdi.observers.consistency import ConsistencyResidual, _gain_fit
from robofdi.seeding import rng

KINDS = (("sensor_scale", "_vel"), ("sensor_noise", "_pos"))    # velocity-gain errors, noisy encoders


def campaign_runs(folder: str) -> list[int]:
    """The faulty runs of a finished campaign whose fault is a velocity-gain error or a noisy encoder."""
    t = load(folder).table
    t = t[t["faulty"] & (t["diagnoser"] == "consistency")]
    pick = np.zeros(len(t), dtype=bool)
    for kind, channel in KINDS:
        pick |= ((t["kind"] == kind) & t["target"].str.endswith(channel)).to_numpy()
    return sorted(int(i) for i in t["index"][pick])


def measure(spec, system, options, calibrations: dict, index: int) -> dict:
    """One run's gain evidence (raw and counted, over its scale) and jumped share on the faulted joint."""
    keys = system.calibration_keys(options)
    key = keys[index % len(keys)]
    if key not in calibrations:
        calibrations[key] = system.calibrate(options, key, ["consistency"])[0]
    cal = calibrations[key]
    seed = run_seed(spec.seed, index)
    mission = system.mission(options, key, rng(seed, "mission"))
    fault = draw_fault(spec, seed, mission.duration)[0]
    record = system.run(options, cal, key, mission, [fault], seed, ["consistency"])
    scenario = system._scenario(options, key, ["consistency"])        # the diagnoser's belief, as in the campaign
    model = scenario.nominal_model(scenario.simulator())
    joint = list(model.joint_names).index(fault.target.rsplit("_", 1)[0])
    diagnoser = ConsistencyResidual(model, cal.designs["consistency"])
    scale, lam = diagnoser._gain_scale[joint], diagnoser._gain_lambda
    raw, counted, share = [], [], []
    Y, U = diagnoser_inputs(record)
    for y, u in zip(Y, U):
        diagnoser.update(y, u)
        sums = diagnoser._gain_sums
        moving = sums[12, joint]        # the window's weight of samples whose reading moved
        share.append(sums[11, joint] / moving if moving > 0 else 0.0)
        counted.append(diagnoser.gain_evidence[joint] / scale)
        free = sums.copy()
        free[11] = 0.0          # the rule off: the same fit on the same kept samples
        single = diagnoser._kinematic.scale[joint, diagnoser._single]     # the fit's floor, as in _step_rows
        raw.append(_gain_fit(free, joint, lam, single) / scale)
    time = np.arange(len(raw)) * diagnoser.T
    after = time > fault.onset
    raw, counted, share = np.array(raw)[after], np.array(counted)[after], np.array(share)[after]
    peak = int(np.argmax(raw))
    return {"index": index, "fault": fault.name, "kind": fault.kind, "onset": fault.onset,
            "raw": raw.max(), "counted": counted.max(), "share at raw peak": share[peak], "largest share": share.max(),
            "share where raw > 1": share[raw > 1.0] if (raw > 1.0).any() else None}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--robot", required=True, help="the acceptance campaign's robot (arm6.xml, arm7.xml, panda, ...)")
    p.add_argument("--speed", default="normal", choices=("normal", "fast"))
    p.add_argument("--seed", type=int, default=None, help="campaign seed (default: the acceptance campaign's)")
    p.add_argument("--robot-seeds", type=int, nargs="+", default=None, help="robot instances (default: the spec's)")
    p.add_argument("--runs", type=int, nargs="*", default=(), help="run indices")
    p.add_argument("--campaign", help="a finished campaign folder: its velocity-gain errors and noisy encoders")
    a = p.parse_args(argv)
    system_fields = None if a.robot_seeds is None else {"robot_seeds": a.robot_seeds}
    spec = parse_spec(acceptance_spec(a.robot, a.speed, seed=a.seed, system=system_fields))
    runs = list(a.runs) + (campaign_runs(a.campaign) if a.campaign else [])
    if not runs:
        p.error("give --runs or --campaign")
    system, options, calibrations = spec.campaign_system, spec.options, {}
    worst = defaultdict(list)
    for index in runs:
        m = measure(spec, system, options, calibrations, index)
        print(f"run {m['index']:4d} {m['fault']:<36s} onset {m['onset']:.2f} s: evidence/scale raw {m['raw']:.2f}, "
              f"counted {m['counted']:.2f}; jumped share at the raw peak {m['share at raw peak']:.2f}, "
              f"largest {m['largest share']:.2f}", flush=True)
        if m["share where raw > 1"] is not None:
            worst[m["kind"]].append(m["share where raw > 1"])
    for kind, shares in worst.items():
        shares = np.concatenate(shares)
        print(f"{kind}: {len(worst[kind])} runs with raw evidence above the scale; the jumped share at those samples "
              f"{shares.min():.2f}-{shares.max():.2f}")


if __name__ == "__main__":
    main()
