"""Why a soak's false alarms happen: exceedances, their operating points and an extreme-value forecast.

    python benchmarks/soak_alarms.py DIR/record.h5 [--fit-minutes 10] [--block 0.25]

Reads a fault-free record (e.g. of ``benchmarks/arm_soak.py --out DIR``) in slices and prints per diagnoser:

- ``exceed``: 0.25 s blocks in which some residual component crossed its threshold (|r_j| > thr_j), and the
  decision's alarm episodes (rising edges of its any-component alarm; a latched decision has fewer);
- the first crossings: time, component, |r|/thr, and the operating point of that joint at that moment — its
  measured speed |q̇_j| and commanded acceleration |q̈_d,j| as percentiles of the whole run's values;
- an extreme-value forecast: a Gumbel law (Coles 2001, Sec. 3.1–3.4) fitted to the block maxima of
  max_j |r_j|/thr_j over the first ``--fit-minutes`` minutes predicts how many blocks of the *rest* of the run
  cross 1; it is printed beside the observed count. Agreement means the alarms are the tail of a stationary
  fault-free residual (a threshold set at a sample maximum is crossed when the run is long enough), not drift.
"""
from __future__ import annotations

import argparse
import json
import sys

import h5py
import numpy as np
from scipy.stats import gumbel_r

SLICE = 50_000


def _block_maxima(ds_r, threshold: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Per block of ``size`` samples: the max over components of |r_j|/thr_j, and the argmax component."""
    n = ds_r.shape[0]
    step = SLICE - SLICE % size
    peaks, where = [], []
    for k0 in range(0, n - n % size, step):
        ratio = np.abs(ds_r[k0:min(k0 + step, n - n % size)]) / threshold
        blocks = ratio.reshape(-1, size, ratio.shape[1]).max(axis=1)
        peaks.append(blocks.max(axis=1))
        where.append(blocks.argmax(axis=1))
    return np.concatenate(peaks), np.concatenate(where)


def _episodes(ds_alarm) -> int:
    count, previous = 0, False
    for k0 in range(0, ds_alarm.shape[0], SLICE):
        a = ds_alarm[k0:k0 + SLICE].any(axis=1)
        count += int(np.count_nonzero(a & ~np.concatenate([[previous], a[:-1]])))
        previous = bool(a[-1]) if a.size else previous
    return count


def _percentile_of(values: np.ndarray, x: float) -> float:
    return 100.0 * float(np.searchsorted(np.sort(values), x)) / max(values.size, 1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("record")
    ap.add_argument("--fit-minutes", type=float, default=10.0, help="minutes the Gumbel law is fitted on (10)")
    ap.add_argument("--block", type=float, default=0.25, help="block length [s] (0.25)")
    ap.add_argument("--show", type=int, default=3, help="first crossings listed per diagnoser (3)")
    args = ap.parse_args(argv)
    with h5py.File(args.record, "r") as f:
        t_ctrl = f["time"]
        n_ctrl = t_ctrl.shape[0]
        t_end = float(t_ctrl[n_ctrl - 1])
        n_joints = f["signals/u"].shape[1]
        qd_meas = np.abs(f["signals/y_meas"][:, n_joints:2 * n_joints])        # |q̇| measured, (N, n)
        qdd_ref = np.abs(f["signals/reference"][:, 2 * n_joints:3 * n_joints])  # |q̈_d|, (N, n)
        dt_ctrl = t_end / max(n_ctrl - 1, 1)
        print(__doc__.splitlines()[0])
        print(f"{args.record}: {t_end:.0f} s simulated; fit on the first {args.fit_minutes:g} min, "
              f"{args.block:g} s blocks; partial = {f.attrs.get('partial', False)}")
        print()
        for name in f["diagnosers"]:
            g = f[f"diagnosers/{name}"]
            threshold = g["threshold"][()]
            components = json.loads(g.attrs["components"])
            t = g["time"]
            dt = float(t[1] - t[0]) if t.shape[0] > 1 else 1.0
            size = max(1, int(round(args.block / dt)))
            peaks, where = _block_maxima(g["residual"], threshold, size)
            crossed = np.flatnonzero(peaks > 1.0)
            fit_blocks = int(args.fit_minutes * 60.0 / (size * dt))
            fit, rest = peaks[:fit_blocks], peaks[fit_blocks:]
            forecast = "-"
            if fit.size >= 20 and rest.size:
                loc, scale = gumbel_r.fit(fit)
                expected = rest.size * float(gumbel_r.sf(1.0, loc, scale))
                forecast = (f"forecast {expected:.1f} blocks over 1 in the rest ({rest.size} blocks), "
                            f"observed {int(np.count_nonzero(rest > 1.0))}; fit max {fit.max():.3f}")
            print(f"{name}: {crossed.size} blocks over threshold, {_episodes(g['alarm'])} alarm episode(s) of the "
                  f"decision; run max |r|/thr {peaks.max():.3f}; {forecast}")
            for b in crossed[:args.show]:
                k = int(b) * size
                ratio = np.abs(g["residual"][k:k + size]) / threshold
                kk, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
                tk = float(t[k + kk])
                comp = components[j]
                joint = next((i for i in range(n_joints) if comp.startswith(f"joint{i + 1}")), None)
                op = ""
                if joint is not None:
                    kc = min(int(round(tk / dt_ctrl)), n_ctrl - 1)
                    v, a = float(qd_meas[kc, joint]), float(qdd_ref[kc, joint])
                    op = (f"; joint {joint + 1}: |q̇| {v:.2f} rad/s (p{_percentile_of(qd_meas[:, joint], v):.1f}), "
                          f"|q̈_d| {a:.1f} rad/s² (p{_percentile_of(qdd_ref[:, joint], a):.1f})")
                print(f"    t = {tk:9.3f} s  {comp:<12} |r|/thr {ratio[kk, j]:.3f}{op}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
