"""Linear-plant scenarios: the wheel speeds of a differential-drive robot, seeded setpoint missions, a calibrated
observer residual in the loop.

The plant (2 states, 2 inputs, 3 outputs; the example of ``tests/test_linear.py``): mass M = 10 kg, yaw inertia
J = 0.5 kg·m², wheel radius ρ = 0.05 m, half track b = 0.2 m, wheel + gear inertia J_w = 0.002 kg·m², viscous wheel
friction c = 0.05 N·m·s/rad; with wheel speeds ω = (ω_L, ω_R) and motor torques τ = (τ_L, τ_R)

    M_w ω̇ = τ − c ω,   M_w = J_w I + (M ρ²/4) [[1, 1], [1, 1]] + (J ρ²/4b²) [[1, −1], [−1, 1]]
    y = (encoder L, encoder R, gyro) = (ω_L, ω_R, ρ (ω_R − ω_L) / 2b)          [rad/s]

sampled at T = 0.01 s, sensor noise std 0.05, 0.05, 0.01 rad/s, process noise std 0.001 rad/s per sample, torque
limits ±2 N·m, sensor ranges ±20, ±20, ±2.5 rad/s. The belief (controller and diagnoser) has seeded relative
parameter errors (:class:`robofdi.models.linear.LinearMismatch`, seed = the robot seed); the controller (LQR +
Kalman predictor on the belief) tracks wheel-speed setpoints mean + amplitude · sin(ω t + φ) drawn per mission.

Steps: :func:`linear_calibration` — fault-free runs on missions of their own (run keys ``calibration/<i>``),
thresholds = margin × max |r| after the observer's start-up (cached per robot seed and settings by
:mod:`robofdi.calibration`); :func:`run_linear` — one mission with faults, the observer in the loop.

The system (:class:`LinearSystem`, registered as ``linear``: its options, fault targets, calibration per robot instance,
missions drawn from a seed and runs; :class:`robofdi.protocols.System`) closes the module.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from robofdi.calibration import cached
from robofdi.checks import check_robot_seeds, is_positive
from robofdi.config import part
from robofdi.control.linear import StateFeedback, lqr_gain
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.loop import ClosedLoop, Diagnosis, Rates
from robofdi.models.linear import LinearMismatch, LinearModel, discretize
from robofdi.observers.linear import ObserverResidual, observer_gain_kalman
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.record import Record
from robofdi.seeding import rng
from robofdi.sims.linear import LinearPlant
from robofdi.systems import RobotInstances, register_system

__all__ = ["WheelSpeedMission", "LinearSettings", "wheel_speed_model", "wheel_speed_plant", "draw_mission",
           "linear_calibration", "run_linear", "SENSOR_RANGE", "TORQUE_LIMIT", "DIAGNOSER"]

T = 0.01                                              # control and diagnosis period [s]
SENSOR_STD = np.array([0.05, 0.05, 0.01])             # [rad/s]
PROCESS_STD = 0.001                                   # [rad/s] per sample
TORQUE_LIMIT = 2.0                                    # [N·m]
SENSOR_RANGE = {"encL": 20.0, "encR": 20.0, "gyro": 2.5}   # [rad/s]
DIAGNOSER = "observer"


def wheel_speed_model() -> LinearModel:
    """The continuous wheel-speed model of the module docstring (the truth's parameters)."""
    M, J, rho, b, Jw, c = 10.0, 0.5, 0.05, 0.2, 0.002, 0.05
    Mw = Jw * np.eye(2) + M * rho**2 / 4 * np.ones((2, 2)) + J * rho**2 / (4 * b**2) * np.array([[1, -1], [-1, 1]])
    C = np.array([[1.0, 0.0], [0.0, 1.0], [-rho / (2 * b), rho / (2 * b)]])
    return LinearModel(-np.linalg.solve(Mw, c * np.eye(2)), np.linalg.inv(Mw), C, state_names=["omega_L", "omega_R"],
                       input_names=["tau_L", "tau_R"], output_names=["encL", "encR", "gyro"],
                       units={"state": ["rad/s"] * 2, "u": ["N*m"] * 2, "y": ["rad/s"] * 3})


def wheel_speed_plant() -> LinearPlant:
    """The truth: the model with process and sensor noise and torque saturation."""
    return LinearPlant(wheel_speed_model(), T, process_noise=np.full(2, PROCESS_STD**2), measurement_noise=SENSOR_STD**2,
                       u_min=-TORQUE_LIMIT, u_max=TORQUE_LIMIT, system="diff-drive")


@dataclass(frozen=True)
class LinearSettings:
    """mismatch: relative error of the belief's parameters, in [0, 0.5); margin: threshold margin >= 1;
    calibration_runs: fault-free runs the thresholds come from (>= 1); duration: of every run [s];
    blanking: start-up time the decision ignores and calibration skips [s]."""

    mismatch: float = 0.05
    margin: float = 1.2
    calibration_runs: int = 5
    duration: float = 10.0
    blanking: float = 1.0

    def __post_init__(self):
        LinearMismatch(self.mismatch, 0)
        checks = (("margin", self.margin >= 1), ("calibration_runs", isinstance(self.calibration_runs, int)
                                                   and self.calibration_runs >= 1),
                  ("duration", is_positive(self.duration, 3600) and self.duration > self.blanking),
                  ("blanking", self.blanking >= 0))
        for name, ok in checks:
            if not ok:
                raise RobofdiError(f"LinearSettings: field {name!r} is out of range, got {getattr(self, name)!r} "
                                   "(margin >= 1, calibration_runs >= 1, 0 <= blanking < duration <= 3600 s)")

    @property
    def blanking_samples(self) -> int:
        return int(round(self.blanking / T))


@dataclass(frozen=True)
class WheelSpeedMission:
    """Setpoints mean + amplitude · sin(frequency · t + phase) per wheel [rad/s, rad/s, rad/s, rad]."""

    mean: tuple
    amplitude: tuple
    frequency: tuple
    phase: tuple

    def __call__(self, t: float) -> np.ndarray:
        return np.asarray(self.mean) + np.asarray(self.amplitude) * np.sin(np.asarray(self.frequency) * t
                                                                         + np.asarray(self.phase))


def draw_mission(generator: np.random.Generator) -> WheelSpeedMission:
    """A seeded mission: mean 5–10 rad/s, amplitude 0–4 rad/s, frequency 0.2–1 rad/s, any phase, per wheel."""
    def draw(lo, hi):
        return tuple(float(v) for v in generator.uniform(lo, hi, 2))
    return WheelSpeedMission(draw(5.0, 10.0), draw(0.0, 4.0), draw(0.2, 1.0), draw(0.0, 2 * np.pi))


def _parts(robot_seed: int, settings: LinearSettings):
    plant = wheel_speed_plant()
    belief = discretize(plant.nominal_model(LinearMismatch(settings.mismatch, robot_seed)), T)
    L = observer_gain_kalman(belief, np.full(2, PROCESS_STD**2), SENSOR_STD**2)
    controller = StateFeedback(belief, lqr_gain(belief, [1.0, 1.0], [0.1, 0.1]), L, tracked=["encL", "encR"],
                               u_min=-TORQUE_LIMIT, u_max=TORQUE_LIMIT)
    return plant, belief, L, controller


def _loop(plant, controller, observer, mission, faults=(), decision=None) -> ClosedLoop:
    return ClosedLoop(plant, controller, mission, faults=faults, diagnoses={DIAGNOSER: Diagnosis(observer, decision)},
                      rates=Rates(1 / T, 1 / T), reference_columns=["encL_setpoint", "encR_setpoint"],
                      reference_units=["rad/s", "rad/s"])


def linear_calibration(robot_seed: int, settings: LinearSettings = LinearSettings(), cache: bool = True
                       ) -> tuple[np.ndarray, bool]:
    """Thresholds [rad/s] per output from fault-free runs — Caccavale & Villani Sec. 6 (margin × max |r|), cached.
    Returns (thresholds, True if from the cache)."""
    def compute() -> np.ndarray:
        plant, belief, L, controller = _parts(robot_seed, settings)
        residuals = []
        for i in range(settings.calibration_runs):
            mission = draw_mission(rng(robot_seed, "calibration", str(i), "mission"))
            record = _loop(plant, controller, ObserverResidual(belief, L), mission).run(
                settings.duration, seed=robot_seed, run_key=f"calibration/{i}")
            residuals.append(record.diagnosers[DIAGNOSER].residual)
        return calibrate_thresholds(residuals, settings.margin, settings.blanking_samples)

    return cached("linear", {"plant": "diff-drive", "seed": robot_seed, **asdict(settings)}, compute, cache=cache)


def run_linear(mission: WheelSpeedMission, faults, thresholds: np.ndarray, robot_seed: int, seed: int,
               settings: LinearSettings = LinearSettings(), run_key: str = "run") -> Record:
    """One closed-loop run of ``settings.duration`` s with the calibrated observer residual and its threshold
    decision in the loop (noise from ``seed``, the belief's errors from ``robot_seed``)."""
    return linear_parts(mission, faults, thresholds, robot_seed, seed, settings, run_key).run()


def linear_parts(mission: WheelSpeedMission, faults, thresholds: np.ndarray, robot_seed: int, seed: int,
                 settings: LinearSettings = LinearSettings(), run_key: str = "run") -> Parts:
    """:func:`run_linear`'s run, built (:class:`~robofdi.protocols.Parts`)."""
    plant, belief, L, controller = _parts(robot_seed, settings)
    observer = ObserverResidual(belief, L)
    decision = ThresholdDecision(observer.components, thresholds, observer.signatures(scale=thresholds),
                                 blanking=settings.blanking_samples)
    return Parts(_loop(plant, controller, observer, mission, faults, decision), settings.duration, None, seed, run_key,
                 "diff-drive", {})


# ---------------------------------------------------------------------------------------------------- the system
@dataclass(frozen=True)
class LinearOptions:
    """The linear plant's configuration (a campaign's ``[system]`` table, the wheel-speed plant of
    :mod:`robofdi.systems.linear`): the runs' ``settings`` (:class:`LinearSettings`: mismatch, margin,
    calibration_runs, duration [s], blanking [s]; named flat, :mod:`robofdi.config`) and robot_seeds: one belief
    (seeded parameter errors) per seed, one calibration each (it depends on the settings and the robot seed)."""

    settings: LinearSettings = part(LinearSettings)
    robot_seeds: tuple = (0,)

    def __post_init__(self):
        check_robot_seeds(self)


@register_system
class LinearSystem(RobotInstances):
    """The differential-drive wheel-speed plant with its observer residual (:mod:`robofdi.systems.linear`)."""

    name = "linear"
    options_type = LinearOptions

    def diagnosers(self, options):

        return (DIAGNOSER,)

    def targets(self, options):

        return {"actuator": {a: TargetLimit(TORQUE_LIMIT, "N*m") for a in ("tau_L", "tau_R")},
                "sensor": {s: TargetLimit(v, "rad/s") for s, v in SENSOR_RANGE.items()}}

    def calibrate(self, options, key, diagnosers):

        return linear_calibration(int(key), options.settings)

    def mission(self, options, key, generator):

        mission = draw_mission(generator)
        return Mission(float(options.settings.duration), mission, {k: list(v) for k, v in mission.__dict__.items()})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        return linear_parts(mission.plan, faults, calibration, int(key), seed, options.settings, run_key="campaign")
