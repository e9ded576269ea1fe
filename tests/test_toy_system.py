"""A user's own system in one file, outside the package: a heated tank (the plant, with a heat loss the belief
does not model), a one-step-prediction residual (the diagnoser), registered by name — and run through
``robofdi run`` and ``robofdi campaign`` exactly as a user would, in a subprocess with this folder on
PYTHONPATH. Nothing in robofdi knows this system.

Plant (truth):  C ẋ = u − k (x − x_a) − k₂ (x − x_a)²,  y = x + noise       (x [K] above ambient x_a = 0)
Belief:         x_{k+1} = a x_k + b u_k with a = exp(−k T/C), b = (1 − a)/k  (the quadratic loss unmodelled)
Residual:       r_k = y_k − (a y_{k−1} + b u_{k−1})
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robofdi.checks import check_fields, check_robot_seeds, is_positive
from robofdi.decision import Signature, ThresholdDecision, calibrate_thresholds
from robofdi.loop import ClosedLoop, Diagnosis
from robofdi.observers.residual import Residual, check_measurement
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.seeding import rng
from robofdi.systems import register_system

T, C, K, K2 = 0.01, 50.0, 2.0, 0.01           # s, J/K, W/K, W/K²
HEATER_MAX = 200.0                             # W
NOISE = 0.001                                  # K


class HeatedTank:
    """The truth: a heated tank with a quadratic heat loss, a saturating heater and a noisy thermometer."""

    system = "heated-tank"
    actuators, sensor_channels, components, component_kinds = ["heater"], ["temperature"], [], {}
    state_names = ["temperature"]
    units = {"state": ["K"], "u": ["W"], "y": ["K"]}
    control_dt = physics_dt = T

    def __init__(self, loss: float = K2):
        self.loss = loss
        self.state = np.zeros(1)
        self.u_applied = np.zeros(1)

    @property
    def true_output(self):
        return self.state.copy()

    def saturate(self, u):
        return np.clip(np.asarray(u, dtype=float), 0.0, HEATER_MAX)

    def reset(self, initial_state=None, seed=None):
        self.state = np.zeros(1) if initial_state is None else np.array(initial_state, dtype=float)
        self._noise = np.random.default_rng(seed)
        return self._measure()

    def step(self, u):
        self.u_applied = self.saturate(u)
        x = self.state[0]
        for _ in range(10):                        # the truth integrates finer than the belief samples
            x += T / 10 / C * (self.u_applied[0] - K * x - self.loss * x * abs(x))
        self.state = np.array([x])
        return self._measure()

    def _measure(self):
        return self.state + NOISE * self._noise.standard_normal(1)

    def apply_component_fault(self, kind, target, value):
        raise KeyError(kind)

    def nominal_model(self, mismatch=None):
        a = np.exp(-K * T / C)
        return a, (1 - a) / K


class PredictionResidual:
    """r_k = y_k − (a y_{k−1} + b u_{k−1}); it sees the nominal (a, b), the inputs and the measurements only."""

    inputs, measurements = ["heater"], ["temperature"]
    components, estimate_components, estimate_modes = ["r_temperature"], ["heater"], ["level"]
    units = {"residual": ["K"], "estimate": ["W"]}

    def __init__(self, a: float, b: float):
        self.a, self.b = a, b
        self.reset()

    def reset(self):
        self._y = None

    def update(self, y, u):
        y = check_measurement(y, 1, "temperature")
        u = check_measurement(u, 1, "heater")
        r = np.zeros(1) if self._y is None else y - (self.a * self._y + self.b * u)
        self._y = y
        return Residual(r, r / self.b)

    def signatures(self):
        return [Signature("heater", frozenset({"r_temperature"})), Signature("temperature", frozenset({"r_temperature"}))]


class Thermostat:
    def update(self, y, reference):
        return np.array([np.clip(20.0 * (reference[0] - y[0]) + K * reference[0], 0.0, HEATER_MAX)])


@dataclass(frozen=True)
class TankOptions:
    """robot_seeds: one calibration each; duration [s] of a run; calibration_runs fault-free runs set the threshold."""

    robot_seeds: tuple = (0,)
    duration: float = 8.0
    calibration_runs: int = 3

    def __post_init__(self):
        check_robot_seeds(self)
        check_fields("system", self, [("duration", is_positive(self.duration, 600), "a time in (0, 600] s")])


@register_system
class TankSystem:
    """A heated tank held at a drawn setpoint by a thermostat; the one-step-prediction residual online."""

    name = "toy-tank"
    options_type = TankOptions

    def diagnosers(self, options):
        return ("prediction",)

    def targets(self, options):
        return {"actuator": {"heater": TargetLimit(HEATER_MAX, "W")}, "sensor": {"temperature": TargetLimit(50.0, "K")}}

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def _loop(self, setpoint, faults=(), threshold=None):
        sim = HeatedTank()
        diagnoser = PredictionResidual(*sim.nominal_model())
        decision = None if threshold is None else ThresholdDecision(diagnoser.components, threshold,
                                                                    diagnoser.signatures(), blanking=5)
        return ClosedLoop(sim, Thermostat(), lambda t: np.array([setpoint]), faults=tuple(faults),
                          diagnoses={"prediction": Diagnosis(diagnoser, decision)})

    def calibrate(self, options, key, diagnosers):
        residuals = []
        for i in range(options.calibration_runs):
            setpoint = float(rng(key, "calibration", str(i)).uniform(5, 15))
            rec = self._loop(setpoint).run(options.duration, seed=int(key), run_key=f"calibration/{i}")
            residuals.append(rec.diagnosers["prediction"].residual)
        return calibrate_thresholds(residuals, 1.5, skip=5), False

    def mission(self, options, key, generator):
        setpoint = float(generator.uniform(5, 15))
        return Mission(float(options.duration), setpoint, {"setpoint": setpoint, "unit": "K"})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        return Parts(self._loop(mission.plan, faults, calibration), mission.duration, None, seed, "campaign", "toy-tank")

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        return self.build(options, calibration, key, mission, faults, seed, diagnosers).run()


def _robofdi(*args, cwd):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "robofdi.cli", *args], capture_output=True, text=True, env=env, cwd=cwd,
                          timeout=300)


def test_robofdi_run_finds_a_users_system_and_diagnoses_its_fault(tmp_path):
    proc = _robofdi("run", "test_toy_system:TankSystem", "--fault", "actuator_additive:heater:100@4.0", "--seed", "2",
                    "--quiet", "--out", str(tmp_path), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "TankSystem-seed2" / "summary.json").read_text())
    (detection,) = summary["diagnosers"]["prediction"]["detections"]
    assert summary["diagnosers"]["prediction"]["false_alarms"] == 0
    assert detection["isolated"] in ("heater", "heater+temperature") and 0 <= detection["delay"] < 0.1
    assert (tmp_path / "TankSystem-seed2" / "record.h5").is_file()


def test_a_bad_fault_target_of_a_users_system_is_one_line(tmp_path):
    proc = _robofdi("run", "test_toy_system:TankSystem", "--fault", "actuator_additive:pump:5@1.0", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "pump" in proc.stderr and "heater" in proc.stderr


def test_robofdi_campaign_runs_a_users_system(tmp_path):
    spec = tmp_path / "tank.toml"
    spec.write_text("""seed = 1
fault_free_runs = 4
faulty_runs = 4
diagnosers = ["prediction"]

[system]
name = "test_toy_system:TankSystem"
duration = 6.0

[[faults]]
kind = "actuator_additive"
magnitude_fraction = [0.4, 0.6]
onset_fraction = [0.3, 0.6]
""")
    proc = _robofdi("campaign", str(spec), "--workers", "1", "--quiet", "--out", str(tmp_path / "c"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    import pandas as pd

    table = pd.read_parquet(tmp_path / "c" / "results.parquet")
    faulty, clean = table[table["faulty"]], table[~table["faulty"]]
    assert len(faulty) == 4 and len(clean) == 4
    assert faulty["detected"].all() and (clean["false_alarms"] == 0).all()
