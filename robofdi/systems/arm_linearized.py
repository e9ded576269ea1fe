"""Cross-use: the linear papers' adaptive fault-estimation observer on the MuJoCo arm, through the Diagnoser protocol.

The belief (the arm scenario's Pinocchio model, with its seeded errors) is linearised about a hold pose; the
reconstructed adaptive fault-estimation observer (seed 004) runs on it at the diagnosis rate with the operating
point (x₀ = [q₀; 0], u₀ = g(q₀)). Calibration on a fault-free run of the same hold (its own noise stream): the
torque offset the belief leaves at the hold (model errors, friction) joins u₀, then thresholds = margin × max |f̂|.
Valid where the motion stays near q₀ (a hold, slow small motions); static friction at the hold is outside the
linear model and absorbs part of a torque fault (the estimate is partial).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from robofdi.control import ComputedTorque
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.loop import ClosedLoop, Diagnosis
from robofdi.models.linear import discretize
from robofdi.models.linearization import linearize_manipulator
from robofdi.observers.adaptive import AdaptiveFaultEstimator, adaptive_fe_gains
from robofdi.record import Record
from robofdi.systems.arm import ArmScenario

__all__ = ["linearized_estimator_loop", "run_linearized"]

BLANKING = 0.5          # [s] the estimator's start-up, skipped by calibration and blanked by the decision
#: Poles of the augmented error system (z-plane, at 500 Hz: time constants 0.04–0.2 s).
POLES = tuple(np.linspace(0.95, 0.99, 18))


def _estimator(sc: ArmScenario, sim, model, poles, offset) -> AdaptiveFaultEstimator:
    rates = sc.loop_rates(sim)
    lin, x0, u0 = linearize_manipulator(model, sc.start_pose)
    md = discretize(lin, 1.0 / rates.diagnosis_hz)
    L, G = adaptive_fe_gains(md, md.B, poles)
    return AdaptiveFaultEstimator(md, L, G=G, operating_point=(x0, u0 - offset))


def linearized_estimator_loop(sc: ArmScenario, poles, offset=None, threshold=None) -> ClosedLoop:
    """The scenario's simulator and controller with the linearised adaptive estimator as the only diagnosis."""
    sim = sc.simulator()
    model = sc.nominal_model(sim)
    rates = sc.loop_rates(sim)
    fe = _estimator(sc, sim, model, poles, np.zeros(sim.n) if offset is None else offset)
    blank = int(round(BLANKING * rates.diagnosis_hz))
    decision = None if threshold is None else ThresholdDecision(fe.components, threshold, fe.signatures(), blanking=blank)
    return ClosedLoop(sim, ComputedTorque(model, torque_limit=model.torque_limit), sc.motion, sc.faults,
                      {"adaptive_fe": Diagnosis(fe, decision)}, rates, sc.injection)


def run_linearized(sc: ArmScenario, poles=POLES, margin: float = 1.5) -> Record:
    """Calibrate (offset, thresholds) on the fault-free hold, then run the scenario; returns the record."""
    start = np.concatenate([sc.start_pose, np.zeros(len(sc.start_pose))])
    free_sc = replace(sc, faults=())
    rates = free_sc.loop_rates(free_sc.simulator())
    blank = int(round(BLANKING * rates.diagnosis_hz))
    free = linearized_estimator_loop(free_sc, poles).run(sc.run_duration, start, seed=sc.seed, run_key="calibration")
    offset = free.diagnosers["adaptive_fe"].residual[blank:].mean(axis=0)
    free = linearized_estimator_loop(free_sc, poles, offset).run(sc.run_duration, start, seed=sc.seed,
                                                                run_key="calibration")
    threshold = calibrate_thresholds([free.diagnosers["adaptive_fe"].residual], margin, skip=blank)
    return linearized_estimator_loop(sc, poles, offset, threshold).run(sc.run_duration, start, seed=sc.seed,
                                                                       scenario=sc.name)
