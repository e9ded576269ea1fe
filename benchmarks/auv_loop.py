"""Speed benchmark of the AUV closed loop (robofdi.sims.auv at 50 Hz control, 200 Hz physics) and of the allocators.

Run from the repository root::

    PYTHONPATH=. python benchmarks/auv_loop.py        # the table (about 30 s)

What is measured (time.perf_counter, µs per call; median over repeats after a warm-up; "(min)" the fastest repeat):

* ``mj_step``          raw ``mujoco.mj_step`` on assets/auv.xml (one 5 ms physics step).
* ``sim.step``         ``AuvSimulator.step``: 4 physics steps + explicit damping/current + 8 motor models + sensors.
* ``controller``       the task-space law eq. (8) (nominal Fossen model, B⁺).
* ``alloc/<method>``   one allocation of a random wrench (σ = 20 N / N·m), with thruster 2 and 6 failed:
                       pseudo_inverse, column_deletion, constrained (QP only when a limit binds), and
                       constrained on wrenches that saturate (σ = 80, the clarabel QP solved every call).
* ``update/<scheme>``  one diagnoser update on recorded fault-free data.
* ``loop``             ``ClosedLoop.run`` of the ch4-auv configuration (all three diagnosers, constrained
                       allocation, recording), 60 s simulated; µs per control tick and the real-time factor
                       RTF = simulated / wall time. ``loop/mj_step`` = µs per tick / (4 × mj_step).
"""
from __future__ import annotations

import statistics
import time
from dataclasses import replace

import mujoco
import numpy as np


def _time(fn, n: int, repeats: int = 5) -> tuple[float, float]:
    fn()
    runs = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        runs.append((time.perf_counter() - t) / n * 1e6)
    return statistics.median(runs), min(runs)


def main() -> None:
    from robofdi.control.auv import TaskSpaceAuvControl
    from robofdi.ftc.allocation import column_deletion_allocation, constrained_allocation, pseudo_inverse_allocation
    from robofdi.loop import Diagnosis, diagnose_record
    from robofdi.systems.auv import AuvScenario, build_loop, calibrate, odin_mission

    sc = AuvScenario(duration=60.0, calibration_runs=1, calibration_duration=60.0)
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    rows = []
    m, d = sim.model, sim.data
    sim.reset(sc.start_pose, seed=0)
    rows.append(("mj_step", *_time(lambda: mujoco.mj_step(m, d), 2000)))
    sim.reset(sc.start_pose, seed=0)
    u = np.full(8, 3.0)
    rows.append(("sim.step", *_time(lambda: sim.step(u), 500)))
    ctl = TaskSpaceAuvControl(model)
    y = sim.reset(sc.start_pose, seed=0)
    ref = odin_mission(60.0)(10.0)
    rows.append(("controller", *_time(lambda: ctl.update(y, ref), 2000)))
    g = np.random.default_rng(0)
    e = np.ones(8)
    e[[1, 5]] = 0.0
    B = model.B
    def allocator(fn, taus):
        state = {"k": 0}

        def call():
            state["k"] += 1
            return fn(taus[state["k"] % len(taus)])
        return call

    normal, saturating = g.normal(0, 20.0, (200, 6)), g.normal(0, 80.0, (200, 6))
    rows.append(("alloc/pseudo_inverse", *_time(allocator(lambda t: pseudo_inverse_allocation(B, t, e), normal), 200)))
    rows.append(("alloc/column_deletion", *_time(allocator(lambda t: column_deletion_allocation(B, t, [1, 5]), normal), 200)))
    rows.append(("alloc/constrained", *_time(allocator(lambda t: constrained_allocation(B, t, -40, 40, e), normal), 200)))
    rows.append(("alloc/constrained (saturating)",
                 *_time(allocator(lambda t: constrained_allocation(B, t, -40, 40, e), saturating), 200)))

    cal = calibrate(sc)
    loop = build_loop(sc, cal)
    record = loop.run(20.0, sc.start_pose, seed=1)
    n = len(record.time)
    for name, diag in loop.diagnoses.items():
        replay = (lambda d: lambda: diagnose_record(record, Diagnosis(d)))(diag.diagnoser)
        rows.append((f"update/{name}", *[v / n for v in _time(replay, 1, 3)]))
    loop = build_loop(replace(sc, duration=60.0), cal)
    t = time.perf_counter()
    loop.run(60.0, sc.start_pose, seed=2)
    wall = time.perf_counter() - t
    ticks = int(60.0 / sc.plant.control_dt) + 1
    per_tick = wall / ticks * 1e6
    rows.append(("loop (per control tick)", per_tick, per_tick))
    mj = rows[0][1]
    print(f"{'what':34s} {'µs/call':>10s} {'(min)':>10s}")
    for name, med, mn in rows:
        print(f"{name:34s} {med:10.1f} {mn:10.1f}")
    print(f"loop RTF (simulated / wall): {60.0 / wall:.1f}")
    print(f"loop/mj_step ratio (µs per tick / (4 × mj_step)): {per_tick / (4 * mj):.1f}")


if __name__ == "__main__":
    main()
