"""The adaptive fault-estimation example (seed 004) as a scenario, on the documented AIRC vertical-plane model.

[HARNESS] (the seed's model, sampling time, noise table and fault profiles are lost): continuous AIRC model
(robofdi.models.linear_examples.f16_vertical) sampled at T = 0.1 s; LQR (Q = I₅, R = I₃) with a Kalman predictor holds
the trim (set points 0); faults on the actuators as additive signals: a constant elevator bias (0.5 deg from 5 s)
and a thrust ramp (0.02 m/s² per s from 15 s); the estimator's gains place the 8 augmented error poles on
0.5 … 0.85 (spectral radius 0.85).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robofdi.control.linear import StateFeedback, lqr_gain
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.faults import Fault
from robofdi.loop import ClosedLoop, Diagnosis, replay
from robofdi.models.linear import LinearMismatch, discretize, perturbed
from robofdi.models.linear_examples import f16_vertical
from robofdi.observers.adaptive import AdaptiveFaultEstimator, adaptive_fe_gains
from robofdi.observers.linear import observer_gain_kalman
from robofdi.record import Record
from robofdi.sims.linear import LinearPlant

__all__ = ["F16Scenario", "PAPER_LIKE_FAULTS", "POLES", "build_loop", "calibrate", "run_f16", "fault_estimates"]

PAPER_LIKE_FAULTS = (
    Fault("elevator_bias", "actuator_additive", "elevator", onset=5.0, magnitude=0.5),
    Fault("thrust_ramp", "actuator_drift", "thrust", onset=15.0, magnitude=0.02),
)
POLES = tuple(np.linspace(0.5, 0.85, 8))


@dataclass(frozen=True)
class F16Scenario:
    """sensor_noise: std per output (0: noise-free); mismatch: relative error of the belief."""

    faults: Sequence[Fault] = PAPER_LIKE_FAULTS
    seed: int = 0
    duration: float = 30.0
    dt: float = 0.1
    sensor_noise: float = 0.0
    mismatch: float = 0.0
    poles: Sequence[float] = POLES

    def __post_init__(self):
        if not (np.isfinite(self.dt) and self.dt > 0 and np.isfinite(self.duration) and self.duration > 0):
            raise RobofdiError("F16Scenario: fields 'dt' and 'duration' must be > 0 s")
        object.__setattr__(self, "faults", tuple(self.faults))


def _estimator(sc: F16Scenario, belief) -> AdaptiveFaultEstimator:
    L, G = adaptive_fe_gains(belief, belief.B, sc.poles)
    return AdaptiveFaultEstimator(belief, L, G=G)


def _belief(sc: F16Scenario):
    truth = f16_vertical()
    return discretize(perturbed(truth, LinearMismatch(sc.mismatch, sc.seed)) if sc.mismatch else truth, sc.dt)


def build_loop(sc: F16Scenario, threshold=None) -> ClosedLoop:
    """The loop of ``sc`` with a threshold decision on f̂ (``threshold`` per actuator; None: 1e9, no alarm)."""
    truth = f16_vertical()
    plant = LinearPlant(truth, sc.dt, system="f16_vertical",
                        measurement_noise=None if not sc.sensor_noise else np.full(3, sc.sensor_noise**2))
    belief = _belief(sc)
    K = lqr_gain(belief, np.ones(5), np.ones(3))
    L_ctrl = observer_gain_kalman(belief, np.full(5, 1e-4), np.full(3, max(sc.sensor_noise, 1e-3) ** 2))
    controller = StateFeedback(belief, K, L_ctrl)
    fe = _estimator(sc, belief)
    threshold = np.full(3, 1e9) if threshold is None else threshold
    decision = ThresholdDecision(fe.components, threshold, fe.signatures(), blanking=int(round(2.0 / sc.dt)))
    return ClosedLoop(plant, controller, lambda t: np.zeros(3), sc.faults,
                      {"adaptive_fe": Diagnosis(fe, decision)},
                      reference_columns=[f"ref_{o}" for o in truth.output_names], reference_units=["m", "m/s", "rad"])


def calibrate(sc: F16Scenario, runs: int = 3) -> np.ndarray:
    """Thresholds on |f̂| from ``runs`` fault-free runs with their own noise streams (1.2 × max after the 2 s
    start-up; floor 1e-3 of the unit)."""
    free = F16Scenario(faults=(), seed=sc.seed, duration=sc.duration, dt=sc.dt, sensor_noise=sc.sensor_noise,
                       mismatch=sc.mismatch, poles=sc.poles)
    loop = build_loop(free)
    residuals = [loop.run(sc.duration, seed=sc.seed, run_key=f"calibration/{i}").diagnosers["adaptive_fe"].residual
                 for i in range(runs if sc.sensor_noise else 1)]
    return np.maximum(calibrate_thresholds(residuals, 1.2, skip=int(round(2.0 / sc.dt))), 1e-3)


def fault_estimates(record: Record, sc: F16Scenario) -> np.ndarray:
    """f̂(k) per sample, replayed offline over the record's y_meas / u_diag (before any isolation gating)."""
    return np.array([res.estimate for res in replay(record, _estimator(sc, _belief(sc)))])


def run_f16(faults: Sequence[Fault] = PAPER_LIKE_FAULTS, seed: int = 0, threshold=None,
            **options) -> tuple[Record, dict]:
    """One scenario run for campaigns: faults + seed (+ F16Scenario options) → (record, summary)."""
    sc = F16Scenario(faults=faults, seed=seed, **options)
    record = build_loop(sc, calibrate(sc) if threshold is None else threshold).run(sc.duration, seed=seed,
                                                                                   scenario="f16_vertical")
    return record, summarize(record, "adaptive-fe", [f.to_dict() for f in sc.faults])
