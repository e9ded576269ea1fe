"""Guo et al.'s UIO bank with its switching index against Bošković & Mehra's hybrid FDI-ARC, on the same records.

The records of ``robofdi run ch5-effector`` (left rudder hard-over at 1.5 s, right LEF lock at 3.5 s on the
flight surrogate) are replayed offline through :class:`robofdi.observers.uio.LockInPlaceBank` (Guo et al. 2008
eqs. (12)–(18), σ = 3, γ = 50, projection on each surface's position limits). Its unknown input is a side gust on
β̇, which the scenario does not excite. The decision is :class:`robofdi.decision.SwitchingIndexDecision` (eq. (21))
with its detection threshold = 1.2 × the largest ‖r₀‖ of the failure-free record. Both schemes see the same
(y, ū(k−1)). The hybrid bank reconfigures the loop it runs in; Guo's bank only diagnoses.

    robofdi run ch5-effector --out runs
    PYTHONPATH=. python benchmarks/ch5_vs_guo.py runs/ch5-effector-seed0
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from robofdi.decision import SwitchingIndexDecision, calibrate_thresholds
from robofdi.loop import replay
from robofdi.models.flight import flight_surrogate
from robofdi.models.linear import LinearModel, discretize
from robofdi.observers.uio import LockInPlaceBank
from robofdi.record import load

DT = 0.01


def guo_bank():
    s = flight_surrogate()
    model = LinearModel(s.A(), s.B(), np.eye(s.n), state_names=list(s.state_names), input_names=list(s.effectors),
                        output_names=list(s.state_names),
                        units={"state": list(s.units), "u": ["rad"] * s.m, "y": list(s.units)})
    E = np.zeros((s.n, 1))
    E[s.state_names.index("beta"), 0] = 1.0
    return LockInPlaceBank(discretize(model, DT), [-3.0] * s.n, E=E, gamma=50.0, u_min=s.u_min, u_max=s.u_max)


def isolation_sequence(record, threshold: float) -> list[tuple[float, str]]:
    """(time, model) of every change of the isolated model of Guo's decision over ``record``."""
    bank = guo_bank()
    r = np.array([res.r for res in replay(record, bank)])
    dec = SwitchingIndexDecision(bank.components, np.r_[threshold, np.full(len(bank.inputs), 1e9)], bank.inputs, DT,
                                 blanking=50)
    seq = []
    for k, row in enumerate(r):
        iso = dec.update(row).isolated
        if iso and (not seq or seq[-1][1] != iso[0]):
            seq.append((round(k * DT, 3), iso[0]))
    return seq


def main(run_dir: str) -> dict:
    d = Path(run_dir)
    free, hyb, base = (load(d / f) for f in ("failure_free.h5", "record.h5", "baseline.h5"))
    r0 = np.array([res.r[:1] for res in replay(free, guo_bank())])
    threshold = max(float(calibrate_thresholds([r0], 1.2, skip=50)[0]), 1e-6)
    summary = json.loads((d / "summary.json").read_text())
    out = {"guo_threshold": threshold,
           "hybrid_fdi_arc": [(e["time"], e["model"]) for e in summary["switching_sequence"]]}
    for name, rec in (("failure_free", free), ("baseline", base), ("hybrid", hyb)):
        out[f"guo_on_{name}"] = isolation_sequence(rec, threshold)
    return out


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1] if len(sys.argv) > 1 else "runs/ch5-effector-seed0"), indent=1))
