"""Write ``arm6_cycles.csv.gz``: what a real arm6 controller would log, recorded from robofdi's simulator.

A pick-and-place cycle (rest pose → work pose → rest pose, quintic segments with 0.3 s dwells) repeated four
times under computed torque; at ``ONSET`` the joint-2 drive starts delivering ``MAGNITUDE`` N·m more than
commanded (an actuator fault the log does not say). Logged like a controller logs, not like a simulator: the
measured joint positions (encoder-quantised) and velocities, and the commanded torques, at 500 Hz with timing
jitter (σ = 50 µs on the stamps) and dropped rows (0.5 % at random, plus one burst of 6), in the controller's
own column names (``t_s``, ``pos_j<i>``, ``vel_j<i>``, ``cmd_j<i>``). The truth is written beside it in
``arm6_cycles.json`` for the tests and the docs; nothing in robofdi reads it when diagnosing.

    python assets/logs/make_arm6_log.py          # from the repository root; takes ~1 min
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from robofdi.control import ComputedTorque
from robofdi.control.trajectory import Sequence
from robofdi.faults import Fault
from robofdi.loop import ClosedLoop, Rates
from robofdi.sims import ArmSimulator

HERE = Path(__file__).resolve().parent
REST = np.array([0.0, -1.2, 1.4, 0.0, 0.6, 0.0])
WORK = np.array([0.9, -0.5, 0.6, 0.8, -0.4, 1.2])
CYCLES, MOVE, DWELL = 4, 1.2, 0.3                  # one cycle: move, dwell, move back, dwell = 3 s
ONSET, MAGNITUDE, JOINT = 10.4, 30.0, "joint2"     # inside the fourth cycle's first move
RATE, JITTER, DROP, SEED = 500.0, 50e-6, 0.005, 7


def cycle_motion() -> Sequence:
    poses, times = [REST], []
    for _ in range(CYCLES):
        poses += [WORK, WORK, REST, REST]
        times += [MOVE, DWELL, MOVE, DWELL]
    return Sequence.through(poses, times)


def main() -> None:
    sim = ArmSimulator("arm6.xml", seed=SEED)
    model = sim.nominal_model()
    motion = cycle_motion()
    fault = Fault(f"{JOINT}_step", "actuator_additive", JOINT, onset=ONSET, magnitude=MAGNITUDE)
    loop = ClosedLoop(sim, ComputedTorque(model, torque_limit=model.torque_limit), motion, (fault,),
                      rates=Rates(1000.0, RATE))
    rec = loop.run(float(motion.end), REST, seed=SEED, run_key="log")
    keep = slice(None, None, int(round(1000.0 / RATE)))            # the controller logs at 500 Hz
    t = rec.time[keep]
    y, u = rec.signals["y_meas"][keep], rec.signals["u_cmd"][keep]
    n = sim.n
    rng = np.random.default_rng(SEED)
    stamps = t + rng.normal(0.0, JITTER, t.size)
    kept = rng.random(t.size) > DROP
    burst = int(0.6 * t.size)
    kept[burst:burst + 6] = False
    kept[0] = True
    table = {"t_s": np.round(stamps, 6)}
    for i in range(n):
        table[f"pos_j{i + 1}"] = np.round(y[:, i], 6)
        table[f"vel_j{i + 1}"] = np.round(y[:, n + i], 5)
        table[f"cmd_j{i + 1}"] = np.round(u[:, i], 4)
    frame = pd.DataFrame(table)[kept]
    frame.to_csv(HERE / "arm6_cycles.csv.gz", index=False)
    truth = {"robot": "arm6.xml", "rate_hz": RATE, "rows": int(kept.sum()), "dropped_rows": int((~kept).sum()),
             "cycle_s": 2 * (MOVE + DWELL), "cycles": CYCLES, "fault": fault.to_dict(),
             "columns": {f"{kind}_j{i + 1}": f"joint{i + 1}_{what}" for i in range(n)
                         for kind, what in (("pos", "q"), ("vel", "qd"), ("cmd", "tau"))} | {"t_s": "time"},
             "sensors": "robofdi's default arm sensors (encoder-quantised positions, noisy velocities)"}
    (HERE / "arm6_cycles.json").write_text(json.dumps(truth, indent=2) + "\n")
    print(f"{len(frame)} rows, {(HERE / 'arm6_cycles.csv.gz').stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
