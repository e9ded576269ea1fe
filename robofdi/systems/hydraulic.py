"""Hydraulic wheel-actuator scenarios: operating profile → rig, controller, faults and calibrated diagnosers.

What a campaign engine needs, each a function of its own:

* :func:`operating_profile` — a random target speed, ramp and load (throttle) drawn from a seed;
* :data:`FAULT_TARGETS` — fault targets per family with their magnitude limits;
* :func:`calibrate` — fault-free runs over random profiles → mlp_ar training + thresholds (a picklable
  :class:`HydraulicCalibration`), once;
* :func:`run_scenario` — one run with the given faults and seed → :class:`~robofdi.record.Record`
  (:func:`robofdi.evaluate.summarize` gives its summary).

Diagnosers (all built from the catalogue model or fault-free data, never from the rig's parameters):
``nlar`` (eqs. (15)–(19), load compensated), ``linear_ar`` (the same engine on the model linearised at the nominal
operating point), ``plar`` (nine regions, blended near borders), ``nnar`` (the book's nearly nonlinear AR: linear
AR's null space applied to the nonlinear equations, Sec. 9; equal to NLAR on this rig), ``mlp_ar`` (a data-driven
baseline, not from the chapter: an MLP predictor of ẏ trained on fault-free runs), and ``nlar_better`` (better
modelling: measured supply pressure, pressure-equation parameters calibrated on fault-free data).

The system (:class:`HydraulicSystem`, registered as ``hydraulic``: its options, fault targets, calibration per robot instance,
missions drawn from a seed and runs; :class:`robofdi.protocols.System`) closes the module.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import lru_cache

import numpy as np

from robofdi.calibration import cached
from robofdi.checks import check_fields, check_robot_seeds, is_int, is_positive
from robofdi.config import check_not_set, part
from robofdi.control.speed import RPM, SpeedPID, SpeedRamp
from robofdi.decision import Signature, ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.faults import Fault, check_faults
from robofdi.loop import ClosedLoop, Diagnosis, Rates, diagnose_record
from robofdi.models.hydraulic import CATALOGUE, HydraulicParameters, hydraulic_domain, hydraulic_model, with_variants
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.record import Record
from robofdi.redundancy.baselines import (
    MLPARResidual, linear_ar_residual, nnar_design, nnar_residual, plar_residual, train_mlp_ar,
)
from robofdi.redundancy.derivatives import SavitzkyGolay, estimate_derivatives
from robofdi.redundancy.nlar import derive_nlar
from robofdi.redundancy.residuals import nlar_residual
from robofdi.seeding import rng
from robofdi.sims.hydraulic import HydraulicRig, RigParameters, RigSensors
from robofdi.systems import RobotInstances, register_system

__all__ = ["HydraulicScenario", "HydraulicCalibration", "calibration", "operating_profile", "FAULT_TARGETS", "DIAGNOSERS",
           "calibrate", "run_scenario", "build_loop", "nominal_operating_point", "fit_pressure_parameters", "TABLE1",
           "table1_fault", "fault_free_rms", "leak_flow_share"]

DIAGNOSERS = ("nlar", "linear_ar", "plar", "nnar", "mlp_ar", "nlar_better")

#: Fault targets per family, with the magnitude range a campaign may draw from (in the kind's unit).
FAULT_TARGETS = {
    "component": {"component_open_winding": {"servovalve": (0.2, 1.0)},
                  "component_valve_sticking": {"servovalve": (0.002, 0.02)},
                  "component_leak": {"motor": (0.002, 0.05)}},
    "sensor": {"sensor_dropout": {"shaft_speed": (1.0, 1.0)}, "sensor_bias": {"shaft_speed": (-0.1, 0.1),
                                                                              "load_pressure": (-5e5, 5e5)}},
    "actuator": {"actuator_additive": {"servovalve": (-0.05, 0.05)}},
}

#: Isolation signatures: a tachometer fault breaks the speed equation (R1), a valve fault the pressure equation.
SIGNATURES = {
    "nlar": (Signature("shaft_speed", {"R1"}, {"R2", "R4", "R5"}), Signature("servovalve", {"R4"}, {"R1", "R2", "R5"})),
}
SIGNATURES["nnar"] = SIGNATURES["nlar"]          # the same tests on this rig (Sec. 5 footnote)


@dataclass(frozen=True)
class HydraulicScenario:
    """One rig run: the operating profile (target speed [rpm], ramp time [s], load throttle area [m²]), faults,
    duration [s], seed (sensor noise), the derivative filter (window, order), diagnosers, threshold margin, and
    the nlar tests R2 / R5 "corrected" (default) or "as_printed" (digest §4.3). Composed (:mod:`robofdi.config`)
    of the simulator's configuration: the ``rig`` (:class:`~robofdi.sims.hydraulic.RigParameters`, its throttle
    area set by ``throttle_area``) and its ``sensors`` (:class:`~robofdi.sims.hydraulic.RigSensors`)."""

    name: str = "baseline"
    faults: tuple = ()
    duration: float = 8.0
    target_rpm: float = 5.0
    ramp_time: float = 2.0
    throttle_area: float = 1.2e-6
    seed: int = 0
    window: int = 41
    order: int = 3
    diagnosers: tuple = DIAGNOSERS
    margin: float = 1.3
    r2_variant: str = "corrected"
    r5_variant: str = "corrected"
    rig: RigParameters = part(RigParameters)
    sensors: RigSensors = part(RigSensors)

    def __post_init__(self):
        if not all(isinstance(f, Fault) for f in self.faults):
            raise RobofdiError("HydraulicScenario: field 'faults' must hold Fault objects")
        object.__setattr__(self, "faults", tuple(self.faults))
        unknown = [d for d in self.diagnosers if d not in DIAGNOSERS]
        if unknown:
            raise RobofdiError(f"HydraulicScenario: field 'diagnosers' has unknown {unknown}; expected some of {DIAGNOSERS}")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise RobofdiError(f"HydraulicScenario: field 'duration' must be > 0 s, got {self.duration!r}")
        if not (np.isfinite(self.throttle_area) and self.throttle_area > 0):
            raise RobofdiError(f"HydraulicScenario: field 'throttle_area' must be > 0 m², got {self.throttle_area!r}")
        SpeedRamp(self.target_rpm, self.ramp_time)        # validates both
        for k in ("r2_variant", "r5_variant"):
            if getattr(self, k) not in ("corrected", "as_printed"):
                raise RobofdiError(f"HydraulicScenario: field {k!r} must be 'corrected' or 'as_printed', "
                                   f"got {getattr(self, k)!r}")
        check_faults(self.faults, self.simulator(), self.duration)

    def simulator(self) -> HydraulicRig:
        return HydraulicRig(replace(self.rig, throttle_area=self.throttle_area), self.sensors)

    def filter(self) -> SavitzkyGolay:
        return SavitzkyGolay(dt=0.001, window=self.window, order=self.order, max_derivative=2)

    def profile(self) -> dict:
        return {"target_rpm": self.target_rpm, "ramp_time": self.ramp_time, "throttle_area": self.throttle_area}


def operating_profile(seed: int) -> dict:
    """A random operating profile: target 4–6 rpm, ramp 1.5–2.5 s, load throttle 0.9–2.5 mm² (seeded)."""
    g = rng(seed, "hydraulic", "profile")
    return {"target_rpm": float(g.uniform(4.0, 6.0)), "ramp_time": float(g.uniform(1.5, 2.5)),
            "throttle_area": float(g.uniform(0.9e-6, 2.5e-6))}


def controller(params: HydraulicParameters = CATALOGUE) -> SpeedPID:
    """PI with flow feedforward from the catalogue (spec digest §6.2)."""
    return SpeedPID(0.001, kp=0.005, ki=0.5, feedforward=params.d_m / (params.K_f * np.sqrt(2 * params.p_s / params.rho)))


def nominal_operating_point(params: HydraulicParameters = CATALOGUE, rpm: float = 5.0,
                            throttle_area: float = 1.2e-6) -> tuple[float, float]:
    """(u0, p0): steady valve opening and load pressure at ``rpm`` for the catalogue motor and throttle."""
    w = rpm * RPM
    pL = 0.5 * params.rho * (params.d_m * w / throttle_area) ** 2
    p0 = pL + params.B_m * w / params.d_m
    u0 = (params.d_m * w + params.C_tm * p0) / (params.K_f * np.sqrt(2 * (params.p_s - p0) / params.rho))
    return float(u0), float(p0)


@lru_cache(maxsize=4)
def _design(load_model: str = "measured_pump_pressure"):
    m = hydraulic_model(CATALOGUE, load_model)
    return derive_nlar(m, hydraulic_domain(m))


@lru_cache(maxsize=1)
def _nnar_design():
    return nnar_design(_design(), CATALOGUE, *nominal_operating_point())


@dataclass
class HydraulicCalibration:
    """Thresholds per diagnoser (residual units), the trained mlp_ar network, the calibrated pressure parameters,
    and the profiles/seeds used. Picklable."""

    thresholds: dict
    mlp_ar: object
    better_params: dict
    blanking: int
    profiles: list = field(default_factory=list)
    margin: float = 1.3


def _diagnosers(sc: HydraulicScenario, cal: HydraulicCalibration | None, names: Sequence[str]) -> dict:
    sim = sc.simulator()
    flt = sc.filter()
    meas, acts = sim.sensor_channels, sim.actuators
    out = {}
    for name in names:
        if name == "nlar":
            design = with_variants(_design(), sc.r2_variant, sc.r5_variant)
            out[name] = nlar_residual(design, meas, acts, flt, SIGNATURES["nlar"])
        elif name == "nlar_better":
            params = dict(cal.better_params) if cal is not None else {}
            out[name] = nlar_residual(_design(), meas, acts, flt, SIGNATURES["nlar"], params=params,
                                      measured={"p_s": "supply_pressure"})
        elif name == "linear_ar":
            out[name] = linear_ar_residual(CATALOGUE, *nominal_operating_point(), meas, acts, flt)
        elif name == "plar":
            out[name] = plar_residual(CATALOGUE, meas, acts, flt)
        elif name == "nnar":
            out[name] = nnar_residual(_nnar_design(), meas, acts, flt, SIGNATURES["nnar"])
        elif name == "mlp_ar":
            if cal is None or cal.mlp_ar is None:
                continue
            out[name] = MLPARResidual(cal.mlp_ar, meas, acts, flt)
    return out


def build_loop(sc: HydraulicScenario, cal: HydraulicCalibration | None, diagnosers: Sequence[str] | None = None,
               decisions: bool = True) -> ClosedLoop:
    """The scenario's closed loop; with ``decisions`` every diagnoser gets its calibrated threshold decision."""
    sim = sc.simulator()
    diagnoses = {}
    for name, d in _diagnosers(sc, cal, sc.diagnosers if diagnosers is None else diagnosers).items():
        decision = None
        if decisions and cal is not None:
            decision = ThresholdDecision(d.components, cal.thresholds[name], d.signatures(), blanking=cal.blanking)
        diagnoses[name] = Diagnosis(d, decision)
    return ClosedLoop(sim, controller(), SpeedRamp(sc.target_rpm, sc.ramp_time), sc.faults, diagnoses,
                      Rates(1000.0, 1000.0), reference_columns=["shaft_speed_ref"], reference_units=["rad/s"])


def run_scenario(sc: HydraulicScenario, cal: HydraulicCalibration | None, run_key: str = "run",
                 progress: Callable[[int], None] | None = None, diagnosers: Sequence[str] | None = None) -> Record:
    """One closed-loop run with the scenario's faults and seed (every diagnoser and decision online)."""
    return parts(sc, cal, run_key, diagnosers).run(progress)


def parts(sc: HydraulicScenario, cal: HydraulicCalibration | None, run_key: str = "run",
          diagnosers: Sequence[str] | None = None) -> Parts:
    """The scenario's run, built (:class:`~robofdi.protocols.Parts`): its closed loop (:func:`build_loop`), seed
    and record metadata."""
    loop = build_loop(sc, cal, diagnosers)
    meta = {"mjcf": loop.simulator.path, "profile": sc.profile(), "derivative_filter": asdict(sc.filter()),
            "derivative_delay": sc.filter().delay, "rig": asdict(sc.rig), "primary_diagnoser": "nlar",
            "joint_names": ["motor_shaft"]}
    return Parts(loop, sc.duration, None, sc.seed, run_key, sc.name, meta)


def fit_pressure_parameters(records: Sequence[Record], flt: SavitzkyGolay,
                            params: HydraulicParameters = CATALOGUE) -> dict:
    """Better modelling: β_e, C_tm, K_f of the pressure equation (d_m, v_t from the catalogue) by least squares on
    fault-free records, with the measured supply pressure: ṗ_l = a₁θ̇ + a₂p_l + a₃ sqrt(2(p_s − p_l)/ρ)u."""
    rows, rhs = [], []
    for rec in records:
        y, u = rec.signals["y_meas"], rec.signals["u_diag"][:, 0]
        d = estimate_derivatives(np.column_stack([y[:, 0], y[:, 1], y[:, 3], np.r_[0.0, u[:-1]]]), flt)
        keep = slice(int(0.5 / flt.dt), None)
        w, p, ps, uu, pd = d[keep, 0, 0], d[keep, 0, 1], d[keep, 0, 2], d[keep, 0, 3], d[keep, 1, 1]
        phi = np.sqrt(2 * np.maximum(ps - p, 1.0) / params.rho)
        rows.append(np.column_stack([w, p, phi * uu]))
        rhs.append(pd)
    a, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    beta = -a[0] * params.v_t / (4 * params.d_m)
    return {"beta_e": float(beta), "C_tm": float(-a[1] * params.v_t / (4 * beta)),
            "K_f": float(a[2] * params.v_t / (4 * beta))}


def calibration(base: HydraulicScenario, runs: int, seed: int, progress: Callable[[int], None] | None = None,
                cache: bool = True) -> tuple[HydraulicCalibration, bool]:
    """:func:`calibrate`, cached per (base scenario, runs, seed) by :mod:`robofdi.calibration`; returns
    (calibration, True if it came from the cache)."""
    return cached("hydraulic", {"base": repr(base), "runs": runs, "seed": seed},
                  lambda: calibrate(base, runs=runs, seed=seed, progress=progress), cache=cache)


def calibrate(base: HydraulicScenario | None = None, runs: int = 8, seed: int = 1000,
              progress: Callable[[int], None] | None = None) -> HydraulicCalibration:
    """Fault-free runs on ``runs`` random operating profiles (seeds seed, seed+1, …): the first half trains mlp_ar
    and fits the better model, all of them set thresholds = margin × max |r| (Caccavale & Villani Sec. 6 rule)."""
    base = base or HydraulicScenario()
    if runs < 2:
        raise RobofdiError(f"calibrate: field 'runs' must be >= 2 (training and thresholds), got {runs}")
    records, profiles = [], []
    for i in range(runs):
        prof = operating_profile(seed + i)
        sc = replace(base, name=f"calibration-{i}", faults=(), seed=seed + i, **prof)
        records.append(run_scenario(sc, None, run_key=f"calibration/{i}", progress=progress, diagnosers=()))
        profiles.append({**prof, "seed": seed + i})
    flt = base.filter()
    half = records[: max(1, runs // 2)]
    mlp = train_mlp_ar(half, flt, seed=seed) if "mlp_ar" in base.diagnosers else None
    better = fit_pressure_parameters(half, flt)
    cal = HydraulicCalibration({}, mlp, better, flt.window, profiles, base.margin)
    for name, d in _diagnosers(base, cal, base.diagnosers).items():
        residuals = [diagnose_record(rec, Diagnosis(d), Rates(1000.0, 1000.0), progress).residual for rec in records]
        cal.thresholds[name] = calibrate_thresholds(residuals, base.margin, skip=flt.window)
    return cal


def fault_free_rms(record: Record, name: str, since: float = 0.5) -> dict:
    """RMS of each residual component of diagnoser ``name`` over t ≥ ``since`` (residual units)."""
    tr = record.diagnosers[name]
    keep = tr.time >= since
    return {c: float(np.sqrt(np.mean(tr.residual[keep, j] ** 2))) for j, c in enumerate(tr.components)}



#: The chapter's Table 1 faults, as run by ``ch6-hydraulic`` (name → kind, target, magnitude, onset offset, end).
#: The sticking valve acts from the ramp on (stick–slip only shows while the command moves: Fig. 7 is on the ramp).
TABLE1 = {
    "open_winding": ("component_open_winding", "servovalve", 1.0),
    "sticking_valve": ("component_valve_sticking", "servovalve", 0.01),
    "tachometer_loss": ("sensor_dropout", "shaft_speed", 0.0),
    "leak": ("component_leak", "motor", 0.008),
}


def table1_fault(name: str, onset: float = 5.0, magnitude: float | None = None) -> Fault:
    """The Table-1 fault ``name`` (open winding: open circuit; sticking: 1 % stroke stiction band from 0.5 s;
    tachometer: reads zero; leak: 0.008 mm² to tank, ≈ 2 % of the motor flow at 5 rpm)."""
    if name not in TABLE1:
        raise RobofdiError(f"table1_fault: unknown fault {name!r}; expected one of {list(TABLE1)}")
    kind, target, default = TABLE1[name]
    start = 0.5 if name == "sticking_valve" else onset
    return Fault(name, kind, target, onset=start, magnitude=default if magnitude is None else magnitude)


def leak_flow_share(area_mm2: float, rpm: float = 5.0, rig: RigParameters | None = None,
                    load_pressure: float = 1.27e6) -> float:
    """Leak flow through ``area_mm2`` as a share of the motor flow d_m θ̇ at ``rpm`` (rig truth, for reporting)."""
    rig = rig or RigParameters()
    q_leak = area_mm2 * 1e-6 * np.sqrt((rig.supply_pressure + load_pressure) / rig.rho)
    return float(q_leak / (rig.d_m * rpm * RPM))


# ---------------------------------------------------------------------------------------------------- the system
#: The scenario of a hydraulic campaign's runs (the campaign draws each run's operating profile, faults and seed).
CAMPAIGN_SCENARIO = HydraulicScenario(name="campaign-hydraulic")
_DRAWN = ("name", "faults", "seed", "diagnosers", "target_rpm", "ramp_time", "throttle_area")


@dataclass(frozen=True)
class HydraulicOptions:
    """The hydraulic rig's configuration (a campaign's ``[system]`` table, :mod:`robofdi.systems.hydraulic`): the
    runs' ``scenario`` (:class:`HydraulicScenario` with its rig and sensors; default :data:`CAMPAIGN_SCENARIO`),
    any of its fields named flat or nested (:mod:`robofdi.config`) — duration [s] of every run (3–600), margin
    (threshold margin >= 1), window / order of the derivative filter, rig and sensor parameters — except what the
    campaign draws (the operating profile, faults, seed; its ``diagnosers`` list). robot_seeds: one calibration each
    (fault-free runs on the random operating profiles of seeds 1000·(1 + robot seed) + i); calibration_runs (>= 2:
    half train mlp_ar and fit the better model, all set thresholds)."""

    scenario: HydraulicScenario = part(HydraulicScenario, lambda: CAMPAIGN_SCENARIO)
    robot_seeds: tuple = (0,)
    calibration_runs: int = 8

    def __post_init__(self):
        check_robot_seeds(self)
        sc = self.scenario
        check_not_set("system", sc, CAMPAIGN_SCENARIO, _DRAWN,
                      "the campaign draws each run's operating "
                      "profile, faults and seed, and its 'diagnosers' list names the diagnosers")
        check_fields("system", sc, [
            ("duration", is_positive(sc.duration, 600) and sc.duration >= 3, "a time in [3, 600] s"),
            ("margin", is_positive(sc.margin) and sc.margin >= 1, "a number >= 1"),
        ])
        check_fields("system", self, [("calibration_runs", is_int(self.calibration_runs, 2), "an integer >= 2")])
        object.__setattr__(self, "scenario", replace(sc, duration=float(sc.duration), margin=float(sc.margin)))


@register_system
class HydraulicSystem(RobotInstances):
    """The hydraulic wheel-actuator rig: random operating profiles (target speed, ramp, load throttle), valve,
    leak and tachometer faults, the nlar residuals and their baselines online (:mod:`robofdi.systems.hydraulic`)."""

    name = "hydraulic"
    options_type = HydraulicOptions

    def diagnosers(self, options):

        return DIAGNOSERS

    def targets(self, options):

        limits = {"shaft_speed": (2.0, "rad/s"), "load_pressure": (2e7, "Pa"), "pump_pressure": (2e7, "Pa"),
                  "supply_pressure": (2e7, "Pa")}                     # sensor ranges (tachometer, 200 bar gauges)
        comps = {kind: {t: TargetLimit(hi, "mm^2" if kind == "component_leak" else "1") for t, (_, hi) in tg.items()}
                 for kind, tg in FAULT_TARGETS["component"].items()}
        return {"actuator": {"servovalve": TargetLimit(1.0, "1 (valve stroke)")},
                "sensor": {c: TargetLimit(*v) for c, v in limits.items()}, **comps}

    def calibrate(self, options, key, diagnosers):
        # only the diagnosers asked for (each one's thresholds are its own; mlp_ar's training only when it is run)
        base = replace(options.scenario, diagnosers=tuple(diagnosers))
        return calibration(base, options.calibration_runs, 1000 * (1 + int(key)))

    def mission(self, options, key, generator):

        profile = operating_profile(int(generator.integers(2**31)))
        return Mission(options.scenario.duration, profile, dict(profile))

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        sc = replace(options.scenario, faults=tuple(faults), seed=int(seed), diagnosers=tuple(diagnosers), **mission.plan)
        return parts(sc, calibration, "campaign")
