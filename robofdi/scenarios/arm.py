"""Arm scenarios: one configuration → simulator, nominal model, controller, faults and calibrated diagnoses.

The steps a scenario runs (each usable on its own):

1. :func:`calibration_records` — fault-free closed-loop runs on worst-case trajectories (Caccavale & Villani
   Sec. 6: very low velocities; high accelerations and wide displacements), checked to stay inside the
   joint and torque limits.
2. :func:`calibrate` — the adaptive scheme's ripple parameters by spectral analysis, then per scheme the
   thresholds ρ_i = margin · max |r_i| over the calibration runs (each diagnoser replayed offline).
3. :func:`run_scenario` — the faulty closed-loop run with every diagnosis in the loop.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from robofdi import RobofdiError
from robofdi.control import ComputedTorque, Quintic, Sequence
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.faults import Fault, FaultInjector
from robofdi.loop import ClosedLoop, Diagnosis, Rates, diagnose_record
from robofdi.models import ManipulatorModel, ModelMismatch
from robofdi.observers import DiagnosticObserver
from robofdi.observers.arm_schemes import SCHEMES, ArmSchemeSettings, arm_schemes
from robofdi.observers.spectral import ripple_initial_parameters
from robofdi.record import Record
from robofdi.sims import ArmSimulator, SensorModel, TorqueRipple

__all__ = ["ArmScenario", "Calibration", "calibration_trajectories", "calibration_records", "calibrate", "run_scenario"]


@dataclass(frozen=True)
class ArmScenario:
    """Everything that defines one arm run. ``seed`` draws the ripple phases, the nominal-model errors and
    the sensor noise; the same seed gives the same record."""

    name: str
    q0: tuple
    dq: tuple
    duration: float = 4.0
    motion_time: float = 4.0
    faults: tuple = ()
    injection: str = "online"
    mjcf: str = "arm6.xml"
    seed: int = 0
    rates: Rates = field(default_factory=Rates)
    schemes: tuple = SCHEMES
    settings: ArmSchemeSettings = field(default_factory=ArmSchemeSettings)
    mismatch: ModelMismatch = field(default_factory=lambda: ModelMismatch(mass=0.02, inertia=0.02, damping=0.05))
    ripple_mode: str = "physical"
    sensors: SensorModel = field(default_factory=SensorModel)
    payload: float = 0.0
    threshold_margin: float = 1.2
    calibration_low_velocity_time: float = 20.0

    def __post_init__(self):
        if not all(isinstance(f, Fault) for f in self.faults):
            raise RobofdiError("ArmScenario: field 'faults' must hold Fault objects")
        if int(self.seed) != self.seed or self.seed < 0:
            raise RobofdiError(f"ArmScenario: field 'seed' must be an integer >= 0, got {self.seed!r}")
        if abs(1.0 / self.rates.diagnosis_hz - self.settings.T) > 1e-12:
            raise RobofdiError(
                f"ArmScenario: settings.T={self.settings.T} must equal 1/rates.diagnosis_hz={1 / self.rates.diagnosis_hz}"
            )

    def simulator(self) -> ArmSimulator:
        return ArmSimulator(
            self.mjcf,
            control_dt=1.0 / self.rates.control_hz,
            ripple=TorqueRipple(self.ripple_mode, seed=self.seed),
            sensors=replace(self.sensors, seed=self.seed),
            payload=self.payload,
        )

    def nominal_model(self, sim: ArmSimulator) -> ManipulatorModel:
        """The diagnosers' belief: the simulator's MJCF read by Pinocchio, with this scenario's seeded errors."""
        return sim.nominal_model(replace(self.mismatch, seed=self.seed))

    def reference(self) -> Quintic:
        return Quintic(self.q0, self.dq, self.motion_time)


def calibration_trajectories(scenario: ArmScenario) -> dict[str, Sequence]:
    """The worst-case fault-free trajectories of Sec. 6 around the scenario's start pose.

    low-velocity: q0 → q0 + Δq/4 and back, each in ``calibration_low_velocity_time`` s;
    high-acceleration: q0 → q0 + [−π/2, π/4, −π/3, π/2, −π/2, 0.9π] and back, 1.5 s each.
    The scenario's own trajectory is deliberately not among them: the fault-free run then tests the thresholds.
    """
    q0 = np.asarray(scenario.q0)
    n = len(q0)
    wide = np.array([-np.pi / 2, np.pi / 4, -np.pi / 3, np.pi / 2, -np.pi / 2, 0.9 * np.pi])[:n]
    slow = scenario.calibration_low_velocity_time
    return {
        "low_velocity": Sequence.through([q0, q0 + 0.25 * np.asarray(scenario.dq), q0], [slow, slow]),
        "high_acceleration": Sequence.through([q0, q0 + wide, q0], [1.5, 1.5]),
    }


def _loop(scenario: ArmScenario, reference, faults=(), diagnoses=None, sim=None, model=None) -> ClosedLoop:
    sim = sim or scenario.simulator()
    model = model or scenario.nominal_model(sim)
    controller = ComputedTorque(model, torque_limit=model.torque_limit)
    injector = FaultInjector(list(faults), sim.actuators, sim.sensor_channels, seed=scenario.seed)
    return ClosedLoop(sim, controller, reference, injector, diagnoses or {}, scenario.rates, scenario.injection)


def _check_inside_limits(name: str, record: Record, sim: ArmSimulator) -> None:
    n = sim.n
    q = record.truth_state[:, :n]
    lo, hi = sim.joint_range.T
    if np.any(q < lo) or np.any(q > hi):
        raise RobofdiError(f"calibration trajectory {name!r} leaves the joint range; thresholds would be meaningless")
    if np.any(np.abs(record.signals["u_cmd"]) > sim.torque_limit + 1e-9):
        raise RobofdiError(f"calibration trajectory {name!r} saturates the motors; thresholds would be meaningless")


def calibration_records(scenario: ArmScenario, progress: Callable[[int], None] | None = None) -> dict[str, Record]:
    """Fault-free closed-loop runs on the calibration trajectories (no diagnoser in the loop)."""
    records = {}
    for name, ref in calibration_trajectories(scenario).items():
        loop = _loop(scenario, ref)
        records[name] = loop.run(ref.end, scenario.q0, system="arm6", scenario=f"calibration:{name}",
                                 seed=scenario.seed, progress=progress)
        _check_inside_limits(name, records[name], loop.simulator)
    return records


@dataclass
class Calibration:
    """Calibrated thresholds per scheme (residual space of the scheme) and the adaptive model's θ₀."""

    thresholds: dict[str, np.ndarray]
    theta0: np.ndarray
    state_thresholds: dict[str, np.ndarray] = field(default_factory=dict)


def calibrate(scenario: ArmScenario, records: dict[str, Record]) -> Calibration:
    """θ₀ from the first calibration run's simple residual, then thresholds per scheme (skip the first 10 ms)."""
    model = scenario.nominal_model(scenario.simulator())
    n, T = model.n, scenario.settings.T
    skip = int(np.ceil(0.010 / T))
    ratio = scenario.rates.ratio
    first = next(iter(records.values()))
    simple = diagnose_record(first, Diagnosis(DiagnosticObserver(model, T, residual_space="state")))
    theta0 = ripple_initial_parameters(first.signals["y_meas"][::ratio][skip:, :n], simple.residual[skip:, n:])
    thresholds = {}
    for name in scenario.schemes:
        residuals = []
        for rec in records.values():
            diagnoser = arm_schemes(model, scenario.settings, theta0, [name])[name]
            residuals.append(diagnose_record(rec, Diagnosis(diagnoser)).residual)
        thresholds[name] = calibrate_thresholds(residuals, scenario.threshold_margin, skip)
    state = {}
    state_settings = replace(scenario.settings, residual_space="state")
    for name in ("time_delayed", "recursive"):
        if name in scenario.schemes:
            residuals = [diagnose_record(r, Diagnosis(arm_schemes(model, state_settings, theta0, [name])[name])).residual
                         for r in records.values()]
            state[name] = calibrate_thresholds(residuals, scenario.threshold_margin, skip)
    return Calibration(thresholds, theta0, state)


def run_scenario(scenario: ArmScenario, calibration: Calibration, progress: Callable[[int], None] | None = None) -> Record:
    """The scenario's closed-loop run with every scheme and its threshold decision in the loop."""
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    diagnoses = {}
    for name, diagnoser in arm_schemes(model, scenario.settings, calibration.theta0, scenario.schemes).items():
        decision = ThresholdDecision(diagnoser.components, calibration.thresholds[name], diagnoser.signatures())
        diagnoses[name] = Diagnosis(diagnoser, decision)
    loop = _loop(scenario, scenario.reference(), scenario.faults, diagnoses, sim, model)
    meta = {
        "mjcf": scenario.mjcf,
        "joint_names": sim.joint_names,
        "faults": [f.to_dict() for f in scenario.faults],
        "primary_diagnoser": "adaptive" if "adaptive" in diagnoses else next(iter(diagnoses), None),
        "ripple_mode": scenario.ripple_mode,
        "mismatch": {k: getattr(scenario.mismatch, k) for k in ("mass", "inertia", "damping", "armature")},
        "payload": scenario.payload,
    }
    return loop.run(scenario.duration, scenario.q0, system="arm6", scenario=scenario.name, seed=scenario.seed,
                    meta=meta, progress=progress)
