"""The helicopter of Jiang & Chowdhury (2005) Sec. V as a closed-loop scenario: configuration → calibrated loop → run.

Harness (robofdi's choice; the paper gives no controller, initial state or reference): LQR on
(A, B) with Q = I₄, R = I₂, fed by the fault-decoupled state estimate x̂ = col(x̂₁, y) of a
:class:`KalmanFaultEstimator`; u = −K x̂ + [sin πt, cos 0.6πt]; x(0) = [1, 0.5, 0, 0]; 10 s at T = 0.01 s.
Faults: r₁ = 0.4 on the collective from 4 s, r₂ = 0.5 + 0.3 sin πt on the cyclic from 2 s (eq. (29), E = −B).
Unknown-input variant (§V): ζ = 0.1 through D = [0, 0, 0, 0.01]ᵀ [HARNESS], r₃ = 0.3 + 0.1 cos 2πt on u₁ from 2 s.

Two harnesses differ only in what feeds the accommodation (29) u = (I − R̂)⁻¹u_nom (both clip R̂ to [0, 0.95]):
"loop" (default) feeds the windowed LS r̂ of the diagnosis, gated by its calibrated threshold decision; "digest"
(spec A.7 [HARNESS], the setting of its item-4 numbers) feeds the element-wise r̂ᵢ = f̂ᵢ(k−1)/u_R,i(k−1) of every
sample, ungated, from the start. Per-sample f̂ noise (std ≈ 56, 26) is as large as u_nom, so that R̂ is mostly noise
and often at 0.95: u is amplified up to 20×, which raises the SNR of the windowed LS estimate.

The system (:class:`HelicopterSystem`, registered as ``helicopter``: its options, fault targets, calibration per robot instance,
missions drawn from a seed and runs; :class:`robofdi.protocols.System`) closes the module.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from robofdi.calibration import cached
from robofdi.checks import check_fields, check_robot_seeds, is_int, is_positive
from robofdi.config import check_not_set, part
from robofdi.control.linear import StateFeedback, lqr_gain
from robofdi.decision import Alarms, ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.faults import Fault, Oscillation
from robofdi.ftc import EffectivenessCompensation
from robofdi.loop import ClosedLoop, Diagnosis, replay
from robofdi.models.linear import LinearMismatch, perturbed
from robofdi.models.linear_examples import HELICOPTER_NOISE, helicopter
from robofdi.observers.kalman import COVARIANCE_MODES, KalmanFaultEstimator
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.record import Record
from robofdi.sims.linear import LinearPlant
from robofdi.systems import RobotInstances, register_system

__all__ = ["HelicopterScenario", "HARNESSES", "PAPER_FAULTS", "UNKNOWN_INPUT_FAULTS", "UNKNOWN_INPUT_D", "build_loop",
           "calibrate", "run_helicopter", "fault_estimates"]

#: The paper's faults (Sec. V, Fig. 1): r₁ = 0.4 from 4 s on u₁, r₂ = 0.5 + 0.3 sin(πt) from 2 s on u₂.
PAPER_FAULTS = (
    Fault("r1", "actuator_loss_of_effectiveness", "collective", onset=4.0, magnitude=0.4),
    Fault("r2", "actuator_loss_of_effectiveness", "cyclic", onset=2.0, magnitude=1.0,
          profile=Oscillation(0.5, 0.3, 0.5)),     # 0.5 + 0.3 sin(π(t − 2)) = 0.5 + 0.3 sin(πt)
)
#: §V: r₃ = 0.3 + 0.1 cos(2πt) on u₁ from 2 s (cos(2π(t−2)) = sin(2π(t−2) + π/2)).
UNKNOWN_INPUT_FAULTS = (Fault("r3", "actuator_loss_of_effectiveness", "collective", onset=2.0, magnitude=1.0,
                              profile=Oscillation(0.3, 0.1, 1.0, np.pi / 2)),)
#: D of the unknown-input example — not given by the paper; [0, 0, 0, 0.01]ᵀ makes ζ observable (spec A.7 item 5).
UNKNOWN_INPUT_D = np.array([[0.0], [0.0], [0.0], [0.01]])
FAULT_OUTPUTS = ("y_u", "y_minus_w")      # y₂ of the paper's partition (Ā₁₁ = 1.0521, Ā₂₁ = 10.5091)
X0 = (1.0, 0.5, 0.0, 0.0)
#: What feeds the accommodation: the diagnosis' gated LS r̂ ("loop") or the ungated element-wise r̂ ("digest").
HARNESSES = ("loop", "digest")


@dataclass(frozen=True)
class HelicopterScenario:
    """One configuration of the helicopter experiment (validated at construction).

    noise: the paper's process S and sensor Q noise (False: noise-free). accommodation: u = (I − R̂)⁻¹u fed by the
    diagnosed health (eq. (29)). window: samples of the LS effectiveness estimate (None: 25 with noise, 1 without).
    unknown_input: ζ (None: no unknown input) acting through UNKNOWN_INPUT_D, estimated by the augmented filter.
    mismatch: relative parameter error of the diagnoser's and controller's belief (0: the paper's exact model).
    harness: "loop" or "digest" — what feeds the accommodation (module docstring; spec A.7 [HARNESS]).
    """

    faults: Sequence[Fault] = PAPER_FAULTS
    seed: int = 0
    duration: float = 10.0
    noise: bool = True
    accommodation: bool = True
    covariance_mode: str = "as_printed"
    window: int | None = None
    unknown_input: float | None = None
    mismatch: float = 0.0
    calibration_runs: int = 3
    harness: str = "loop"

    def __post_init__(self):
        if self.harness not in HARNESSES:
            raise RobofdiError(f"HelicopterScenario: field 'harness' must be one of {HARNESSES}, got {self.harness!r}")
        if self.covariance_mode not in COVARIANCE_MODES:
            raise RobofdiError(f"HelicopterScenario: field 'covariance_mode' must be one of {COVARIANCE_MODES}, "
                               f"got {self.covariance_mode!r}")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise RobofdiError(f"HelicopterScenario: field 'duration' must be > 0 s, got {self.duration!r}")
        if self.unknown_input is not None and not np.isfinite(self.unknown_input):
            raise RobofdiError(f"HelicopterScenario: field 'unknown_input' must be None or finite, got {self.unknown_input!r}")
        object.__setattr__(self, "faults", tuple(self.faults))

    @property
    def samples(self) -> int:
        return self.window if self.window is not None else (25 if self.noise else 1)


def _estimator(sc: HelicopterScenario, belief, window: int) -> KalmanFaultEstimator:
    return KalmanFaultEstimator(belief, HELICOPTER_NOISE["process"], HELICOPTER_NOISE["sensor"],
                                fault_outputs=FAULT_OUTPUTS, covariance_mode=sc.covariance_mode, window=window,
                                unknown_input=None if sc.unknown_input is None else UNKNOWN_INPUT_D)


class Ungated:
    """Decision protocol of the digest harness: every component counts as isolated at every sample, no alarm —
    the element-wise R̂ reaches the accommodation (29) without a decision (spec A.7 [HARNESS]). Not a diagnosis:
    its trace detects nothing."""

    def __init__(self, components: Sequence[str]):
        self.components = tuple(components)
        self.threshold = np.full(len(self.components), np.inf)

    def reset(self) -> None:
        """Stateless."""

    def update(self, residual: np.ndarray) -> Alarms:
        return Alarms(alarm=np.zeros(len(self.components), dtype=bool), isolated=self.components)


def build_loop(sc: HelicopterScenario, threshold=None) -> ClosedLoop:
    """The closed loop of ``sc``: plant (truth), LQR on the estimator's x̂, the Kalman fault estimator with a
    threshold decision (``threshold`` per actuator; None: 1, i.e. no alarm), accommodation when asked — fed by
    that diagnosis (harness "loop") or by the ungated element-wise r̂ of diagnosis "elementwise" (harness "digest")."""
    truth = helicopter()
    E = None if sc.unknown_input is None else UNKNOWN_INPUT_D
    if E is not None:
        truth = replace(truth, E=E)
    noise = sc.noise
    plant = LinearPlant(truth, truth.dt, process_noise=HELICOPTER_NOISE["process"] if noise else None,
                        measurement_noise=HELICOPTER_NOISE["sensor"] if noise else None, x0=X0, system="helicopter",
                        disturbance=None if E is None else (lambda t, z=sc.unknown_input: np.array([z])))
    belief = perturbed(helicopter(), LinearMismatch(sc.mismatch, sc.seed)) if sc.mismatch else helicopter()
    K = lqr_gain(belief, np.ones(4), np.ones(2))
    controller = StateFeedback(belief, K, None, estimator=_estimator(sc, belief, 1))
    excitation = np.linalg.pinv(controller.N)        # reference whose N·ref is the excitation [sin πt, cos 0.6πt]

    def reference(t: float) -> np.ndarray:
        return excitation @ np.array([np.sin(np.pi * t), np.cos(0.6 * np.pi * t)])

    fe = _estimator(sc, belief, sc.samples)
    threshold = np.ones(2) if threshold is None else threshold
    decision = ThresholdDecision(fe.components, threshold, fe.signatures(), blanking=sc.samples + 1)
    acc = EffectivenessCompensation(fe.components) if sc.accommodation else None
    diagnoses = {"kalman_fe": Diagnosis(fe, decision)}
    source = "kalman_fe"
    if sc.harness == "digest" and sc.accommodation:
        source = "elementwise"
        diagnoses[source] = Diagnosis(_estimator(sc, belief, 1), Ungated(fe.components))
    return ClosedLoop(plant, controller, reference, sc.faults, diagnoses,
                      accommodation=acc, health_source=source if sc.accommodation else None,
                      reference_columns=[f"ref_{n}" for n in truth.output_names],
                      reference_units=list(truth.units["y"]))


def calibrate(sc: HelicopterScenario) -> np.ndarray:
    """Thresholds on r̂ from fault-free runs (margin 1.2 × max, start-up samples skipped) — seeds never used by
    test runs (run keys "calibration/i")."""
    loop = build_loop(replace(sc, faults=(), accommodation=False))
    runs = [loop.run(sc.duration, seed=sc.seed, run_key=f"calibration/{i}").diagnosers["kalman_fe"].residual
            for i in range(sc.calibration_runs if sc.noise else 1)]
    return calibrate_thresholds(runs, margin=1.2, skip=sc.samples + 1)


def run_helicopter(faults: Sequence[Fault] = PAPER_FAULTS, seed: int = 0, threshold=None,
                   **options) -> tuple[Record, dict]:
    """One scenario run for campaigns: faults + seed (+ HelicopterScenario options) → (record, summary).
    ``threshold``: per-actuator thresholds on r̂ (None: calibrated on fault-free runs of the same configuration)."""
    sc = HelicopterScenario(faults=faults, seed=seed, **options)
    if threshold is None:
        threshold = calibrate(sc)
    record = build_loop(sc, threshold).run(sc.duration, seed=seed, scenario="helicopter", meta={"noise": sc.noise})
    return record, summarize(record, "jiang2005", [f.to_dict() for f in sc.faults])


def fault_estimates(record: Record, sc: HelicopterScenario) -> tuple[np.ndarray, np.ndarray]:
    """(f̂(k−1), ζ̂(k)) per diagnosis sample, replayed offline over the record's y_meas / u_diag with the scenario's
    estimator (deterministic: the same numbers the online diagnoser computed)."""
    belief = perturbed(helicopter(), LinearMismatch(sc.mismatch, sc.seed)) if sc.mismatch else helicopter()
    rows = replay(record, _estimator(sc, belief, sc.samples),
                  tap=lambda fe, _: (fe.fault_estimate.copy(), fe.unknown_input_estimate))
    return np.array([f for f, _ in rows]), np.array([z for _, z in rows])


# ---------------------------------------------------------------------------------------------------- the system
#: The scenario of a helicopter campaign's belief: 5 % seeded parameter errors (the paper's belief is exact), no
#: fault (the campaign draws each run's faults and noise seed; the robot seed seeds the belief's errors).
CAMPAIGN_SCENARIO = HelicopterScenario(faults=(), mismatch=0.05)
_DRAWN = ("faults", "seed")


@dataclass(frozen=True)
class HelicopterOptions:
    """The helicopter's configuration (a campaign's ``[system]`` table, Jiang & Chowdhury 2005 Sec. V,
    :mod:`robofdi.systems.helicopter`): the runs' ``scenario`` (:class:`HelicopterScenario`, default
    :data:`CAMPAIGN_SCENARIO`), any field named flat (:mod:`robofdi.config`) — duration [s] (≤ 600), mismatch (a
    fraction in [0, 0.5)), noise, accommodation, calibration_runs, … — except the drawn faults and seed;
    robot_seeds: one belief (seeded relative parameter errors of size ``mismatch``) and calibration each."""

    scenario: HelicopterScenario = part(HelicopterScenario, lambda: CAMPAIGN_SCENARIO)
    robot_seeds: tuple = (0,)

    def __post_init__(self):
        check_robot_seeds(self)
        sc = self.scenario
        check_not_set("system", sc, CAMPAIGN_SCENARIO, _DRAWN,
                      "the campaign draws each run's faults, "
                      "and the robot seeds seed the belief")
        check_fields("system", sc, [
            ("duration", is_positive(sc.duration, 600), "a time in (0, 600] s"),
            ("mismatch", isinstance(sc.mismatch, (int, float)) and 0 <= sc.mismatch < 0.5, "a fraction in [0, 0.5)"),
            ("noise", isinstance(sc.noise, bool), "true or false"),
            ("accommodation", isinstance(sc.accommodation, bool), "true or false"),
            ("calibration_runs", is_int(sc.calibration_runs, 1), "an integer >= 1"),
        ])
        object.__setattr__(self, "scenario", replace(sc, duration=float(sc.duration), mismatch=float(sc.mismatch)))

    def belief(self, key: int, faults=()) -> HelicopterScenario:
        """The scenario of belief ``key`` (its seed seeds the belief's errors; run noise comes from the run seed)."""
        return replace(self.scenario, faults=tuple(faults), seed=int(key))


@register_system
class HelicopterSystem(RobotInstances):
    """The linearised helicopter of Jiang & Chowdhury (2005): the paper's LQR + excitation harness, actuator
    effectiveness faults estimated by the Kalman fault estimator and accommodated (the mission is the paper's fixed
    excitation; runs differ by their fault and noise)."""

    name = "helicopter"
    options_type = HelicopterOptions

    def diagnosers(self, options):
        return ("kalman_fe",)

    def targets(self, options):
        from robofdi.models.linear_examples import helicopter

        # limit of an input: the excitation's amplitude (1 input unit)
        return {"actuator": {a: TargetLimit(1.0, "input") for a in helicopter().input_names}}

    def calibrate(self, options, key, diagnosers):

        sc = options.belief(key)
        return cached("helicopter", {"scenario": repr(sc)}, lambda: calibrate(sc))

    def mission(self, options, key, generator):
        return Mission(options.scenario.duration, None, {"excitation": "sin(pi t), cos(0.6 pi t)"})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        sc = options.belief(key, faults)
        return Parts(build_loop(sc, calibration), sc.duration, None, seed, "campaign", "campaign-helicopter",
                     {"noise": sc.noise, "robot_seed": int(key)})
