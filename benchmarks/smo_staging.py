"""Staging of book ch. 1's Example 2 SMO by schedule against the sliding detector (robofdi.observers.sliding_mode.
SlidingDetector): the chapter's ODE plant, u = 0, x(0) = 1, 3 s, h = 1e-8 s, τ = 1e-5 s; prints each stage's
switch-on time and the rms estimation errors on [2.5, 3] s. Run from the repository root::

    PYTHONPATH=. python benchmarks/smo_staging.py        # about 2 min per variant on an idle core

Measured results: docs/systems/ch1-sliding-mode.md (Numerics, Staging).
"""
from __future__ import annotations

import time

import numpy as np
import scipy.integrate

from robofdi.observers.sliding_mode import SlidingDetector
from robofdi.sims.flexible_joint import FLEXIBLE_JOINT
from robofdi.systems.flexible_joint import FlexibleJointOptions, flexible_joint_smo

VARIANTS = (None, SlidingDetector(0.05, 0.05), SlidingDetector(0.2, 0.02))


def main():
    A, G = FLEXIBLE_JOINT["A"], FLEXIBLE_JOINT["G"]
    T, H = 1e-3, 3.0
    ts = np.arange(0, H + T / 2, T)
    X = scipy.integrate.solve_ivp(lambda t, x: A @ x + G[:, 0] * (-3.33 * np.sin(x[2])), (0, H), [1, 1, 1, 1.0],
                                  t_eval=ts, rtol=1e-10, atol=1e-12, method="DOP853").y.T
    for det in VARIANTS:
        t0 = time.perf_counter()
        smo = flexible_joint_smo(FlexibleJointOptions(substep=1e-8, tau=1e-5), T, detector=det)
        for k in range(len(ts)):
            smo.update(X[k, :1], [0.0])
        E = X - np.array(smo.history)
        print(f"{det or 'schedule 0.2/0.8/1.8 s'}: on at {smo.switched_on} s, rms error on [2.5, 3] s "
              f"{np.sqrt((E[-500:] ** 2).mean(0)).round(3)}, {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
