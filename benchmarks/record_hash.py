"""Same seed, same record: the SHA-256 of an arm run's record, to compare the loop engine before and after a change.

    PYTHONPATH=. python benchmarks/record_hash.py [--seed 0] [--faults SPEC ...]

Runs :func:`robofdi.systems.arm.arm_scenario` (arm6, every arm scheme with its threshold decision; default fault:
a step on a seeded joint) and prints one line per record series (its SHA-256 over the raw array bytes) and the
SHA-256 of the whole HDF5 file (:meth:`robofdi.record.Record.to_bytes`) as the last line. Two versions of the
engine that print the same lines give the same record, bit for bit.
"""
from __future__ import annotations

import argparse
import hashlib

import numpy as np

from robofdi.systems.arm import arm_scenario, calibration, run_scenario


def _h(a) -> str:
    a = np.asarray(a)
    if a.dtype == object:
        return hashlib.sha256("\x00".join(map(str, a.ravel())).encode()).hexdigest()[:16]
    return hashlib.sha256(np.ascontiguousarray(a).tobytes() + str(a.shape).encode()).hexdigest()[:16]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--faults", nargs="*", default=())
    args = ap.parse_args(argv)
    sc = arm_scenario("arm6.xml", faults=args.faults, seed=args.seed)
    cal, _ = calibration(sc)
    rec = run_scenario(sc, cal)
    series = {"time": rec.time, "truth/state": rec.truth_state, "truth/u_applied": rec.u_applied,
              **{f"signals/{k}": v for k, v in rec.signals.items()},
              **{f"faults/{k}/{p}": getattr(lab, p) for k, lab in rec.faults.items() for p in ("active", "value")},
              **{f"diagnosers/{k}/{p}": getattr(tr, p) for k, tr in rec.diagnosers.items()
                 for p in ("time", "residual", "threshold", "alarm", "isolated", "estimate")}}
    for key, value in series.items():
        print(f"{key:<36} {_h(value)}")
    print(f"record.h5 sha256: {hashlib.sha256(rec.to_bytes()).hexdigest()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
