"""Speed of the sliding-mode observers of book ch. 1 (robofdi.observers.sliding_mode): µs per ``update`` (one 1 ms
diagnosis sample), with the sub-stepping each one's accuracy needs, against the raw kernel.

Run from the repository root::

    PYTHONPATH=. python benchmarks/smo_update.py        # about 1 min

What is measured (time.perf_counter, µs per call; median over repeats after a warm-up; "(min)" the fastest):

* ``kernel/step``       the compiled kernel per Euler sub-step (4 states, 4 stages), the floor of every observer;
* ``kernel/python``     the same kernel interpreted (the fallback without numba), per sub-step;
* ``update/<observer>`` one ``update`` of each observer at its experiment's settings, and its ratio to
                        nsub × kernel/step (the per-sample Python overhead around the kernel):
    flexible_joint (Example 2, h = 1e-8 s, τ = 1e-5 s: 100,000 sub-steps per sample), motor_smo and motor_fdi
    (Examples 4–5, h = 1e-7, τ = 1e-4: 10,000), pendulum (Example 3, h = 5e-6, τ = 5e-5: 200), walcott_zak and
    utkin (G1/G4 settings, h = 1e-5: 100).
"""
from __future__ import annotations

import statistics
import time

import numpy as np

from robofdi.observers import smo_kernel
from robofdi.observers.sliding_mode import SMOSettings, utkin_smo, walcott_zak_smo


def _time(fn, n: int, repeats: int = 5) -> tuple[float, float]:
    fn()
    runs = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        runs.append((time.perf_counter() - t) / n * 1e6)
    return statistics.median(runs), min(runs)


def _kernel_args(nsub):
    n = S = 4
    return (np.zeros(n), np.zeros(S), nsub, 1e-8, np.zeros((1, 4)), np.eye(n) * -1, np.eye(n) * -1, np.ones(n), np.ones(n),
            np.eye(n), np.ones((S, 1)), np.eye(S, n), np.array([0, 1, 1, 1]), np.array([0, 0, 1, 2]), np.ones(S),
            np.ones(S), np.ones(S), np.ones(S, dtype=np.int64), 0, 0.02, np.full(S, 1e-3))


def main():
    rows = []
    nsub = 100_000
    med, mn = _time(lambda: smo_kernel.integrate_interval(*_kernel_args(nsub)), 3)
    step = med / nsub
    rows.append(("kernel/step (compiled)" if smo_kernel.COMPILED else "kernel/step (interpreted)", step, mn / nsub, ""))
    py_n = 2000
    args = list(_kernel_args(py_n))
    out = (np.zeros(4), np.zeros(4), np.zeros(4))
    med_py, mn_py = _time(lambda: smo_kernel._integrate(*args, *out), 1, 3)
    rows.append(("kernel/python", med_py / py_n, mn_py / py_n, f"{med_py / py_n / step:.0f}× the compiled step"))

    from robofdi.systems.cart_pendulum import PendulumDiagnoser
    from robofdi.systems.flexible_joint import FlexibleJointOptions, flexible_joint_smo
    from robofdi.systems.motor import MotorFDI, motor_smo

    A = np.array([[-2.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, -3.0, -1.0]])
    G = np.array([[0.0], [0.0], [1.0]])
    C = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    Bw = np.array([[0.0], [1.0], [0.0]])
    Au = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -3.0]])
    observers = {
        "flexible_joint": (flexible_joint_smo(FlexibleJointOptions(), keep_history=False), 1, 1),
        "motor_smo": (motor_smo(SMOSettings(1e-3, 1e-7, 1e-4), keep_history=False), 1, 2),
        "motor_fdi": (MotorFDI(SMOSettings(1e-3, 1e-7, 1e-4)), 2, 2),
        "pendulum": (PendulumDiagnoser(), 3, 1),
        "walcott_zak": (walcott_zak_smo(A, Bw, C, G, 1.0, SMOSettings(1e-3, 1e-5, 1e-3)), 2, 1),
        "utkin": (utkin_smo(Au, np.array([[0.0], [0.0], [1.0]]), [[1.0, 0.0, 1.0]], [20.0], [-2.0, -3.0],
                            SMOSettings(1e-3, 1e-5, 1e-4)), 1, 1),
    }
    for name, (obs, p, m) in observers.items():
        k = [0]
        y = np.ones(p)
        u = np.zeros(m)
        obs.reset()

        def call(obs=obs, y=y, u=u, k=k):
            k[0] += 1
            obs.update(y * np.sin(1e-3 * k[0]), u)

        inner = getattr(obs, "smo", obs)
        inner = getattr(inner, "smfo", inner)
        nsub = inner.nsub
        n_calls = max(3, int(2e5 / nsub))
        med, mn = _time(call, n_calls, 3)
        rows.append((f"update/{name}", med, mn, f"nsub = {nsub}, {med / (nsub * step):.2f}× nsub × kernel/step"))
    print(f"{'what':32s} {'µs':>12s} {'(min)':>12s}  note")
    for what, med, mn, note in rows:
        print(f"{what:32s} {med:12.4g} {mn:12.4g}  {note}")


if __name__ == "__main__":
    main()
