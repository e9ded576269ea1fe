"""Speed of NLAR residual evaluation: generated functions vs direct sympy evaluation, per test sample.

Run from the repository root::

    PYTHONPATH=. python benchmarks/nlar_eval.py

What is measured (time.perf_counter, µs per call, median of 7 timed repeats after a warm-up; "(min)" the fastest):

* ``mj_step (rig)``        raw ``mujoco.mj_step`` of assets/hydraulic_rig.xml (the reference unit of cost).
* ``derive_nlar``          the symbolic derivation of the hydraulic model's tests (once per model), in ms.
* ``lambdify (math, cse)`` ``NLARDesign.residual_function()``: all four kept tests R1, R2, R4, R5 at one sample.
* ``lambdify (numpy)``     the same expressions lambdified with numpy (no cse), one sample.
* ``sympy subs+evalf``     direct sympy: substitute the sample into the four expressions and evaluate.
* ``vectorised numpy``     the numpy function on 10 000 samples at once, per sample (offline replay).
* ``RedundancyResidual.update`` one Diagnoser sample: SG derivative filter (41 × 10 dot) + tests.
"""
from __future__ import annotations

import platform
import statistics
import time

import mujoco
import numpy as np
import sympy as sp

from robofdi import ASSETS
from robofdi.models.hydraulic import hydraulic_domain, hydraulic_model
from robofdi.redundancy import derive_nlar
from robofdi.redundancy.derivatives import SavitzkyGolay
from robofdi.redundancy.residuals import nlar_residual
from robofdi.sims.hydraulic import HydraulicRig


def timed(fn, number: int, repeats: int = 7) -> tuple[float, float]:
    fn()
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        out.append((time.perf_counter() - t0) / number * 1e6)
    return statistics.median(out), min(out)


def main() -> None:
    rows = []
    m = mujoco.MjModel.from_xml_path(str(ASSETS / "hydraulic_rig.xml"))
    d = mujoco.MjData(m)
    rows.append(("mj_step (rig)", *timed(lambda: mujoco.mj_step(m, d), 2000)))
    model = hydraulic_model()
    t0 = time.perf_counter()
    design = derive_nlar(model, hydraulic_domain(model))
    derive_ms = (time.perf_counter() - t0) * 1e3
    args = design.arguments()
    sample = dict(zip(args, [0.52, 0.01, -0.2, 1.3e6, 2e4, -5e5, 0.065, 0.01, 1.2e6, 1e3]))
    values = [sample[a] for a in args]
    fast = design.residual_function()
    exprs = [design.tests[n].subs(model.params) for n in design.independent]
    numpy_fn = sp.lambdify(args, exprs, modules="numpy")
    rows.append(("lambdify (math, cse)", *timed(lambda: fast(*values), 20000)))
    rows.append(("lambdify (numpy)", *timed(lambda: numpy_fn(*values), 5000)))
    rows.append(("sympy subs+evalf", *timed(lambda: [e.subs(sample).evalf() for e in exprs], 20, 5)))
    batch = [np.full(10000, v) + np.linspace(0, 1e-6, 10000) for v in values]
    med, mn = timed(lambda: numpy_fn(*batch), 20)
    rows.append(("vectorised numpy (per sample)", med / 10000, mn / 10000))
    sim = HydraulicRig()
    res = nlar_residual(design, sim.sensor_channels, sim.actuators, SavitzkyGolay(dt=0.001))
    y, u = np.array([0.52, 1.3e6, 1.2e6, 2.0e7]), np.array([0.065])
    for _ in range(50):
        res.update(y, u)
    rows.append(("RedundancyResidual.update", *timed(lambda: res.update(y, u), 5000)))
    step = rows[0][1]
    print(f"python {platform.python_version()}, sympy {sp.__version__}, mujoco {mujoco.__version__}, "
          f"{platform.processor() or platform.machine()}")
    print(f"derive_nlar (hydraulic model, once): {derive_ms:.0f} ms")
    print(f"{'what':32s} {'µs/call':>12s} {'(min)':>12s} {'× mj_step':>10s}")
    for name, med, mn in rows:
        print(f"{name:32s} {med:12.3f} {mn:12.3f} {med / step:10.1f}")
    print(f"generated (math, cse) vs direct sympy: {rows[3][1] / rows[1][1]:.0f}× faster")


if __name__ == "__main__":
    main()
