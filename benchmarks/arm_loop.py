"""Speed benchmark of the arm closed loop: where does the wall time of one 1 kHz control tick go?

Run from the repository root::

    PYTHONPATH=. python benchmarks/arm_loop.py            # the table (about 20 s)
    PYTHONPATH=. python benchmarks/arm_loop.py --profile  # also cProfile loop (b), top robofdi functions

What is measured (time.perf_counter, µs per call; every figure is the median over several repeats of a
timed block after an untimed warm-up repeat; the "(min)" column is the fastest repeat — when it is far
below the median, something else was using the CPU):

* ``mj_step``     raw ``mujoco.mj_step`` on assets/arm6.xml (0.5 ms physics step, contacts off, Coulomb
                  friction on), started from states of a recorded closed-loop run with its recorded torque.
* ``pin.rnea``    Pinocchio inverse dynamics on the nominal model (ManipulatorModel), random q, v, a.
* ``pin.aba``     Pinocchio forward dynamics on the nominal model, random q, v, tau.
* ``update/<s>``  ``update(y, u)`` of each diagnoser from ``arm_schemes``, fed with the y and ū of a
                  pre-recorded fault-free closed-loop run (θ₀ of the adaptive scheme from
                  ``ripple_initial_parameters``, as ``scenarios.arm.calibrate`` does), after a warm-up of
                  50 samples so every estimator is in its normal regime. "per tick" is half the update
                  cost: the diagnosers run at 500 Hz, on every 2nd control tick.
* ``piece/...``   the other pieces of one tick of ``ClosedLoop.run``, each in isolation: simulator step
                  (2 physics steps + ripple term + measurement: the compiled kernels of robofdi.sims.kernels),
                  computed-torque controller, reference (read ahead as the loop does, ``sample``),
                  fault injector (no faults), threshold decision, and the DiagnosisRunner's own
                  bookkeeping per tick (with a stub diagnoser).
* ``loop (a/b/c)`` ``ClosedLoop.run`` over 2 s of simulated time (2000 control ticks, no faults), wall
                  time / 2000: (a) no diagnoser, (b) the adaptive diagnoser with its ThresholdDecision
                  (thresholds 1e9, so no alarm), (m) the momentum observer with its decision, (c) the six
                  book schemes, each with its ThresholdDecision, (d) every arm scheme (the six and the
                  consistency scheme, its design learnt from the pre-recorded run) with its decision.
                  Includes everything ``run`` does: recording every signal, building the Record at the
                  end. The repeats go round-robin over (a), (b), (c). ``RTF`` = simulated seconds / wall
                  seconds (> 1: faster than real time).

"where the time of a tick goes" splits each loop into the isolated pieces. The "in-loop excess" is what
the loop costs beyond the sum of its isolated pieces: the same Python/numpy code runs slower when it is
interleaved with MuJoCo, Pinocchio and the other pieces (colder caches; measured ~+30 % on the adaptive
update) than in a tight loop of itself — plus measurement noise.

The floor is the raw model cost of one control tick: 2 × mj_step (2 physics steps per tick) + 1 rnea (the
controller's inverse dynamics) + 1 aba (a diagnoser's forward dynamics). ``loop/floor`` says how many
times slower the loop is than that floor, i.e. the Python overhead factor; the very last line,
``loop/floor ratio: R``, is for loop (b); the one before, ``all-diagnosers loop/floor ratio: R``, for
loop (d). Each ratio is the median over the loop rounds of the loop's time over the floor timed in the same
round (``time_loops``): the raw mj_step alone ran at 4.8 µs and at 6.8–7.1 µs on the same idle VM minutes apart,
while the loops did not move, so a floor timed once before the loops moved the ratios by 40 % (3.2 against 4.4).
Absolute numbers depend on the machine and its load; the ratios travel better.
"""
from __future__ import annotations

import argparse
import gc
import os
import statistics
import sys
import time

import mujoco
import numpy as np
import pinocchio as pin

import robofdi
from robofdi.control import ComputedTorque
from robofdi.decision import ThresholdDecision
from robofdi.control import Quintic
from robofdi.faults import FaultInjector
from robofdi.loop import ClosedLoop, Diagnosis, DiagnosisRunner, Rates, diagnose_record, diagnoser_inputs
from robofdi.observers import DiagnosticObserver
from robofdi.observers.arm_schemes import BOOK_SCHEMES as SCHEMES
from robofdi.observers.arm_schemes import SCHEMES as ALL_SCHEMES
from robofdi.observers.arm_schemes import arm_schemes, scheme_calibration
from robofdi.observers.spectral import ripple_initial_parameters
from robofdi.systems.arm import ArmScenario
from robofdi.sims import ArmSimulator, SensorModel, StribeckFriction, TorqueRipple

# The book's motion (experiments/ch3_industrial_robot.py): q0 → q0 + Δq in 4 s.
Q0 = (np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0)
DQ = (np.pi / 4, np.pi / 4, -np.pi / 4, 0.0, -np.pi / 2, np.pi / 2)
LOOP_SECONDS = 2.0           # simulated time per timed closed-loop run
CLOCK = time.perf_counter    # --clock cpu: time.process_time (this process's CPU time; steadier on a loaded machine)
RECORD_SECONDS = 2.0         # pre-recorded run that feeds the diagnosers


class Timing(float):
    """µs per call: the median of the repeats (it is a float); ``.min`` the fastest repeat."""

    def __new__(cls, samples):
        obj = super().__new__(cls, statistics.median(samples))
        obj.min = min(samples)
        return obj


def bench(fn, number: int, repeats: int, setup=None) -> Timing:
    """Median over ``repeats`` of (time of ``fn()`` called ``number`` times) / number, in µs.

    ``fn`` is called as ``fn(i)`` with i = 0..number-1 so it can walk through pre-built inputs;
    ``setup()`` (untimed) runs before every repeat; one untimed warm-up repeat comes first.
    """
    samples = []
    for rep in range(repeats + 1):
        if setup is not None:
            setup()
        gc.collect()
        t0 = CLOCK()
        for i in range(number):
            fn(i)
        dt = CLOCK() - t0
        if rep:                       # repeat 0 is the warm-up
            samples.append(dt / number * 1e6)
    return Timing(samples)


def previous_harness() -> ArmSimulator:
    """arm6 as the plant was before the honest harness: ideal sensors, ripple of eq. (50)'s class only (one
    harmonic plus the load term), no Stribeck term — to time the loop machinery like for like."""
    return ArmSimulator("arm6.xml", ripple=TorqueRipple(harmonics=(0.0, 0.0), transmission=0.0),
                        sensors=SensorModel.ideal(), friction=StribeckFriction(breakaway=0.0))


def build_loop(scenario: ArmScenario, diagnoser_names=(), theta0=None, sim=None, designs=None) -> ClosedLoop:
    """The loop of ``scenarios.arm.build_loop`` / ``run_scenario``: fault-free, online injection, the honest
    harness (ripple harmonics, Stribeck friction, encoder quantisation and velocity noise) unless ``sim``."""
    sim = sim or scenario.simulator()
    model = scenario.nominal_model(sim)
    controller = ComputedTorque(model, torque_limit=sim.torque_limit)
    diagnoses = {}
    if diagnoser_names:
        settings = scenario.scheme_settings(scenario.rates)
        for name, d in arm_schemes(model, settings, theta0, diagnoser_names, designs=designs).items():
            decision = ThresholdDecision(d.components, np.full(len(d.components), 1e9), d.signatures())
            diagnoses[name] = Diagnosis(d, decision)
    return ClosedLoop(sim, controller, scenario.motion, (), diagnoses, scenario.rates, scenario.injection)


def time_loops(loops: dict, q0, repeats: int, floor=None) -> tuple[dict, dict]:
    """Median wall µs per control tick of ``loop.run(LOOP_SECONDS)`` for each loop, and the median over the
    repeats of each loop's ratio to ``floor()`` (µs per tick, timed in the same repeat). One short warm-up run
    each, then the repeats go round-robin over the floor and the loops, so that a change of the machine's speed
    (load elsewhere, a shared host: the raw mj_step was measured at 4.8 and at 6.8 µs minutes apart on the 2-core
    VM, idle) hits the floor and the loops alike."""
    for loop in loops.values():
        loop.run(0.1, q0)
    samples = {key: [] for key in loops}
    floors = []
    for _ in range(repeats):
        if floor is not None:
            floors.append(floor())
        for key, loop in loops.items():
            ticks = int(round(LOOP_SECONDS * loop.rates.control_hz))
            gc.collect()
            t0 = CLOCK()
            loop.run(LOOP_SECONDS, q0)
            samples[key].append((CLOCK() - t0) / ticks * 1e6)
    ratios = {key: statistics.median(t / f for t, f in zip(v, floors)) for key, v in samples.items()} if floors else {}
    if floors:
        ratios["floor"] = Timing(floors)
    return {key: Timing(v) for key, v in samples.items()}, ratios


class _StubDiagnoser:
    """Looks like ``like`` to a DiagnosisRunner but returns a fixed residual: isolates the runner's own cost."""

    def __init__(self, like, residual):
        self.components, self.estimate_components = like.components, like.estimate_components
        self.estimate_modes, self._res = like.estimate_modes, residual
        self.inputs, self.measurements, self.units = like.inputs, like.measurements, like.units

    def signatures(self):
        return []

    def reset(self):
        pass

    def update(self, y, u):
        return self._res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", action="store_true", help="cProfile loop (b) and list the top robofdi functions")
    ap.add_argument("--repeats", type=int, default=11, help="repeats of each micro-benchmark (default 11)")
    ap.add_argument("--loop-repeats", type=int, default=7, help="repeats of each closed-loop run (default 7)")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="wall time (time.perf_counter, default) or this process's CPU time (time.process_time)")
    args = ap.parse_args(argv)
    global CLOCK
    CLOCK = time.process_time if args.clock == "cpu" else time.perf_counter
    R, LR = args.repeats, args.loop_repeats
    t_start = time.perf_counter()

    scenario = ArmScenario("benchmark", motion=Quintic(Q0, DQ, 4.0), duration=LOOP_SECONDS, rates=Rates(1000.0, 500.0))
    ratio = scenario.rates.ratio
    rows: list[tuple[str, float, str]] = []   # (name, µs per call, note)

    # ---- a pre-recorded fault-free run: realistic states, torques, diagnoser inputs, and θ₀ -------------
    rec_loop = build_loop(scenario)
    record = rec_loop.run(RECORD_SECONDS, Q0, seed=1)   # seeded: an unseeded run sometimes left joint 4 without a
    # velocity change for the consistency design (identify_skew failed, about 1 run in 3)
    model = rec_loop.controller.model
    settings = scenario.scheme_settings(scenario.rates)
    n, T = model.n, settings.T
    skip = int(np.ceil(0.010 / T))
    simple = diagnose_record(record, Diagnosis(DiagnosticObserver(model, T, residual_space="state")))
    theta0 = ripple_initial_parameters(record.signals["y_meas"][::ratio][skip:, :n], simple.residual[skip:, n:])
    y_all, u_all = record.signals["y_meas"], record.signals["u_diag"]
    # diagnoser samples k: y = y(k·ratio), ū = mean of the commands over the interval that just ended
    feed = [(y_all[j], np.mean(u_all[j - ratio:j], axis=0)) for j in range(ratio, len(y_all), ratio)]

    # ---- raw MuJoCo ------------------------------------------------------------------------------------
    mj_model = mujoco.MjModel.from_xml_path(str(robofdi.ASSETS / "arm6.xml"))
    mj_data = mujoco.MjData(mj_model)
    states = record.truth_state
    u_rec = record.signals["u"]
    start = iter(range(10**9))

    def mj_setup():
        k = (next(start) * 397) % (len(states) - 1)
        mujoco.mj_resetData(mj_model, mj_data)
        mj_data.qpos[:], mj_data.qvel[:] = states[k, :n], states[k, n:]
        mj_data.ctrl[:] = u_rec[k]
        mujoco.mj_forward(mj_model, mj_data)

    mj_step = mujoco.mj_step
    t_mj = bench(lambda i: mj_step(mj_model, mj_data), 400, R, mj_setup)
    rows.append(("mj_step (raw, 0.5 ms physics step)", t_mj, ""))

    # ---- raw Pinocchio ---------------------------------------------------------------------------------
    pm, pd = model.model, model.data
    rng = np.random.default_rng(0)
    K = 256
    qs = [pin.randomConfiguration(pm) for _ in range(K)]
    vs = [rng.standard_normal(n) for _ in range(K)]
    taus = [rng.standard_normal(n) * 50 for _ in range(K)]
    t_rnea = bench(lambda i: pin.rnea(pm, pd, qs[i % K], vs[i % K], taus[i % K]), 2000, R)
    t_aba = bench(lambda i: pin.aba(pm, pd, qs[i % K], vs[i % K], taus[i % K]), 2000, R)
    rows.append(("pin.rnea (nominal model)", t_rnea, ""))
    rows.append(("pin.aba  (nominal model)", t_aba, ""))
    t_floor = 2 * t_mj + t_rnea + t_aba

    # ---- diagnosers' update(y, u) ----------------------------------------------------------------------
    warm = 50
    number = min(400, len(feed) - warm)
    t_update = {}
    for name in SCHEMES:
        d = arm_schemes(model, settings, theta0, [name])[name]

        def setup(d=d):
            d.reset()
            for y, u in feed[:warm]:
                d.update(y, u)

        upd = d.update
        t_update[name] = bench(lambda i, upd=upd: upd(*feed[warm + i]), number, R, setup)
        rows.append((f"update/{name}", t_update[name], f"per tick {t_update[name] / ratio:7.1f} µs"))

    # ---- the other pieces of one loop tick, in isolation ----------------------------------------------
    sim = rec_loop.simulator
    ctrl, ref_fn = rec_loop.controller, rec_loop.reference
    inj = FaultInjector([], sim.actuators, sim.sensor_channels, 0, component_kinds=sim.component_kinds)
    ys = record.signals["y_true"]
    ts = record.time
    refs = [ref_fn(t) for t in ts]

    def sim_setup():
        sim.reset(np.asarray(Q0))

    t_sim = bench(lambda i: sim.step(u_rec[i]), 400, R, sim_setup)
    rows.append(("piece/ArmSimulator.step (2 mj_step + ripple)", t_sim, ""))
    t_ctrl = bench(lambda i: ctrl.update(ys[i], refs[i]), 1000, R)
    rows.append(("piece/ComputedTorque.update (rnea)", t_ctrl, ""))
    ahead = {}

    def ref_ahead(i):                  # as the loop reads it: sample() a block of ticks ahead, then one row per tick
        k = i % 1000
        if k == 0:
            ahead["q"], ahead["v"], ahead["a"] = ref_fn.sample(list(ts[i:i + 1000]))
        return ahead["q"][k], ahead["v"][k], ahead["a"][k]

    t_ref = bench(ref_ahead, 1000, R)
    t_call = bench(lambda i: ref_fn(ts[i]), 1000, R)
    rows.append(("piece/reference, read ahead (sample)", t_ref, f"called every tick: {t_call:.1f} µs"))
    t_inj = bench(lambda i: (inj.sense(ts[i], ys[i]), inj.actuate(ts[i], u_rec[i])), 1000, R)
    rows.append(("piece/FaultInjector sense+actuate (no faults)", t_inj, ""))
    d_ad = arm_schemes(model, settings, theta0, ["adaptive"])["adaptive"]
    dec = ThresholdDecision(d_ad.components, np.full(2 * n, 1e9), d_ad.signatures())
    res = [d_ad.update(y, u) for y, u in feed[:200]]
    t_dec = bench(lambda i: dec.update(res[i % 200].r), 1000, R)
    rows.append(("piece/ThresholdDecision.update (no alarm)", t_dec, f"per tick {t_dec / ratio:7.1f} µs"))
    runner = DiagnosisRunner(Diagnosis(_StubDiagnoser(d_ad, res[-1])), scenario.rates)
    t_run = bench(lambda i: runner.push(i + 1, ts[i], ys[i], u_rec[i]), 1000, R, runner.reset)
    rows.append(("piece/DiagnosisRunner.push, own cost per tick", t_run, "mean of ū, identification, trace rows"))

    # ---- the full closed loop --------------------------------------------------------------------------
    # the consistency scheme's learnt design, from the pre-recorded run (what calibration learns from its motions)
    designs = {"consistency": scheme_calibration("consistency", settings).design(
        model, [diagnoser_inputs(record, scenario.rates)], settings, skip)}
    loops = {
        "a": ("loop (a) no diagnoser", build_loop(scenario)),
        "b": ("loop (b) adaptive + decision", build_loop(scenario, ("adaptive",), theta0)),
        "m": ("loop (m) momentum + decision", build_loop(scenario, ("momentum",), theta0)),
        "c": ("loop (c) all six + decisions", build_loop(scenario, SCHEMES, theta0)),
        "d": ("loop (d) all seven arm schemes", build_loop(scenario, ALL_SCHEMES, theta0, designs=designs)),
        "a0": ("loop (a0) = (a), previous harness", build_loop(scenario, sim=previous_harness())),
        "b0": ("loop (b0) = (b), previous harness", build_loop(scenario, ("adaptive",), theta0, previous_harness())),
    }

    def floor() -> float:           # one floor measurement beside each round of loops (time_loops)
        return (2 * bench(lambda i: mj_step(mj_model, mj_data), 400, 1, mj_setup)
                + bench(lambda i: pin.rnea(pm, pd, qs[i % K], vs[i % K], taus[i % K]), 2000, 1)
                + bench(lambda i: pin.aba(pm, pd, qs[i % K], vs[i % K], taus[i % K]), 2000, 1))

    t_loop, ratio_of = time_loops({key: loop for key, (_, loop) in loops.items()}, Q0, LR, floor)
    for key, (label, _loop) in loops.items():
        rows.append((label + ", per tick", t_loop[key], f"RTF {1e3 / t_loop[key]:5.2f}"))

    # ---- report ----------------------------------------------------------------------------------------
    print(__doc__.splitlines()[0])
    print(f"python {sys.version.split()[0]}, mujoco {mujoco.__version__}, pinocchio {pin.__version__}, "
          f"numpy {np.__version__}; control {scenario.rates.control_hz:g} Hz, diagnosis "
          f"{scenario.rates.diagnosis_hz:g} Hz, physics {1 / sim.physics_dt:g} Hz ({sim.substeps} substeps/tick)")
    print(f"clock: {args.clock}; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print(f"µs per call: median (and fastest) of {R} repeats, {LR} interleaved repeats of {LOOP_SECONDS:g} s for the loops")
    print()
    w = max(len(r[0]) for r in rows)
    print(f"{'what':<{w}}  {'median':>8}  {'(min)':>8}  note")
    print("-" * (w + 60))
    for name, us, note in rows:
        print(f"{name:<{w}}  {us:8.2f}  {us.min:8.2f}  {note}")
    print("-" * (w + 60))
    print()
    print("real-time factor (simulated s / wall s):")
    for key, (label, _) in loops.items():
        print(f"  {label:<30} {1e3 / t_loop[key]:6.2f}")
    print()
    pieces_a = t_sim + t_ctrl + t_ref + t_inj
    print("where the time of a tick goes (µs, medians):")
    print(f"  loop (a) {t_loop['a']:.1f} = sim.step {t_sim:.1f} + controller {t_ctrl:.1f} + reference {t_ref:.1f} "
          f"+ injector {t_inj:.1f} + rest {t_loop['a'] - pieces_a:.1f} (recording, loop body, Record)")
    diag_b = (t_update["adaptive"] + t_dec) / ratio + t_run
    print(f"  loop (b) - (a) = {t_loop['b'] - t_loop['a']:.1f}; isolated: (update {t_update['adaptive']:.1f} + decision "
          f"{t_dec:.1f}) / {ratio} + runner {t_run:.1f} = {diag_b:.1f}; in-loop excess "
          f"{t_loop['b'] - t_loop['a'] - diag_b:.1f}")
    diag_c = sum(t_update.values()) / ratio + len(SCHEMES) * (t_dec / ratio + t_run)
    print(f"  loop (c) - (a) = {t_loop['c'] - t_loop['a']:.1f}; isolated: six updates, decisions and runners "
          f"= {diag_c:.1f}; in-loop excess {t_loop['c'] - t_loop['a'] - diag_c:.1f}")
    print()
    print(f"floor per control tick = 2 x mj_step + rnea + aba = 2 x {t_mj:.2f} + {t_rnea:.2f} + {t_aba:.2f} "
          f"= {t_floor:.2f} µs alone, before the loops; {ratio_of['floor']:.2f} µs (fastest {ratio_of['floor'].min:.2f}) "
          f"timed beside them")
    print(f"the ratios below: the median over the {LR} rounds of each loop over the floor timed in the same round")
    print(f"[benchmark wall time {time.perf_counter() - t_start:.1f} s]")
    if args.profile:
        profile_loop(loops["b"][1])
    print(f"loop/floor ratio (a): {ratio_of['a']:.2f}")
    print(f"loop/floor ratio (c): {ratio_of['c']:.2f}")
    print(f"loop/floor ratio (b0), the previous harness's plant: {ratio_of['b0']:.2f}")
    print(f"momentum loop/floor ratio (m): {ratio_of['m']:.2f}")
    print(f"all-diagnosers loop/floor ratio: {ratio_of['d']:.2f}")
    print(f"loop/floor ratio: {ratio_of['b']:.2f}")
    return 0


def profile_loop(loop: ClosedLoop, top: int = 8) -> None:
    """cProfile one run of loop (b); print the top robofdi functions by cumulative time."""
    import cProfile
    import pstats

    prof = cProfile.Profile()
    prof.enable()
    loop.run(LOOP_SECONDS, Q0)
    prof.disable()
    stats = pstats.Stats(prof)
    ticks = LOOP_SECONDS * loop.rates.control_hz
    entries = [(func, st) for func, st in stats.stats.items() if "robofdi" in func[0]]
    entries.sort(key=lambda e: e[1][3], reverse=True)
    print()
    print(f"cProfile of loop (b), {ticks:g} ticks (profiler overhead inflates everything); top {top} robofdi "
          f"functions by cumulative time:")
    print(f"  {'cum ms':>8} {'µs/tick':>8} {'calls':>7}  function")
    for (file, line, fn), (_cc, nc, _tt, ct, _callers) in entries[:top]:
        short = file[file.rfind("robofdi"):]
        print(f"  {ct * 1e3:8.1f} {ct / ticks * 1e6:8.2f} {nc:7d}  {short}:{line}({fn})")
    print()
    print("  top 12 functions overall by own (tottime) time:")
    flat = sorted(stats.stats.items(), key=lambda e: e[1][2], reverse=True)[:12]
    for (file, line, fn), (_cc, nc, tt, _ct, _callers) in flat:
        short = file[file.rfind("robofdi"):] if "robofdi" in file else file.split("/")[-1]
        print(f"  {tt * 1e3:8.1f} ms {nc:7d}  {short}:{line}({fn})")
    print()


if __name__ == "__main__":
    raise SystemExit(main())
