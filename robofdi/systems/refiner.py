"""The TMP chip refiner of Wang (book ch. 2, Sec. 10.2) as a scenario: gain-fault detection, diagnosis and FTC.

Wang's model has a same-sample feedthrough (y(k) = C x + D f u(k)) and a controller on the state,
u(k) = r − K x(k) (eq. (116)). :class:`robofdi.loop.ClosedLoop` measures y before it computes u (the feedthrough
there acts one sample late, which makes M₀ = 0 and the recursive estimator (38) undefined), so this scenario steps
its own loop with the engine's parts: the :class:`FaultInjector` (faults and labels), a
:class:`~robofdi.loop.DiagnosisBank` stepping the :class:`GainFaultObserver` with its :class:`WindowedTTest` and
identification (the diagnoser is told u(k), the input of its own sample), the :class:`GainCompensation`
accommodation fed by the diagnosed health one sample late, and a :class:`~robofdi.loop.Recorder` → :class:`Record`.

Numbers (Wang, book ch. 2, the refiner example): f_H = 10, K = [0.175 0.245], L = [0.533; 0.467], r = 30, N = 10,
λ = 8; step fault f = 8 on 50 ≤ k < 100; drift ±0.005 f_H per sample on 200 ≤ k < 300 (peak 12.5 at k = 249).
[HARNESS] 400 samples, x₀ = 0; ω, μ truncated Gaussian (±3σ) of std ``sigma`` (the chapter gives none).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robofdi.decision import WindowedTTest
from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.faults import Fault, FaultInjector, Ramp
from robofdi.ftc import GainCompensation
from robofdi.loop import Diagnosis, DiagnosisBank, Rates, Recorder
from robofdi.models.linear_examples import CHIP_REFINER, chip_refiner
from robofdi.observers.gain import GainFaultObserver
from robofdi.record import Record
from robofdi.seeding import rng, stream

__all__ = ["RefinerScenario", "PAPER_FAULTS", "run_refiner", "true_gain"]

F_H = CHIP_REFINER["f_H"]
#: Eq. (117) and Sec. 10.2: f = 0.8 f_H on [50, 100); f rises by 0.005 f_H per sample on [200, 250) and falls back on
#: [250, 300) — two gain changes on the same channel multiply: 1.25 · (1 − 0.2 p) falls linearly from 12.5 to 10.
PAPER_FAULTS = (
    Fault("step", "actuator_loss_of_effectiveness", "chip_feed", onset=50.0, end=100.0, magnitude=0.2),
    Fault("drift_up", "actuator_scale", "chip_feed", onset=199.0, end=300.0, magnitude=0.25, profile=Ramp(50.0)),
    Fault("drift_down", "actuator_scale", "chip_feed", onset=249.0, end=300.0, magnitude=-0.2, profile=Ramp(50.0)),
)


@dataclass(frozen=True)
class RefinerScenario:
    """sigma: std of ω and μ (0: noise-free); denominator: of the t-test ("std" or "var_literal");
    accommodation: u = f_H f̂⁻¹ u_cmd (eq. (104)) from the diagnosed health; state_feedback: "true" (the chapter's
    u = r − K x) or "estimate" (K on the diagnostic observer's x̂ — the belief only)."""

    faults: Sequence[Fault] = PAPER_FAULTS
    seed: int = 0
    samples: int = 400
    sigma: float = 0.0
    denominator: str = "std"
    accommodation: bool = False
    state_feedback: str = "true"

    def __post_init__(self):
        if not (np.isfinite(self.sigma) and self.sigma >= 0):
            raise RobofdiError(f"RefinerScenario: field 'sigma' must be >= 0, got {self.sigma!r}")
        if self.state_feedback not in ("true", "estimate"):
            raise RobofdiError(f"RefinerScenario: field 'state_feedback' must be 'true' or 'estimate', "
                               f"got {self.state_feedback!r}")
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 1:
            raise RobofdiError(f"RefinerScenario: field 'samples' must be an integer >= 1, got {self.samples!r}")
        object.__setattr__(self, "faults", tuple(self.faults))


def _truncated(gen: np.random.Generator, sigma: float) -> float:
    """N(0, σ²) truncated at ±3σ by rejection (spec E)."""
    if sigma == 0:
        return 0.0
    while True:
        v = gen.standard_normal()
        if abs(v) <= 3.0:
            return sigma * v


def true_gain(faults: Sequence[Fault], k: np.ndarray) -> np.ndarray:
    """f(k) of the scenario, from the injector applied to a unit input (the truth, for checks and figures)."""
    inj = FaultInjector(faults, ["chip_feed"], ["motor_load"], 0)
    return np.array([F_H * inj.actuate(float(t), np.ones(1))[0] for t in k])


def run_refiner(faults: Sequence[Fault] = PAPER_FAULTS, seed: int = 0, **options) -> tuple[Record, dict]:
    """One scenario run for campaigns: faults + seed (+ RefinerScenario options) → (record, summary)."""
    sc = RefinerScenario(faults=faults, seed=seed, **options)
    model = chip_refiner()
    A, B, C, D = model.A, model.B, model.C, model.D
    E, Fm = model.E, np.ones((1, 1))
    K, r_set = CHIP_REFINER["K"], CHIP_REFINER["setpoint"]
    observer = GainFaultObserver(model, CHIP_REFINER["L"], F_H)
    decision = WindowedTTest(observer.components, [CHIP_REFINER["threshold"]], observer.signatures(),
                             window=CHIP_REFINER["window"], denominator=sc.denominator, latch=sc.accommodation)
    acc = GainCompensation(model.input_names, F_H) if sc.accommodation else None
    inj = FaultInjector(sc.faults, model.input_names, model.output_names, stream(seed, "run", "faults"))
    w_gen, v_gen = rng(seed, "run", "process"), rng(seed, "run", "sensor")
    rates = Rates(1.0, 1.0, "first")
    bank = DiagnosisBank({"gain": Diagnosis(observer, decision)}, rates, "gain")
    x = np.zeros(model.n)
    rec = Recorder(("x", "u_cmd", "u", "u_applied", "y_true", "y", "stat", "fhat"), [f.name for f in sc.faults])
    for k in range(sc.samples):
        t = float(k)
        health = bank.latest_health                                          # sample k−1's diagnosis
        xs = x if sc.state_feedback == "true" else observer._x
        u_cmd = np.array([r_set]) - K @ xs                                   # (116)
        u = acc.update(u_cmd, health) if acc is not None else u_cmd
        u_plant = inj.actuate(t, u)
        y_true = C @ x + D @ (F_H * u_plant)
        y = y_true + Fm @ np.array([_truncated(v_gen, sc.sigma)])
        bank.push(k, t, y, u)                                                # the same-sample input u(k)
        rec.append(**{key: np.array(val, dtype=float) for key, val in (
            ("x", x), ("u_cmd", u_cmd), ("u", u), ("u_applied", u_plant), ("y_true", y_true), ("y", y),
            ("stat", decision.statistic), ("fhat", np.diag(observer.gain)))})
        rec.append_labels(inj.labels)
        x = A @ x + B @ (F_H * u_plant) + E @ np.array([_truncated(w_gen, sc.sigma)])
    time = np.arange(sc.samples, dtype=float)
    u_cols, y_cols = list(model.input_names), list(model.output_names)
    record = Record(
        system="tmp_refiner", scenario="ch2-wang", seed=seed, rates={"control_hz": 1.0, "diagnosis_hz": 1.0,
                                                                     "input_hold": "first"},
        time=time, truth_state=rec.array("x"), u_applied=rec.array("u_applied"),
        faults=rec.fault_labels({f.name: "1" for f in sc.faults}),
        signals={"reference": np.full((sc.samples, 1), r_set), "u_cmd": rec.array("u_cmd"), "u": rec.array("u"),
                 "u_diag": rec.array("u"), "y_true": rec.array("y_true"), "y_meas": rec.array("y"),
                 "t_statistic": rec.array("stat"), "gain_estimate": rec.array("fhat")},
        diagnosers=bank.traces(),
        meta={"injection": "online", "duration": float(sc.samples), "faults": [f.to_dict() for f in sc.faults],
              "accommodation": "GainCompensation" if acc else None, "health_source": "gain" if acc else None,
              "sigma": sc.sigma, "denominator": sc.denominator, "state_feedback": sc.state_feedback,
              "time_unit": "sample (T = 1)"},
        columns={"truth/state": list(model.state_names), "truth/u_applied": u_cols, "signals/reference": ["motor_load_ref"],
                 "signals/u_cmd": u_cols, "signals/u": u_cols, "signals/u_diag": u_cols, "signals/y_true": y_cols,
                 "signals/y_meas": y_cols, "signals/t_statistic": y_cols, "signals/gain_estimate": u_cols},
        units={"truth/state": ["1", "1"], "truth/u_applied": ["1"], "signals/reference": ["1"], "signals/u_cmd": ["1"],
               "signals/u": ["1"], "signals/u_diag": ["1"], "signals/y_true": ["1"], "signals/y_meas": ["1"],
               "signals/t_statistic": ["1"], "signals/gain_estimate": ["1"]},
    )
    return record, summarize(record, "ch2-wang", [f.to_dict() for f in sc.faults])
