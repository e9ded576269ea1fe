"""The aircraft of Guo, Jiang, Zhang & Wang (2008) Sec. 4 as a scenario: UIO bank + switching index under a gust.

Harness (robofdi's choice; the paper omits these): open loop, u = 0.5 on every surface from
t = 0; disturbance ξ = sin(t) through E from 10 s; the right elevator (input 2, the labels erratum) locked at
ū = 1 from 15 s — in robofdi's vocabulary a hard-over to 1 (the lock value differs from the command);
σ = 3 (F = −3I), Q = I, γᵢ = 50, projection [−2, 2], c = (1, 1, 1), W = I; 30 s. Plant: exact ZOH at ``dt``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from robofdi.control.linear import OpenLoop
from robofdi.decision import SwitchingIndexDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.faults import Fault
from robofdi.loop import ClosedLoop, Diagnosis, replay
from robofdi.models.linear import LinearMismatch, discretize, perturbed
from robofdi.models.linear_examples import aircraft_lateral
from robofdi.observers.uio import LockInPlaceBank
from robofdi.record import Record
from robofdi.sims.linear import LinearPlant

__all__ = ["AircraftScenario", "PAPER_FAULTS", "build_loop", "calibrate", "run_aircraft"]

#: Right elevator (input 2) locked at ū = 1 from 15 s (the command is 0.5).
PAPER_FAULTS = (Fault("lock_er", "actuator_hard_over", "elevator_right", onset=15.0, params={"limit": 1.0}),)
SIGMA = 3.0


@dataclass(frozen=True)
class AircraftScenario:
    """One configuration: ``gust`` switches ξ = sin t from ``gust_onset``; ``sensor_noise``: std per output (0:
    the paper's noise-free simulation); ``mismatch``: relative error of the bank's belief (0: exact model)."""

    faults: Sequence[Fault] = PAPER_FAULTS
    seed: int = 0
    duration: float = 30.0
    dt: float = 1e-3
    gust: bool = True
    gust_onset: float = 10.0
    command: float = 0.5
    gamma: float = 50.0
    sensor_noise: float = 0.0
    mismatch: float = 0.0

    def __post_init__(self):
        for name in ("duration", "dt", "gamma"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"AircraftScenario: field {name!r} must be > 0, got {v!r}")
        object.__setattr__(self, "faults", tuple(self.faults))


def build_loop(sc: AircraftScenario, threshold: float | None = None) -> ClosedLoop:
    truth = aircraft_lateral()
    gust_onset = sc.gust_onset if sc.gust else np.inf
    plant = LinearPlant(truth, sc.dt, system="aircraft",
                        measurement_noise=None if not sc.sensor_noise else np.full(6, sc.sensor_noise**2),
                        disturbance=lambda t: np.array([np.sin(t) if t >= gust_onset - 1e-12 else 0.0]))
    belief = perturbed(truth, LinearMismatch(sc.mismatch, sc.seed)) if sc.mismatch else truth
    bank = LockInPlaceBank(discretize(belief, sc.dt), [-SIGMA] * 6, gamma=sc.gamma)
    thr = np.full(len(bank.components), 1e9)
    thr[0] = 1.0 if threshold is None else threshold
    decision = SwitchingIndexDecision(bank.components, thr, bank.inputs, sc.dt, blanking=int(0.5 / sc.dt))
    command = np.full(5, sc.command)
    return ClosedLoop(plant, OpenLoop(5), lambda t: command, sc.faults, {"amm": Diagnosis(bank, decision)},
                      reference_columns=[f"cmd_{a}" for a in truth.input_names], reference_units=["deg"] * 5)


def calibrate(sc: AircraftScenario) -> float:
    """Detection threshold on ‖r₀‖ from a fault-free run with the gust (margin 1.2 × max, first 0.5 s skipped);
    a noise-free exact model gives ~0, so the threshold is floored at 1e-6."""
    rec = build_loop(replace(sc, faults=())).run(sc.duration, seed=sc.seed, run_key="calibration")
    r = rec.diagnosers["amm"].residual[:, :1]
    return max(float(calibrate_thresholds([r], 1.2, skip=int(0.5 / sc.dt))[0]), 1e-6)


def run_aircraft(faults: Sequence[Fault] = PAPER_FAULTS, seed: int = 0, threshold: float | None = None,
                 **options) -> tuple[Record, dict]:
    """One scenario run for campaigns: faults + seed (+ AircraftScenario options) → (record, summary)."""
    sc = AircraftScenario(faults=faults, seed=seed, **options)
    if threshold is None:
        threshold = calibrate(sc)
    record = build_loop(sc, threshold).run(sc.duration, seed=seed, scenario="aircraft")
    return record, summarize(record, "guo2008", [f.to_dict() for f in sc.faults])


def switching_index(record: Record, dt: float, c=(1.0, 1.0, 1.0), diagnoser: str = "amm") -> np.ndarray:
    """Jᵢ(t) of eq. (21) recomputed from the recorded residual norms (the bank models' columns), (N, m)."""
    tr = record.diagnosers[diagnoser]
    sq = tr.residual[:, 1:] ** 2
    t = np.arange(len(sq)) * dt
    return c[0] * sq + c[1] / (c[2] * t[:, None] + 1.0) * np.cumsum(sq * dt, axis=0)


def residual_vectors(record: Record, sc: AircraftScenario) -> np.ndarray:
    """(N, m+1, p) residual vectors rᵢ = y − C x̂ᵢ of every bank observer, replayed offline over the record."""
    bank = build_loop(sc).diagnoses["amm"].diagnoser
    return np.array(replay(record, bank, tap=lambda d, _: d.residuals.copy()))
