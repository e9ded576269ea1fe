"""Arm scenarios: one configuration → simulator, nominal model, controller, faults and calibrated diagnoses.

The steps a scenario runs (each usable on its own):

1. :func:`calibration_records` — fault-free closed-loop runs on worst-case motions (Caccavale & Villani Sec. 6:
   very low velocities; high accelerations and wide displacements), derived from the robot's joint ranges and
   torque limits (:func:`robofdi.control.calibration_motions`) unless the scenario gives its own, and checked to
   stay inside the joint and torque limits. Their sensor noise comes from streams of their own (run keys
   ``calibration/<name>``), never the test run's.
2. :func:`calibrate` — the adaptive scheme's ripple parameters by spectral analysis, then per scheme the
   thresholds ρ_i = margin · max |r_i| over the calibration runs (each diagnoser replayed offline), ignoring the
   same start-up samples the in-loop decision blanks. :func:`calibration` caches the result per robot and seed.
3. :func:`run_scenario` — the scenario's closed-loop run with every diagnosis in the loop, optionally with
   fault compensation fed by a diagnoser's health (or by the oracle, for a bound).

The system (:class:`ArmSystem`, registered as ``arm``: its options, fault targets, calibration per robot instance,
missions drawn from a seed and runs; :class:`robofdi.protocols.System`) closes the module.
"""
from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from robofdi.calibration import cached
from robofdi.checks import check_fields, check_robot_seeds, is_int, is_number
from robofdi.config import check_not_set, compose, part
from robofdi.control import ComputedTorque, MotionLimits, calibration_motions, random_point_to_point
from robofdi.decision import (
    STARTUP_BLANKING,
    ThresholdDecision,
    calibrate_thresholds,
    extreme_value_thresholds,
    startup_samples,
)
from robofdi.errors import RobofdiError
from robofdi.faults import Fault, check_faults, parse_fault_specs
from robofdi.ftc import FaultCompensation
from robofdi.loop import ORACLE, ClosedLoop, Diagnosis, Rates, diagnose_record, diagnoser_inputs
from robofdi.mjcf import model_xml
from robofdi.models import ManipulatorModel, ModelMismatch
from robofdi.observers import DiagnosticObserver
from robofdi.observers.arm_schemes import (ALL_SCHEMES, BOOK_SCHEMES, SCHEMES, ArmSchemeSettings, arm_schemes, row_tails,
                                         scheme_calibration)
from robofdi.observers.spectral import ripple_initial_parameters
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.record import Record
from robofdi.seeding import rng
from robofdi.sims import ArmSimulator
from robofdi.sims.arm import ArmPlant
from robofdi.systems import RobotInstances, register_system

__all__ = ["ArmScenario", "ArmOptions", "ArmMissions", "ARM_MISMATCH", "arm_scenario", "Calibration",
           "CALIBRATION_SEGMENTS", "ENVELOPE_MOTIONS",
           "calibration_trajectories", "calibration_records", "calibrate",
           "calibration", "parts", "run_scenario", "build_loop", "check_scenario"]

ACCOMMODATIONS = (None, "compensation")
#: The diagnosers' belief of an arm by default: 2 % mass and inertia, 5 % damping errors (seeded per robot instance).
ARM_MISMATCH = ModelMismatch(mass=0.02, inertia=0.02, damping=0.05)
#: The span [rad] a continuous joint's (no range) position and velocity sensor faults are sized on in a campaign
#: (``magnitude_fraction``): one turn.
CONTINUOUS_JOINT_SPAN = 2 * np.pi
#: Schemes whose thresholds are also calibrated in the book's state space (reported next to the book's).
STATE_SPACE_SCHEMES = ("time_delayed", "recursive")


@dataclass(frozen=True)
class ArmScenario:
    """Everything that defines one arm run, composed (:mod:`robofdi.config`) of the simulator's configuration
    ``plant`` (:class:`~robofdi.sims.arm.ArmPlant`: robot file, joints, drives, ripple, sensors, payload), the
    nominal model's ``mismatch`` (:class:`~robofdi.models.ModelMismatch`, seeded by ``seed``) and the diagnosis
    ``settings`` (:class:`~robofdi.observers.arm_schemes.ArmSchemeSettings`); :func:`robofdi.config.compose` /
    :func:`~robofdi.config.evolve` name their fields flat (``evolve(sc, robot="ur5e.xml", payload=1.0)``).

    ``motion``: the reference, a trajectory giving (q_d, q̇_d, q̈_d) with an ``end`` [s]; the run starts at rest
    at its first pose. ``duration`` None = motion end + 1 s. ``seed`` draws the robot's ripple phases and the
    nominal-model errors, and the runs' sensor noise (each from its own stream); the same seed gives the same
    record. ``rates`` None: control at the simulator's control period (≈ 1 kHz, a multiple of the physics step
    of the file), diagnosis at 500 Hz where that divides the control rate, else at the control rate.
    ``calibration``: fault-free calibration motions by name; None derives them from the robot, over the
    operating envelope the runs declare: ``envelope_speed`` and ``envelope_segments`` (as :class:`ArmMissions`;
    faster than "normal" or more than :data:`CALIBRATION_SEGMENTS` segments adds :data:`ENVELOPE_MOTIONS`
    random motions like them, :func:`calibration_trajectories`).
    ``accommodation``: None or "compensation" (subtract the identified
    actuator fault after isolation) with health from ``health_source`` (a scheme name or "oracle").
    ``nominal_payload`` [kg]: a load the user declares (a tool or part the robot file lacks), carried by the
    nominal model at the payload point: the calibration motions are planned with it and the controller
    compensates it. The plant's own ``payload`` is the truth; the two are set separately (0 and 0 by default).
    """

    name: str
    motion: object
    duration: float | None = None
    faults: tuple = ()
    injection: str = "online"
    plant: ArmPlant = part(ArmPlant)
    mismatch: ModelMismatch = part(ModelMismatch, lambda: ARM_MISMATCH)
    seed: int = 0
    rates: Rates | None = None
    schemes: tuple = BOOK_SCHEMES
    settings: ArmSchemeSettings = part(ArmSchemeSettings)
    threshold_margin: float = 1.2
    startup_blanking: float = STARTUP_BLANKING
    calibration: Mapping | None = None
    envelope_speed: Any = "normal"
    envelope_segments: int = 1
    accommodation: str | None = None
    health_source: str | None = None
    nominal_payload: float = 0.0

    def __post_init__(self):
        if not all(isinstance(f, Fault) for f in self.faults):
            raise RobofdiError("ArmScenario: field 'faults' must hold Fault objects")
        for name, kind in (("plant", ArmPlant), ("mismatch", ModelMismatch), ("settings", ArmSchemeSettings)):
            if not isinstance(getattr(self, name), kind):
                raise RobofdiError(f"ArmScenario: field {name!r} must be a {kind.__name__}, got {getattr(self, name)!r}")
        object.__setattr__(self, "faults", tuple(self.faults))
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise RobofdiError(f"ArmScenario: field 'seed' must be an integer >= 0, got {self.seed!r}")
        if not callable(self.motion) or not hasattr(self.motion, "end"):
            raise RobofdiError("ArmScenario: field 'motion' must be a trajectory (t -> (q, q̇, q̈), with .end)")
        if self.duration is not None and not (np.isfinite(self.duration) and self.duration > 0):
            raise RobofdiError(f"ArmScenario: field 'duration' must be None or > 0 s, got {self.duration}")
        object.__setattr__(self, "schemes", tuple(self.schemes))
        check_fields("ArmScenario", self, [
            ("injection", self.injection in ("online", "offline"), "'online' or 'offline'"),
            ("schemes", len(self.schemes) > 0, f"a non-empty subset of {list(ALL_SCHEMES)}"),
            ("threshold_margin", is_number(self.threshold_margin) and self.threshold_margin >= 1, "a number >= 1"),
            ("startup_blanking", is_number(self.startup_blanking) and 0 <= self.startup_blanking < self.run_duration,
             "a time in [0, run duration) s"),
            ("rates", self.rates is None or isinstance(self.rates, Rates), "None or a Rates"),
            ("envelope_speed", _is_speed(self.envelope_speed), "one of ['fast', 'normal', 'slow'] or a number >= 1"),
            ("envelope_segments", is_int(self.envelope_segments, 1), "an integer >= 1"),
            ("nominal_payload", _is_mass(self.nominal_payload), "a finite mass >= 0 kg"),
        ])
        unknown = [s for s in self.schemes if s not in ALL_SCHEMES]
        if unknown:
            raise RobofdiError(f"ArmScenario: field 'schemes' has unknown scheme(s) {unknown}; "
                               f"expected a subset of {list(ALL_SCHEMES)}")
        if self.accommodation not in ACCOMMODATIONS:
            raise RobofdiError(f"ArmScenario: field 'accommodation' must be one of {list(ACCOMMODATIONS)}, "
                               f"got {self.accommodation!r}")
        if self.accommodation and self.health_source not in (*self.schemes, ORACLE):
            raise RobofdiError(f"ArmScenario: field 'health_source' must be one of {[*self.schemes, ORACLE]} for "
                               f"accommodation, got {self.health_source!r}")
        check_faults(self.faults, duration=self.run_duration)

    @property
    def run_duration(self) -> float:
        return float(self.duration) if self.duration is not None else float(self.motion.end) + 1.0

    @property
    def start_pose(self) -> np.ndarray:
        return np.asarray(self.motion(0.0)[0], dtype=float)

    def simulator(self) -> ArmSimulator:
        """The truth: the plant in MuJoCo for this scenario's robot instance (seed) and control rate."""
        return self.plant.simulator(self.seed, None if self.rates is None else 1.0 / self.rates.control_hz)

    def nominal_model(self, sim: ArmSimulator) -> ManipulatorModel:
        """The diagnosers' belief: the same file read into Pinocchio, with this scenario's seeded errors and the
        declared load."""
        return sim.nominal_model(replace(self.mismatch, seed=self.seed), self.nominal_payload)

    def loop_rates(self, sim: ArmSimulator) -> Rates:
        if self.rates is not None:
            return self.rates
        control_hz = 1.0 / sim.control_dt
        return Rates(control_hz, default_diagnosis_hz(control_hz))

    def scheme_settings(self, rates: Rates) -> ArmSchemeSettings:
        return replace(self.settings, T=1.0 / rates.diagnosis_hz)


#: Segments of the calibration suite's random motions (:func:`robofdi.control.calibration_motions`).
CALIBRATION_SEGMENTS = 3
#: Random motions added to the calibration suite at the declared envelope's speed and segments, when it is wider
#: than the suite's own (half of them design the learnt schemes, half set their thresholds: :func:`design_split`).
ENVELOPE_MOTIONS = 4


def default_diagnosis_hz(control_hz: float) -> float:
    """The arm's diagnosis rate [Hz] at a control rate: 500 Hz where that divides the control rate, else the
    control rate itself."""
    ratio = control_hz / 500.0
    return 500.0 if ratio >= 1 and abs(ratio - round(ratio)) < 1e-9 else float(control_hz)


def _is_mass(value) -> bool:
    return is_number(value) and value >= 0


def _is_rate(value) -> bool:
    return value is None or (is_number(value) and value > 0)


def _is_speed(value) -> bool:
    from robofdi.control import SPEEDS

    return value in SPEEDS or (isinstance(value, (int, float)) and not isinstance(value, bool) and value >= 1)


def _beyond_suite(speed, segments: int) -> bool:
    """Whether missions of this speed and segments leave what the calibration suite covers ("normal" random
    motions of :data:`CALIBRATION_SEGMENTS` segments; the top-speed motion covers "normal" speeds only)."""
    from robofdi.control import SPEEDS

    factor = SPEEDS[speed][0] if isinstance(speed, str) else float(speed)
    return factor < SPEEDS["normal"][0] or segments > CALIBRATION_SEGMENTS


def calibration_trajectories(scenario: ArmScenario, sim: ArmSimulator | None = None,
                             model: ManipulatorModel | None = None) -> dict:
    """The scenario's fault-free calibration motions: its own, or derived from the robot's ranges and limits,
    with :data:`ENVELOPE_MOTIONS` random motions at the declared envelope's speed and segments when it is wider
    than the suite's (a learnt scheme that needs random motions only), interleaved with the suite's random
    motions so that the design and the held-out halves (:func:`design_split`) both hold some."""
    if scenario.calibration is not None:
        return dict(scenario.calibration)
    sim = sim or scenario.simulator()
    model = model or scenario.nominal_model(sim)
    limits = MotionLimits.from_ranges(sim.joint_range[:, 0], sim.joint_range[:, 1], model.torque_limit)
    rules = [scheme_calibration(s, scenario.settings) for s in scenario.schemes]
    n_random = max((r.random_motions for r in rules), default=0)
    motions = calibration_motions(model, limits, scenario.seed, n_random=n_random,
                                  top_speed=any(r.top_speed for r in rules))
    if not n_random or not _beyond_suite(scenario.envelope_speed, scenario.envelope_segments):
        return motions
    extra = {f"random_envelope_{i}": random_point_to_point(
        model, limits, rng(scenario.seed, "calibration", f"random_envelope_{i}"), scenario.envelope_segments,
        speed=scenario.envelope_speed) for i in range(1, ENVELOPE_MOTIONS + 1)}
    randoms, others = [k for k in motions if k.startswith("random_")], [k for k in motions if not k.startswith("random_")]
    a, b = randoms[:len(randoms) // 2], randoms[len(randoms) // 2:]
    e = list(extra)
    order = [*others, *a, *e[:len(e) // 2], *b, *e[len(e) // 2:]]
    both = motions | extra
    return {k: both[k] for k in order}


def design_split(names) -> tuple[list[str], list[str]]:
    """Calibration motions that design the schemes with a learnt design (:class:`SchemeCalibration`), and those
    held out to set their thresholds: the second half of the ``random_*`` motions (none held out when there are
    fewer than two)."""
    names = list(names)
    randoms = [k for k in names if k.startswith("random_")]
    held = randoms[len(randoms) // 2:] if len(randoms) >= 2 else []
    return [k for k in names if k not in held], held


def _controller(model: ManipulatorModel) -> ComputedTorque:
    return ComputedTorque(model, torque_limit=model.torque_limit)


def _check_inside_limits(name: str, record: Record, sim: ArmSimulator, declared: float = 0.0) -> None:
    """Raise if a calibration run left a joint's range or saturated a motor (``declared`` [kg]: the load the nominal
    model carries, named with the plant's payload when it is less)."""
    q = record.truth_state[:, :sim.n]
    lo, hi = sim.joint_range.T
    if np.any(q < lo) or np.any(q > hi):
        i = int(np.argmax(np.maximum(lo - q, q - hi).max(axis=0)))
        err = float(np.abs(q[:, i] - record.signals["reference"][:, i]).max())
        raise RobofdiError(f"calibration motion {name!r} leaves the joint range of {sim.joint_names[i]!r} "
                           f"[{lo[i]:.4g}, {hi[i]:.4g}] (reached {q[:, i].min():.4g} .. {q[:, i].max():.4g}, tracking "
                           f"error up to {err:.3g}); thresholds would be meaningless")
    if np.any(np.abs(record.signals["u_cmd"]) >= sim.torque_limit):
        i = int(np.argmax((np.abs(record.signals["u_cmd"]) / sim.torque_limit).max(axis=0)))
        carried = f"carries {declared:g} kg of" if declared else "lacks"
        load = (f"; the motions were planned with the nominal model, which {carried} the plant's {sim.payload:g} kg "
                "payload: declare the load (nominal_payload), add it to the robot file, or carry a lighter one (a "
                "slower speed helps the random motions only)" if sim.payload > declared else "")
        raise RobofdiError(f"calibration motion {name!r} saturates the motor of {sim.joint_names[i]!r} (limit "
                           f"{sim.torque_limit[i]:.4g}){load}; thresholds would be meaningless")


def calibration_records(scenario: ArmScenario, progress: Callable[[int], None] | None = None) -> dict[str, Record]:
    """Fault-free closed-loop runs on the calibration motions (no diagnoser in the loop)."""
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    rates = scenario.loop_rates(sim)
    records = {}
    for name, ref in calibration_trajectories(scenario, sim, model).items():
        loop = ClosedLoop(sim, _controller(model), ref, rates=rates)
        records[name] = loop.run(ref.end, np.asarray(ref(0.0)[0]), seed=scenario.seed, run_key=f"calibration/{name}",
                                 scenario=f"calibration:{name}", progress=progress)
        _check_inside_limits(name, records[name], sim, scenario.nominal_payload)
    return records


@dataclass
class Calibration:
    """Calibrated thresholds per scheme (residual space of the scheme), the adaptive model's θ₀, the start-up
    blanking [samples] used for both, the learnt designs by scheme (:class:`SchemeCalibration` ``design``; e.g.
    the consistency scheme's) and evidence levels per scheme (:class:`~robofdi.decision.ThresholdDecision`;
    absent: the thresholds)."""

    thresholds: dict[str, np.ndarray]
    theta0: np.ndarray
    blanking: int
    state_thresholds: dict[str, np.ndarray] = field(default_factory=dict)
    designs: dict[str, Any] = field(default_factory=dict)
    evidence: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def payload(self) -> float:
        """The mass [kg] the consistency scheme's design identified at the payload point beyond the declared load
        (0 without that scheme, or where none entered the design)."""
        design = self.designs.get("consistency")
        return float(design.payload) if design is not None else 0.0


def calibrate(scenario: ArmScenario, records: dict[str, Record],
              progress: Callable[[int], None] | None = None) -> Calibration:
    """θ₀ from the first calibration run's simple residual, the learnt designs from the design motions
    (:func:`design_split`), then thresholds per scheme by its rule (:func:`scheme_calibration`; blanked start-up
    skipped; a designed scheme's on the held-out motions, and for a false-alarm rate on the design motions too)."""
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    rates = scenario.loop_rates(sim)
    settings = scenario.scheme_settings(rates)
    n, T = model.n, settings.T
    skip = startup_samples(T, scenario.startup_blanking)
    first = next(iter(records.values()))
    simple = diagnose_record(first, Diagnosis(DiagnosticObserver(model, T, residual_space="state")), rates, progress)
    theta0 = ripple_initial_parameters(first.signals["y_meas"][::rates.ratio][skip:, :n], simple.residual[skip:, n:])

    rules = {name: scheme_calibration(name, settings) for name in scenario.schemes}
    designing, held = design_split(records)
    designs = {}
    if any(r.design for r in rules.values()):
        inputs = [diagnoser_inputs(records[k], rates) for k in designing]
        designs = {name: r.design(model, inputs, settings, skip) for name, r in rules.items() if r.design}

    evidence = {}

    def thresholds(scheme_settings, names):
        out = {}
        for name in names:
            rule = rules[name]
            runs = [records[k] for k in (held or records)] if rule.design else list(records.values())
            diagnoser = arm_schemes(model, scheme_settings, theta0, [name], designs=designs)[name]
            residuals = [diagnose_record(rec, Diagnosis(diagnoser), rates, progress).residual for rec in runs]
            if rule.thresholds == "false_alarm_rate":       # a rate per hour, fitted on the held-out motions
                out[name] = extreme_value_thresholds(residuals, T, settings.consistency_false_alarm_rate, skip=skip,
                                                     tail=row_tails(settings.consistency_tail, diagnoser))
                if rule.design and held:
                    # the design runs' largest value is a floor, not part of the fit: the rare excursions that set a
                    # bound are in them only (held-out runs alone put robosuite iiwa's joint_1_step at 0.63 of its
                    # bound, 22 of 300 fault-free runs crossed it), but the bounds are tight on them (their largest
                    # value is 1), and fitting the tail to them too raised arm6's dynamic thresholds by 5-40 %
                    # (incipient faults detected on arm6 fast: 29/31 as a floor, 25/31 in the fit)
                    designed = [diagnose_record(records[k], Diagnosis(diagnoser), rates, progress).residual
                                for k in designing]
                    out[name] = np.maximum(out[name], calibrate_thresholds(designed, 1.0, skip))
                    residuals += designed
                # discriminating rows: evidence from their largest fault-free value, designed (1) or held out
                largest = np.maximum(calibrate_thresholds(residuals, 1.0, skip), 1.0)
                chosen = np.isin(diagnoser.components, getattr(diagnoser, "discriminating", ()))
                evidence[name] = np.where(chosen, np.minimum(largest, out[name]), out[name])
            else:
                out[name] = calibrate_thresholds(residuals, scenario.threshold_margin, skip)
        return out

    state_schemes = [s for s in STATE_SPACE_SCHEMES if s in scenario.schemes]
    return Calibration(thresholds(settings, scenario.schemes), theta0, skip,
                       thresholds(replace(settings, residual_space="state"), state_schemes), designs, evidence)


def calibration_steps(scenario: ArmScenario, records_duration: float, rates: Rates,
                      motions: Mapping | None = None) -> int:
    """Progress units of :func:`calibration`: control ticks simulated plus ticks replayed per scheme — exact when
    the calibration ``motions`` are given (each run ticks once per sample, both ends; a scheme with a learnt
    design and margin thresholds replays only the held-out motions), else estimated from their total duration."""
    rules = {s: scheme_calibration(s, scenario.settings) for s in scenario.schemes}
    designed = {s for s, r in rules.items() if r.design and r.thresholds != "false_alarm_rate"}
    replays = 1 + len(scenario.schemes) + len([s for s in STATE_SPACE_SCHEMES if s in scenario.schemes])
    if motions is None:
        return int(records_duration * rates.control_hz) * (1 + replays)
    ticks = {k: int(round(m.end * rates.control_hz)) + 1 for k, m in motions.items()}
    every, held = sum(ticks.values()), sum(ticks[k] for k in design_split(ticks)[1])
    first = next(iter(ticks.values()), 0)
    schemes = [*scenario.schemes, *(s for s in STATE_SPACE_SCHEMES if s in scenario.schemes)]
    return every + first + sum(held or every if s in designed else every for s in schemes)


def _calibration_description(scenario: ArmScenario, sim: ArmSimulator, trajectories: Mapping) -> dict:
    """Everything a calibration depends on: the compiled robot, its seed and harness, rates, schemes and motions
    (:mod:`robofdi.calibration` adds the code)."""
    return {
        "robot": hashlib.sha256(model_xml(sim.path).encode()).hexdigest(),
        "joints": list(sim.joint_names), "torque_motors": scenario.plant.torque_motors, "seed": scenario.seed,
        "ripple": scenario.plant.ripple_mode, "sensors": repr(scenario.plant.sensors), "payload": scenario.plant.payload,
        "mismatch": repr(scenario.mismatch), "rates": repr(scenario.loop_rates(sim)), "settings": repr(scenario.settings),
        "schemes": list(scenario.schemes), "margin": scenario.threshold_margin, "blanking": scenario.startup_blanking,
        "motions": {k: repr(v) for k, v in trajectories.items()},
    } | ({"drive_inertia": float(scenario.plant.drive_inertia)} if scenario.plant.drive_inertia else {}) \
      | ({"nominal_payload": float(scenario.nominal_payload)} if scenario.nominal_payload else {})


def calibration(scenario: ArmScenario, progress: Callable[[int], None] | None = None,
                cache: bool = True) -> tuple[Calibration, bool]:
    """The scenario's calibration, computed once per robot, seed and settings and cached (:mod:`robofdi.calibration`).
    Returns (calibration, True if it came from the cache). The motion under test plays no part in it."""
    sim = scenario.simulator()
    trajectories = calibration_trajectories(scenario, sim)

    def compute() -> Calibration:
        return calibrate(scenario, calibration_records(replace(scenario, calibration=trajectories), progress), progress)

    return cached("arm", _calibration_description(scenario, sim, trajectories), compute, cache=cache)


def _diagnoses(scenario: ArmScenario, model: ManipulatorModel, cal: Calibration, settings: ArmSchemeSettings) -> dict:
    diagnoses = {}
    for name, diagnoser in arm_schemes(model, settings, cal.theta0, scenario.schemes, designs=cal.designs).items():
        rule = scheme_calibration(name, settings)
        decision = ThresholdDecision(diagnoser.components, cal.thresholds[name], diagnoser.signatures(),
                                     blanking=cal.blanking, confirm=rule.confirm, evidence=cal.evidence.get(name),
                                     release=rule.release, overturn=rule.overturn,
                                     defer=rule.defer)
        diagnoses[name] = Diagnosis(diagnoser, decision)
    return diagnoses


def build_loop(scenario: ArmScenario, cal: Calibration) -> ClosedLoop:
    """The scenario's closed loop with every scheme and its threshold decision, and its accommodation."""
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    rates = scenario.loop_rates(sim)
    accommodation = FaultCompensation(sim.actuators) if scenario.accommodation == "compensation" else None
    n = sim.n
    columns = [f"{j}_{part}" for part in ("q_d", "qd_d", "qdd_d") for j in sim.joint_names]
    units = sim.units["state"][:n] + sim.units["state"][n:] + [f"{u}/s" for u in sim.units["state"][n:]]
    return ClosedLoop(sim, _controller(model), scenario.motion, scenario.faults,
                      _diagnoses(scenario, model, cal, scenario.scheme_settings(rates)), rates, scenario.injection,
                      accommodation, scenario.health_source if accommodation is not None else None, columns, units)


def check_scenario(scenario: ArmScenario) -> None:
    """Raise now, before any calibration, if the scenario cannot run: its motions do not fit the robot's joints,
    or a fault names an unknown target or cannot be injected as asked."""
    sim = scenario.simulator()
    motions = {"motion": scenario.motion, **(scenario.calibration or {})}
    for name, motion in motions.items():
        size = np.asarray(motion(0.0)[0]).shape
        if size != (sim.n,):
            raise RobofdiError(f"ArmScenario: {name} gives {size[0] if size else 0} joint positions, the robot "
                               f"{sim.system} has {sim.n} joints {list(sim.joint_names)}")
    check_faults(scenario.faults, sim, scenario.run_duration, scenario.injection)


def parts(scenario: ArmScenario, cal: Calibration, run_key: str = "run", seed: int | None = None) -> Parts:
    """The scenario's run, built once (:class:`~robofdi.protocols.Parts`): its closed loop (:func:`build_loop`) with
    every scheme and its threshold decision, the start pose, the run's noise seed (default the scenario's, which
    also seeds the robot instance) and the record's metadata. Experiments, the command line and campaigns
    (:meth:`ArmSystem.build`) all run the arm through it."""
    loop = build_loop(scenario, cal)
    sim, plant = loop.simulator, scenario.plant
    meta = {
        "mjcf": str(sim.path),
        "joint_names": list(sim.joint_names),
        "primary_diagnoser": "adaptive" if "adaptive" in loop.diagnoses else next(iter(loop.diagnoses), None),
        "ripple_mode": plant.ripple_mode,
        "sensors": asdict(plant.sensors),
        "mismatch": {k: getattr(scenario.mismatch, k) for k in ("mass", "inertia", "damping", "armature")},
        "payload": plant.payload,
    } | ({"nominal_payload": scenario.nominal_payload} if scenario.nominal_payload else {})
    return Parts(loop, scenario.run_duration, scenario.start_pose, scenario.seed if seed is None else seed, run_key,
                 scenario.name, meta)


def run_scenario(scenario: ArmScenario, cal: Calibration, progress: Callable[[int], None] | None = None,
                 run_key: str = "run") -> Record:
    """The scenario's closed-loop run with every scheme and its threshold decision in the loop (:func:`parts`)."""
    return parts(scenario, cal, run_key).run(progress)


def _default_fault(joint_names, torque_limit: np.ndarray, motion_end: float, seed: int) -> Fault:
    """A step of 25 % of the motor torque limit on a seeded random joint, at 40 % of the motion."""
    i = int(rng(seed, "scenario", "default_fault").integers(len(joint_names)))
    return Fault(f"{joint_names[i]}_step", "actuator_additive", joint_names[i], onset=round(0.4 * motion_end, 3),
                 magnitude=round(0.25 * float(torque_limit[i]), 3))


def arm_scenario(robot: str | Path = "arm6.xml", faults=(), seed: int = 0, joints=None, torque_motors: bool = False,
                 drive_inertia: float = 0.0, **overrides) -> ArmScenario:
    """Any MJCF arm on a seeded point-to-point motion inside its joint ranges and torque limits, faults injected
    online. ``faults``: Fault objects or SPEC strings (:mod:`robofdi.faults.spec`); none = a step of 25 % of the
    torque limit on a seeded random joint at 40 % of the motion. Every scheme runs (the book's, the momentum
    baseline and the consistency scheme) unless ``schemes`` says otherwise. Everything is checked at once,
    before any calibration; ``overrides`` name any field of :class:`ArmScenario` or of its parts, flat
    (:func:`robofdi.config.compose`: ``payload=1.0``, ``velocity_noise=0.0``, ``mass=0.05``)."""
    overrides.setdefault("schemes", SCHEMES)
    faults = tuple(faults)
    if faults and all(isinstance(f, str) for f in faults):
        faults = parse_fault_specs(faults)
    plant = ArmPlant(robot, joints, torque_motors, drive_inertia)
    sim = plant.simulator(seed)
    declared = overrides.get("nominal_payload", 0.0)
    if not _is_mass(declared):
        raise RobofdiError(f"ArmScenario: field 'nominal_payload' must be a finite mass >= 0 kg, got {declared!r}")
    model = sim.nominal_model(payload=declared)   # the catalogue model plans the motion (belief, never the plant)
    limits = MotionLimits.from_ranges(sim.joint_range[:, 0], sim.joint_range[:, 1], model.torque_limit)
    motion = random_point_to_point(model, limits, seed)
    if not faults:
        faults = (_default_fault(sim.joint_names, model.torque_limit, motion.end, seed),)
    sc = compose(ArmScenario, overrides, name=f"arm-{sim.system}", motion=motion, faults=faults,
                 plant=replace(plant, joints=tuple(sim.joint_names)), seed=seed)
    check_scenario(sc)
    return sc


# ---------------------------------------------------------------------------------------------------- the system
@dataclass(frozen=True)
class ArmMissions:
    """How an arm campaign draws its missions: seeded point-to-point motions from random start poses
    (:func:`robofdi.control.random_point_to_point`). speed: "fast" | "normal" | "slow" or a factor >= 1
    (:data:`robofdi.control.SPEEDS`); segments: point-to-point segments per motion; tail: time after the
    motion's end [s]."""

    speed: Any = "normal"
    segments: int = 1
    tail: float = 1.0

    def __post_init__(self):
        from robofdi.control import SPEEDS

        check_fields("ArmMissions", self, [
            ("speed", _is_speed(self.speed), f"one of {sorted(SPEEDS)} or a number >= 1"),
            ("segments", is_int(self.segments, 1), "an integer >= 1"),
            ("tail", isinstance(self.tail, (int, float)) and 0 <= self.tail < 60, "a time in [0, 60) s"),
        ])


@dataclass(frozen=True)
class ArmOptions:
    """The arm system's configuration (a campaign's ``[system]`` table), composed of the simulator's
    configuration ``plant`` (:class:`~robofdi.sims.arm.ArmPlant`: robot file, default the shipped arm6.xml;
    joints, torque_motors, drive_inertia, ripple, sensors, payload), the nominal model's ``mismatch``
    (:class:`~robofdi.models.ModelMismatch`), the mission draw ``missions`` (:class:`ArmMissions`: speed,
    segments, tail) and the diagnosers' ``settings`` (:class:`~robofdi.observers.arm_schemes.ArmSchemeSettings`,
    e.g. ``consistency_gain``; every robot instance is calibrated with them); fields are named flat or as nested
    tables (:mod:`robofdi.config`). robot_seeds: one robot instance per seed (ripple phases, nominal-model
    errors), one calibration each, runs cycle through them; injection: "online" | "offline"; nominal_payload [kg]:
    a load the user declares, carried by the nominal model (:class:`ArmScenario`; the plant's is ``payload``).
    control_hz, diagnosis_hz [Hz]: the loop's rates (None: the robot's, :meth:`ArmScenario.loop_rates`; the control
    period a multiple of the file's physics step, the diagnosis rate a divisor of the control rate); every robot
    instance is calibrated at them."""

    plant: ArmPlant = part(ArmPlant)
    mismatch: ModelMismatch = part(ModelMismatch, lambda: ARM_MISMATCH)
    missions: ArmMissions = part(ArmMissions)
    settings: ArmSchemeSettings = part(ArmSchemeSettings)
    robot_seeds: tuple = (0,)
    injection: str = ArmScenario.injection
    nominal_payload: float = 0.0
    control_hz: float | None = None
    diagnosis_hz: float | None = None

    def __post_init__(self):
        check_robot_seeds(self)
        check_not_set("system", self.settings, ArmSchemeSettings(), ["T"],
                      "the diagnosis sample time follows the loop's diagnosis rate")
        check_fields("system", self, [("injection", self.injection in ("online", "offline"), "'online' or 'offline'"),
                                      ("nominal_payload", _is_mass(self.nominal_payload), "a finite mass >= 0 kg"),
                                      ("control_hz", _is_rate(self.control_hz), "none or a rate > 0 Hz"),
                                      ("diagnosis_hz", _is_rate(self.diagnosis_hz), "none or a rate > 0 Hz")])
        if self.mismatch.seed:
            raise RobofdiError("system: field 'seed' is not an option of the arm: each robot instance's seed "
                               "(robot_seeds) seeds its nominal-model errors, and the campaign's seed its runs")


@functools.lru_cache(maxsize=8)
def _arm(robot: str, joints, torque_motors: bool, drive_inertia: float, nominal_payload: float = 0.0):
    """(simulator, catalogue model, motion limits) of a robot, once per process (the catalogue model, with the
    declared load, plans motions)."""
    sim = ArmPlant(robot, joints, torque_motors, drive_inertia).simulator()
    model = sim.nominal_model(payload=nominal_payload)
    return sim, model, MotionLimits.from_ranges(sim.joint_range[:, 0], sim.joint_range[:, 1], model.torque_limit)


@register_system
class ArmSystem(RobotInstances):
    """Any MJCF arm: seeded point-to-point motions from random start poses, faults injected online, the book's
    schemes and the momentum observer in the loop (:mod:`robofdi.systems.arm`)."""

    name = "arm"
    options_type = ArmOptions

    def _base(self, options: ArmOptions):
        try:
            p = options.plant
            return _arm(p.robot, p.joints, p.torque_motors, p.drive_inertia, options.nominal_payload)
        except RobofdiError as exc:
            raise RobofdiError(f"system.robot: {exc}") from None

    def _rates(self, options: ArmOptions, check: bool = False) -> Rates | None:
        """The loop's rates the options set (None: the robot's own); ``check``: against the robot's physics step."""
        if options.control_hz is None and options.diagnosis_hz is None:
            return None
        sim = self._base(options)[0]
        control = float(options.control_hz) if options.control_hz is not None else 1.0 / sim.control_dt
        if check:
            try:
                options.plant.simulator(control_dt=1.0 / control)
            except RobofdiError:
                raise RobofdiError(f"system: field 'control_hz' must make the control period a multiple of the "
                                   f"physics step {sim.physics_dt:g} s of {sim.path.name} (e.g. "
                                   f"{1.0 / sim.control_dt:g} Hz), got {control:g}") from None
        diagnosis = float(options.diagnosis_hz) if options.diagnosis_hz is not None else default_diagnosis_hz(control)
        try:
            return Rates(control, diagnosis)
        except RobofdiError:
            raise RobofdiError(f"system: field 'diagnosis_hz' must divide the control rate {control:g} Hz, got "
                               f"{diagnosis:g}") from None

    def diagnosers(self, options):
        return ALL_SCHEMES

    def default_diagnosers(self, options):
        """The diagnosers a campaign runs when its spec names none: all but the opt-in ones (:data:`OPT_IN_SCHEMES
        <robofdi.observers.arm_schemes.OPT_IN_SCHEMES>`)."""
        return SCHEMES

    def targets(self, options):
        self._rates(options, check=True)         # a spec's options are checked here, before any calibration
        sim, model, _ = self._base(options)
        n = sim.n
        width = sim.joint_range[:, 1] - sim.joint_range[:, 0]
        # a continuous joint (no range: robosuite's kinova3) sizes its sensor faults on one turn
        width = np.where(np.isfinite(width), width, CONTINUOUS_JOINT_SPAN)
        sensors = {ch: TargetLimit(float(width[i % n]), "rad" if i < n else "rad/s")
                   for i, ch in enumerate(sim.sensor_channels)}          # velocity channels: one range per second
        masses = {b: TargetLimit(m, "kg") for b, m in sim.link_masses.items()}
        masses["payload"] = TargetLimit(max(v.limit for v in masses.values()), "kg")
        return {"actuator": {a: TargetLimit(float(model.torque_limit[i]), "N·m") for i, a in enumerate(sim.actuators)},
                "sensor": sensors,
                "component_friction": {j: TargetLimit(1.0, "1") for j in sim.component_kinds["component_friction"]},
                "component_mass": {b: masses[b] for b in sim.component_kinds["component_mass"]}}

    def _scenario(self, options, key, diagnosers, motion=None, duration=None, faults=()):
        sim, _, _ = self._base(options)
        if motion is None:
            motion = self.mission(options, key, rng(key, "campaign", "calibration-placeholder")).plan
        return ArmScenario("campaign-arm", motion=motion, duration=duration, faults=tuple(faults),
                           injection=options.injection, plant=replace(options.plant, joints=tuple(sim.joint_names)),
                           mismatch=options.mismatch, settings=options.settings, seed=int(key), schemes=tuple(diagnosers),
                           envelope_speed=options.missions.speed, envelope_segments=options.missions.segments,
                           nominal_payload=options.nominal_payload, rates=self._rates(options))

    def calibrate(self, options, key, diagnosers):
        return calibration(self._scenario(options, key, diagnosers))

    def calibration_notes(self, calibration: Calibration) -> dict:
        """The mass the consistency scheme identified at the payload point beyond the declared load [kg]."""
        return {"consistency_payload_kg": calibration.payload} if "consistency" in calibration.designs else {}

    def mission(self, options, key, generator):
        _, model, limits = self._base(options)
        missions = options.missions
        motion = random_point_to_point(model, limits, generator, missions.segments, speed=missions.speed)
        start = np.asarray(motion(0.0)[0], dtype=float)
        return Mission(float(motion.end) + float(missions.tail), motion,
                       {"start_pose": [round(float(v), 6) for v in start], "motion_end": float(motion.end)})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        sc = self._scenario(options, key, diagnosers, mission.plan, mission.duration, faults)
        built = parts(sc, calibration, "campaign", seed)    # the robot instance (key) seeded the plant and belief
        built.meta["robot_seed"] = int(key)
        return built
