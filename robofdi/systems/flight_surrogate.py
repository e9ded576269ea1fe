"""Bošković & Mehra's chapter 5 (FDIR in flight control) on robofdi's over-actuated flight surrogate
(:mod:`robofdi.models.flight`, :class:`robofdi.sims.flight.FlightPlant`): scenarios, and the campaign face.

Harness [RECONSTRUCTED; the chapter gives no plant, reference, W, Λ or run length]: IDCL (59) with the
surrogate's W (1/(half travel)², leading-edge flaps 10× cheaper); error dynamics Λ_o = [Ā; Λ] and reference
model [Ā; A_m] from LQR designs (weights ERROR_WEIGHTS / REFERENCE_WEIGHTS: light on V, so the airspeed noise is
not amplified), unit DC gain from r = (θ_cmd, φ_cmd, β_cmd) to (θ, φ, β); the mission is a pitch-attitude step
(0.05 rad at 0.5 s) and a bank-angle doublet (+0.3 rad from 4 s, −0.3 rad from 8 s, 0 from 12 s), each
transition smoothed over 1 s; 100 Hz control and diagnosis.

Schemes (what closes the loop): ``baseline`` (IDCL on y); ``hybrid`` (IDCL + the hybrid FDI-ARC bank
:class:`~robofdi.observers.effector_bank.HybridEffectorFDI` feeding :class:`~robofdi.ftc.idcl.MultipleModelReallocation`);
``sensor`` (IDCL on x̂ = y − d̂ of :class:`~robofdi.observers.sensor_adaptive.SensorBiasEstimator`); ``damage``
(IDCL with Â, B̂ of :class:`~robofdi.observers.damage.DamageEstimator`); ``integrated`` (all three, §7).

The system (:class:`FlightSurrogateSystem`, registered as ``flight-surrogate``) draws random effector
(lock-in-place, hard-over) and sensor (bias, calibration) faults; its diagnosers (:data:`DIAGNOSERS`) are ``hybrid_mm``,
``mmst`` (the non-hybrid bank of §5.3), ``sensor_bias`` (§3.1), ``sensor_calibration`` (§3.2) and
``sensor_generalised`` (§4, y = Cx + d); scheme ``mmst`` lets the non-hybrid bank drive the reallocation.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from robofdi.calibration import cached
from robofdi.checks import check_fields, check_robot_seeds, is_positive
from robofdi.config import check_not_set, part
from robofdi.decision import SupervisorStatusDecision, ThresholdDecision
from robofdi.errors import RobofdiError
from robofdi.faults import Fault
from robofdi.ftc.idcl import (
    IDCLController, MultipleModelReallocation, ReferenceModel, error_feedback_lqr, reference_model_design,
)
from robofdi.loop import ClosedLoop, Diagnosis
from robofdi.models.flight import FlightSurrogate, flight_surrogate
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.sims.flight import FlightPlant
from robofdi.systems import RobotInstances, register_system

__all__ = ["FlightScenario", "SCHEMES", "ERROR_WEIGHTS", "REFERENCE_WEIGHTS", "design", "reference_signal",
           "build_loop", "calibrate", "calibrate_delta", "effector_bank", "TRACKED"]

SCHEMES = ("baseline", "hybrid", "sensor", "damage", "integrated", "mmst")
#: every diagnoser the system can run (``FlightScenario.diagnosers`` picks a subset; the campaign's list).
DIAGNOSERS = ("hybrid_mm", "sensor_bias", "mmst", "sensor_calibration", "sensor_generalised")
DEFAULT_DIAGNOSERS = ("hybrid_mm", "sensor_bias")
#: LQR state weights (V, α, θ, β, φ, q, p, r) and input weight of Λ (error dynamics) and of A_m (reference).
ERROR_WEIGHTS = ((1e-4, 1.0, 10.0, 10.0, 10.0, 1.0, 1.0, 1.0), 0.05)
REFERENCE_WEIGHTS = ((1e-4, 1.0, 4.0, 4.0, 4.0, 0.5, 0.5, 0.5), 1.0)
#: r = (θ_cmd, φ_cmd, β_cmd): the states the reference model tracks with unit DC gain.
TRACKED = ("theta", "phi", "beta")
DT = 0.01
#: Channels whose bias is estimated: all but V and φ, the two weakest directions of A (singular values 0.002
#: and 0.015: a bias there is not identifiable within a run); Λ = −5 I and 0.1 s quasi-static convergence
#: (bias_gains; the slowest coupled mode is then ≈ 1.4 s).
BIAS_CHANNELS = ("alpha", "theta", "beta", "q", "p", "r")
SENSOR_LAMBDA = -5.0
SENSOR_TAU = 0.1
#: damage estimator: the simplified (x₂, λ = 20) observer, γ = 3000, dead zone 1.5e-3 rad/s on ‖ê₂‖.
#: calibration-error laws (B2, B3): channels whose calibration is estimated (all but V and β: V's excursions are
#: small, β is held at 0 by the mission), Γ_c from calibration_gains (3 s time constant, P = (σ_min/σᵢ)² of the
#: datasheet noise) on the default mission (seed 0, 12 s, baseline loop), rounded; box ĉ ∈ [0.5, 2].
CALIBRATION_CHANNELS = ("alpha", "theta", "phi", "q", "p", "r")
CALIBRATION_TAU = 3.0
CALIBRATION_GAMMA = (0.0, 1890.0, 10750.0, 0.0, 100.0, 2940.0, 30.0, 910.0)
DAMAGE_GAMMA = 3000.0
DAMAGE_DEAD_ZONE = 1.5e-3


def _smooth(t: float, t0: float, width: float = 1.0) -> float:
    s = min(max((t - t0) / width, 0.0), 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


@dataclass(frozen=True)
class FlightScenario:
    """One configuration: ``scheme`` (see the module docstring); ``noise``: sensor noise on (the plant's
    defaults) or off; ``pitch`` / ``bank`` [rad]: the mission's command amplitudes; ``delta``: the bank's
    switching threshold on I₀ − minᵢ Iᵢ [(rad/s)²] (None: 1e-5); ``mismatch``: relative error of the belief."""

    faults: Sequence[Fault] = ()
    seed: int = 0
    duration: float = 12.0
    scheme: str = "hybrid"
    noise: bool = True
    pitch: float = 0.05
    bank: float = 0.3
    bank_onset: float = 4.0
    delta: float | None = None
    mismatch: float = 0.0
    sensor_threshold: tuple | None = None
    lam: float = 40.0
    gamma: float = 5000.0
    c: tuple = (1.0, 10.0, 100.0)
    t_s: float = 0.05
    diagnosers: tuple | None = None
    mmst_delta: float | None = None
    calibration_threshold: tuple | None = None
    generalised_threshold: tuple | None = None

    def __post_init__(self):
        if self.scheme not in SCHEMES:
            raise RobofdiError(f"FlightScenario: field 'scheme' must be one of {SCHEMES}, got {self.scheme!r}")
        check_fields("FlightScenario", self, [
            ("duration", is_positive(self.duration, 600), "a time in (0, 600] s"),
            ("pitch", isinstance(self.pitch, (int, float)) and abs(self.pitch) <= 0.2, "a pitch command in [-0.2, 0.2] rad"),
            ("bank", isinstance(self.bank, (int, float)) and abs(self.bank) <= 0.8, "a bank command in [-0.8, 0.8] rad"),
            ("delta", self.delta is None or is_positive(self.delta), "None or a threshold > 0"),
            ("mmst_delta", self.mmst_delta is None or is_positive(self.mmst_delta), "None or a threshold > 0"),
            ("diagnosers", self.diagnosers is None or (isinstance(self.diagnosers, tuple)
                                                       and set(self.diagnosers) <= set(DIAGNOSERS)),
             f"None or a tuple of names from {DIAGNOSERS}"),
        ])
        object.__setattr__(self, "faults", tuple(self.faults))


def design(s: FlightSurrogate | None = None):
    """(Λ, ReferenceModel) of the harness: Λ and A_m by LQR (ERROR_WEIGHTS, REFERENCE_WEIGHTS)."""
    s = s or flight_surrogate()
    Lam = error_feedback_lqr(s.Abar, *ERROR_WEIGHTS)
    Am, Bm = reference_model_design(s.Abar, REFERENCE_WEIGHTS[0], [s.state_names.index(v) for v in TRACKED],
                                    R=REFERENCE_WEIGHTS[1])
    return Lam, ReferenceModel(s.Abar, Am, Bm)


def reference_signal(sc: FlightScenario):
    """r(t) = (θ_cmd, φ_cmd, 0) of the mission."""
    def r(t: float) -> np.ndarray:
        bank = sc.bank * (_smooth(t, sc.bank_onset) - 2 * _smooth(t, sc.bank_onset + 4.0) + _smooth(t, sc.bank_onset + 8.0))
        return np.array([sc.pitch * _smooth(t, 0.5), bank, 0.0])
    return r


class _Reference:
    """reference(t) = [r(t), x_m(t)] on the control grid (x_m precomputed exactly by the reference model)."""

    def __init__(self, r, xm: np.ndarray, dt: float):
        self.r, self.xm, self.dt = r, xm, dt

    def __call__(self, t: float) -> np.ndarray:
        k = min(int(round(t / self.dt)), len(self.xm) - 1)
        return np.concatenate([self.r(t), self.xm[k]])


def _belief(sc: FlightScenario) -> FlightSurrogate:
    return FlightPlant(noise=0.0).nominal_model(sc.mismatch or None)


def effector_bank(sc: FlightScenario, belief: FlightSurrogate | None = None):
    """The hybrid FDI-ARC bank of the scenario (on the belief)."""
    from robofdi.observers.effector_bank import HybridEffectorFDI

    b = belief or _belief(sc)
    return HybridEffectorFDI(
        b.A2(), b.B2(), b.effectors, b.state_names, list(range(b.n1, b.n)), DT, b.u_min, b.u_max, b.rate_limit,
        lam=sc.lam, gamma=sc.gamma, c=sc.c, t_s=sc.t_s, delta=1e-5 if sc.delta is None else sc.delta)


def mmst_bank(sc: FlightScenario, belief: FlightSurrogate | None = None):
    """The non-hybrid MMST bank of §5.3 (:class:`~robofdi.observers.mmst_bank.MultipleModelEffectorFDI`) with the
    hybrid bank's gains, t_s and observers; its own threshold ``mmst_delta`` (None: 1e-5)."""
    from robofdi.observers.mmst_bank import MultipleModelEffectorFDI

    b = belief or _belief(sc)
    return MultipleModelEffectorFDI(
        b.A2(), b.B2(), b.effectors, b.state_names, list(range(b.n1, b.n)), DT, b.u_min, b.u_max, b.rate_limit,
        lam=sc.lam, gamma=sc.gamma, c=sc.c, t_s=sc.t_s, delta=1e-5 if sc.mmst_delta is None else sc.mmst_delta)


def calibration_estimator(sc: FlightScenario, belief: FlightSurrogate | None = None, bias: bool = False):
    """The calibration-error law of §3.2 (``bias=False``) or the generalised y = Cx + d law of §4 (``bias=True``,
    the bias part with the sensor_bias estimator's channels and Γ_d):
    :class:`~robofdi.observers.sensor_calibration.GeneralisedSensorEstimator`."""
    from robofdi.observers.sensor_adaptive import bias_gains
    from robofdi.observers.sensor_calibration import GeneralisedSensorEstimator
    from robofdi.sims.flight import DEFAULT_NOISE

    b = belief or _belief(sc)
    P = (min(DEFAULT_NOISE) / np.asarray(DEFAULT_NOISE)) ** 2
    gd = (bias_gains(b.A(), SENSOR_LAMBDA, SENSOR_TAU, [b.state_names.index(c) for c in BIAS_CHANNELS], weights=P)
          if bias else 0.0)
    return GeneralisedSensorEstimator(b.A(), b.B(), b.state_names, b.effectors, list(b.units), DT,
                                      lam=SENSOR_LAMBDA, gamma_d=gd, gamma_c=np.asarray(CALIBRATION_GAMMA), weights=P,
                                      estimate=("bias", "calibration") if bias else ("calibration",))


def sensor_estimator(sc: FlightScenario, belief: FlightSurrogate | None = None):
    from robofdi.observers.sensor_adaptive import SensorBiasEstimator, bias_gains

    b = belief or _belief(sc)
    channels = [b.state_names.index(c) for c in BIAS_CHANNELS]
    gamma = bias_gains(b.A(), SENSOR_LAMBDA, SENSOR_TAU, channels)
    return SensorBiasEstimator(b.A(), b.B(), b.state_names, b.effectors, list(b.units), DT, lam=SENSOR_LAMBDA,
                               gamma=gamma)


def damage_estimator(sc: FlightScenario, belief: FlightSurrogate | None = None):
    from robofdi.observers.damage import DamageEstimator

    b = belief or _belief(sc)
    Lam, _ = design(b)
    return DamageEstimator(b, Lam, DT, gamma=DAMAGE_GAMMA, dead_zone=DAMAGE_DEAD_ZONE, observer="simplified")


def build_loop(sc: FlightScenario) -> ClosedLoop:
    """The closed loop of ``sc``: plant (truth), IDCL on the belief with the scheme's estimators, diagnoses."""
    plant = FlightPlant(DT, noise=None if sc.noise else 0.0)
    b = _belief(sc)
    Lam, ref_model = design(b)
    r = reference_signal(sc)
    xm = ref_model.trajectory(r, sc.duration, DT)
    uses = {"baseline": (), "hybrid": ("effector",), "sensor": ("sensor",), "damage": ("damage",),
            "integrated": ("effector", "sensor", "damage"), "mmst": ("effector",)}[sc.scheme]
    wanted = set(DEFAULT_DIAGNOSERS if sc.diagnosers is None else sc.diagnosers)
    health = "mmst" if sc.scheme == "mmst" else "hybrid_mm"
    if "effector" in uses:
        wanted.add(health)
    controller = IDCLController(b.A2, b.B2, b.weights(), Lam, ref_model,
                                sensor=sensor_estimator(sc, b) if "sensor" in uses else None,
                                damage=damage_estimator(sc, b) if "damage" in uses else None)
    diagnoses = {}
    if "hybrid_mm" in wanted:
        bank = effector_bank(sc, b)
        diagnoses["hybrid_mm"] = Diagnosis(bank, SupervisorStatusDecision(bank.components, bank.effectors))
    if "mmst" in wanted:
        mm = mmst_bank(sc, b)
        diagnoses["mmst"] = Diagnosis(mm, SupervisorStatusDecision(mm.components, mm.effectors))
    if "sensor_bias" in wanted:
        sens = sensor_estimator(sc, b)
        thr = sens.threshold() if sc.sensor_threshold is None else np.asarray(sc.sensor_threshold, dtype=float)
        diagnoses["sensor_bias"] = Diagnosis(sens, ThresholdDecision(sens.components, thr, sens.signatures(),
                                                                     latch=True, blanking=int(1.0 / DT)))
    for name, bias, given in (("sensor_calibration", False, sc.calibration_threshold),
                              ("sensor_generalised", True, sc.generalised_threshold)):
        if name in wanted:
            est = calibration_estimator(sc, b, bias=bias)
            thr = np.full(b.n, 0.05) if given is None else np.asarray(given, dtype=float)
            diagnoses[name] = Diagnosis(est, ThresholdDecision(est.components, thr, est.signatures(), latch=True,
                                                               blanking=int(1.0 / DT)))
    if sc.scheme in ("damage", "integrated") or any(f.kind == "component_wing_damage" for f in sc.faults):
        dam = damage_estimator(sc, b)
        diagnoses["damage"] = Diagnosis(dam, ThresholdDecision(dam.components, np.array([0.05]), dam.signatures()))
    acc = None
    if "effector" in uses:
        acc = MultipleModelReallocation(b.B2(), b.weights(), b.effectors, b.u_min, b.u_max, b.rate_limit, DT)
    cols = ["theta_cmd", "phi_cmd", "beta_cmd"] + [f"xm_{s}" for s in b.state_names]
    return ClosedLoop(plant, controller, _Reference(r, xm, DT), sc.faults, diagnoses, accommodation=acc,
                      health_source=health if acc is not None else None, reference_columns=cols,
                      reference_units=["rad"] * 3 + list(b.units))


def calibrate(sc: FlightScenario, runs: int = 2) -> dict:
    """{"delta": the bank's switching threshold (:func:`calibrate_delta`), "sensor_threshold": per channel 1.5 ×
    the largest |d̂| after the first second of the same fault-free runs (floor 0.005; 1e9 for the channels not
    estimated), "mmst_delta": the non-hybrid bank's δ (the same rule), "calibration_threshold" /
    "generalised_threshold": the calibration-error laws' thresholds by the sensor_bias rule (floors 0.02 and
    0.005)} — run keys ``calibration/<i>``."""
    free = replace(sc, faults=(), scheme="baseline", diagnosers=DIAGNOSERS)
    loop = build_loop(free)
    recs = [loop.run(sc.duration, seed=sc.seed, run_key=f"calibration/{i}") for i in range(runs if sc.noise else 1)]

    def rule(name, floor):
        worst = np.max([np.abs(r.diagnosers[name].residual[int(1.0 / DT):]).max(axis=0) for r in recs], axis=0)
        return np.where(worst > 0, np.maximum(1.5 * worst, floor), 1e9).tolist()

    return {"delta": calibrate_delta(sc, runs, records=recs), "sensor_threshold": rule("sensor_bias", 0.005),
            "mmst_delta": calibrate_delta(sc, runs, records=recs, bank=mmst_bank),
            "calibration_threshold": rule("sensor_calibration", 0.02),
            "generalised_threshold": rule("sensor_generalised", 0.005)}


def calibrate_delta(sc: FlightScenario, runs: int = 2, margin: float = 3.0, records=None, bank=None) -> float:
    """The switching threshold δ: ``margin`` × the largest I₀ − minᵢ Iᵢ of ``runs`` fault-free runs (run keys
    ``calibration/<i>``; the bank — ``bank(scenario)``, default :func:`effector_bank` — replayed with δ = +inf-like
    so it never switches), floored at 1e-7."""
    from robofdi.loop import replay

    free = replace(sc, faults=(), scheme="baseline")
    loop = build_loop(free)
    worst = 0.0
    for i in range(runs if sc.noise else 1):
        rec = records[i] if records is not None else loop.run(sc.duration, seed=sc.seed, run_key=f"calibration/{i}")
        made = (bank or effector_bank)(replace(sc, delta=1e9, mmst_delta=1e9))
        gaps = replay(rec, made, tap=lambda d, _: d.index[0] - d.index[1:].min())
        worst = max(worst, float(np.max(gaps[int(1.0 / DT):])))
    return max(margin * worst, 1e-7)


# ---------------------------------------------------------------------------------------------------- the system
#: The scenario of a flight-surrogate campaign's runs: 10 s missions (the campaign draws each run's pitch step and
#: bank doublet, faults and seed; calibration sets the thresholds).
CAMPAIGN_SCENARIO = FlightScenario(duration=10.0)
_DRAWN = ("faults", "seed", "pitch", "bank", "delta", "sensor_threshold", "mmst_delta", "diagnosers",
          "calibration_threshold", "generalised_threshold")


@dataclass(frozen=True)
class FlightSurrogateOptions:
    """The flight surrogate's configuration (a campaign's ``[system]`` table): the runs' ``scenario``
    (:class:`FlightScenario`, default :data:`CAMPAIGN_SCENARIO`), any field named flat (:mod:`robofdi.config`) —
    duration [s], noise, mismatch (relative error of the belief, in [0, 0.3)), scheme (:data:`SCHEMES`), the bank's
    gains — except what the campaign draws or calibrates; robot_seeds: one calibration of the thresholds each."""

    scenario: FlightScenario = part(FlightScenario, lambda: CAMPAIGN_SCENARIO)
    robot_seeds: tuple = (0,)

    def __post_init__(self):
        check_robot_seeds(self)
        sc = self.scenario
        check_not_set("system", sc, CAMPAIGN_SCENARIO, _DRAWN,
                      "the campaign draws each run's mission, "
                      "faults and seed, calibration sets the thresholds, and its 'diagnosers' list "
                      "names the diagnosers")
        check_fields("system", sc, [
            ("noise", isinstance(sc.noise, bool), "true or false"),
            ("mismatch", isinstance(sc.mismatch, (int, float)) and 0 <= sc.mismatch < 0.3, "a fraction in [0, 0.3)"),
        ])
        object.__setattr__(self, "scenario", replace(sc, duration=float(sc.duration), mismatch=float(sc.mismatch)))


@register_system
class FlightSurrogateSystem(RobotInstances):
    """The over-actuated flight surrogate with Bošković & Mehra's hybrid FDI-ARC (effector lock-in-place and
    hard-over failures reconfigured through the allocation) and the adaptive sensor-bias estimator; missions
    are pitch steps and bank doublets of drawn amplitudes."""

    name = "flight-surrogate"
    options_type = FlightSurrogateOptions

    def diagnosers(self, options):
        return DIAGNOSERS

    def targets(self, options):
        s = flight_surrogate()
        actuator = {e: TargetLimit(float(max(abs(lo), abs(hi))), "rad") for e, lo, hi in zip(s.effectors, s.u_min, s.u_max)}
        sensor = {n: TargetLimit(0.05 if u == "rad" else (0.05 if u == "rad/s" else 2.0), u)
                  for n, u in zip(s.state_names, s.units)}
        return {"actuator": actuator, "sensor": sensor}

    def calibrate(self, options, key, diagnosers):
        sc = replace(options.scenario, seed=int(key), bank=0.4, pitch=0.08)   # the largest mission drawn (conservative δ)
        return cached("flight-surrogate-fdir", {"scenario": repr(replace(sc, faults=()))}, lambda: calibrate(sc))

    def mission(self, options, key, generator):
        bank = float(generator.uniform(0.15, 0.4) * generator.choice([-1.0, 1.0]))
        pitch = float(generator.uniform(0.02, 0.08))
        return Mission(options.scenario.duration, {"bank": bank, "pitch": pitch}, {"bank_rad": bank, "pitch_rad": pitch})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        plan = mission.plan or {}
        sc = replace(options.scenario, faults=tuple(faults), seed=int(key), bank=plan.get("bank", 0.3),
                     pitch=plan.get("pitch", 0.05), delta=float(calibration["delta"]),
                     sensor_threshold=tuple(calibration["sensor_threshold"]),
                     mmst_delta=float(calibration["mmst_delta"]), diagnosers=tuple(diagnosers),
                     calibration_threshold=tuple(calibration["calibration_threshold"]),
                     generalised_threshold=tuple(calibration["generalised_threshold"]))
        return Parts(build_loop(sc), sc.duration, None, seed, "campaign", "campaign-flight-surrogate",
                     {"robot_seed": int(key), "scheme": sc.scheme})
