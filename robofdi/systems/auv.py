"""The AUV's configuration → calibrated closed loop (shared by experiments ``ch4-*``, campaigns and tests).

The pieces a campaign engine needs, each usable alone:

* :func:`draw_mission` — a random mission from a seed (:func:`robofdi.control.auv.random_mission`);
* :data:`FAULT_TARGETS` / :func:`fault_targets` — per fault kind, its targets on the vehicle and magnitude limits;
* :func:`calibrate` — fault-free missions (their own seeds, never the test mission) → :class:`AuvCalibration`
  (the identified current characteristic and every diagnoser's thresholds; a small picklable dataclass);
* :func:`run_scenario` — one scenario with given faults, seed and accommodation variant → (Record, summary).

Variants of accommodation (all use the same allocator, so the comparison is fair): ``"no_ftc"`` (allocation with
every thruster assumed healthy), ``"oracle"`` (the fault labels: a bound, explicitly named) and ``"diagnosed"``
(the health of :attr:`AuvScenario.health_source`, one diagnosis sample late).

The system (:class:`AuvSystem`, registered as ``auv``: its options, fault targets, calibration per robot instance,
missions drawn from a seed and runs; :class:`robofdi.protocols.System`) closes the module.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from robofdi.calibration import cached
from robofdi.checks import check_fields, check_robot_seeds, is_int, is_positive
from robofdi.config import check_not_set, part
from robofdi.control.auv import POSE_NAMES, MissionLimits, TaskSpaceAuvControl, random_mission
from robofdi.control.trajectory import Sequence as Mission
from robofdi.decision import NisBankDecision, ThresholdDecision, calibrate_thresholds, startup_samples
from robofdi.errors import RobofdiError
from robofdi.faults import Fault, check_faults
from robofdi.ftc.allocation import ALLOCATORS, ThrustReallocation
from robofdi.loop import ORACLE, ClosedLoop, Diagnosis, diagnose_record, diagnoser_inputs
from robofdi.models.auv import AuvModel, AuvModelMismatch
from robofdi.observers.auv import (
    CurrentMap,
    DepthSwitchingControl,
    DepthVote,
    ForceObserver,
    VoltageResidual,
    identify_current_characteristic,
    identify_depth_arx,
    identify_supply_resistance,
    vertical_force,
)
from robofdi.observers.ekf_bank import EkfBank, calibrate_process_noise
from robofdi.protocols import Mission as CampaignMission
from robofdi.protocols import Parts, TargetLimit
from robofdi.record import Record
from robofdi.seeding import rng
from robofdi.sims.auv import AuvPlant, AuvSimulator
from robofdi.systems import RobotInstances, register_system

__all__ = ["AuvScenario", "AuvCalibration", "calibration", "calibration_description",
           "DIAGNOSERS", "VARIANTS", "FAULT_TARGETS", "fault_targets", "draw_mission",
           "odin_mission", "roby2_mission", "calibrate", "build_loop", "run_scenario", "tracking_rms", "thruster_names",
           "current_map_regions", "check_scenario", "depth_switch_time", "ALL_DIAGNOSERS"]

DIAGNOSERS = ("voltage_residual", "current_map", "force_observer", "ekf_bank")
#: Every diagnoser a scenario may run (depth_vote: the ODIN depth-sensor scheme, with its ARX virtual sensor).
ALL_DIAGNOSERS = DIAGNOSERS + ("depth_vote",)
VARIANTS = ("no_ftc", "oracle", "diagnosed")
#: The allocation choices: the chapter-4 allocators, and "smc_ca" (Edwards, Alwi & Tan §6: sliding-mode control with
#: the on-line allocation W = I − K̂, :mod:`robofdi.ftc.smc_auv`; it replaces the controller too).
ALLOCATIONS = ALLOCATORS + ("smc_ca",)


def thruster_names(n: int = 8) -> list[str]:
    return [f"thruster{i}" for i in range(1, n + 1)]


#: Fault kind -> (targets, (min, max) magnitude in the kind's unit) on the shipped vehicle. Thruster kinds act on
#: every thruster; the sensor kinds on the channels named.
FAULT_TARGETS: dict[str, tuple[tuple[str, ...], tuple[float, float]]] = {
    "actuator_float": (tuple(thruster_names()), (0.0, 0.0)),                       # rotor failure (drive zeroed)
    "actuator_loss_of_effectiveness": (tuple(thruster_names()), (0.3, 1.0)),
    "actuator_lock_in_place": (tuple(thruster_names()), (0.0, 0.0)),               # stuck command
    "component_thruster_blocking": (tuple(thruster_names()), (1.0, 1.0)),
    "component_thruster_flooding": (tuple(thruster_names()), (0.2, 0.6)),
    "sensor_dropout": (("depth", "u", "v", "w"), (0.0, 0.0)),                      # depth zeroing, DVL dropout
    "sensor_bias": (("yaw",), (-0.3, 0.3)),                                        # compass bias [rad]
}


def fault_targets(kind: str | None = None):
    """:data:`FAULT_TARGETS`, or one kind's (targets, limits); an unknown kind is a clear error."""
    if kind is None:
        return dict(FAULT_TARGETS)
    if kind not in FAULT_TARGETS:
        raise RobofdiError(f"fault_targets: kind {kind!r} is not used on the AUV; expected one of {sorted(FAULT_TARGETS)}")
    return FAULT_TARGETS[kind]


def odin_mission(duration: float, start_depth: float = 5.0, side: float = 2.0, speed: float = 0.2,
                 dwell: float = 3.0) -> Mission:
    """ODIN-like 6-DOF task (digest §6.8): a ``side`` m square in x–y with ±1 m depth steps and ±30° yaw, peak
    speed ``speed``, repeated until ``duration``."""
    corners = [(side, 0.0, 1.0, np.pi / 6), (side, side, 0.0, -np.pi / 6), (0.0, side, -1.0, 0.0), (0.0, 0.0, 0.0, 0.0)]
    wp = [np.array([0.0, 0.0, -start_depth, 0.0, 0.0, 0.0])]
    durations, t, k = [], 0.0, 0
    while t < duration:
        x, y, dz, yaw = corners[k % 4]
        nxt = np.array([x, y, -start_depth - dz, 0.0, 0.0, yaw])
        d = max(4.0, 1.875 * np.linalg.norm(nxt[:3] - wp[-1][:3]) / speed)
        wp += [nxt, nxt]
        durations += [d, dwell]
        t += d + dwell
        k += 1
    return Mission.through(wp, durations)


def roby2_mission(seed: int, duration: float, limits: MissionLimits | None = None, start_depth: float = 5.0,
                  name: str = "mission") -> Mission:
    """A seeded mission for a vehicle without sway thrust (Roby 2): surge legs along world x (yaw 0) to a random
    x in ±``half_width``, each followed by a turn on the spot to a random yaw in ±``yaw`` and back, with dwells
    (stream ``("mission", name)``)."""
    limits = limits or MissionLimits()
    g = rng(seed, "mission", name)
    wp = [np.array([0.0, 0.0, -start_depth, 0.0, 0.0, 0.0])]
    durations, t = [], 0.0
    while t < duration:
        here = wp[-1].copy()
        nxt = here.copy()
        nxt[0] = g.uniform(-limits.half_width, limits.half_width)
        turn = here.copy()
        turn[0], turn[5] = nxt[0], g.uniform(-limits.yaw, limits.yaw)
        d = max(4.0, 1.875 * abs(nxt[0] - here[0]) / limits.speed)
        d_turn = max(4.0, 1.875 * abs(turn[5]) / 0.2)
        wp += [nxt, nxt, turn, turn, nxt, nxt]
        durations += [d, limits.dwell, d_turn, limits.dwell, d_turn, limits.dwell]
        t += d + d_turn * 2 + 3 * limits.dwell
    return Mission.through(wp, durations)


def draw_mission(seed: int, duration: float, limits: MissionLimits | None = None, name: str = "mission") -> Mission:
    """A random mission of ``duration`` s from ``seed`` (stream ``("mission", name)``)."""
    return random_mission(seed, duration, limits or MissionLimits(), name=name)


@dataclass(frozen=True)
class AuvScenario:
    """One AUV scenario: vehicle, mission, faults, diagnosers, accommodation; composed (:mod:`robofdi.config`) of
    the simulator's configuration ``plant`` (:class:`~robofdi.sims.auv.AuvPlant`: mjcf, control_dt [s] — diagnosis
    runs at the control rate —, current [m/s], sensors, thrust_limit [N], floor_depth [m]) and the belief's
    ``mismatch`` (:class:`~robofdi.models.auv.AuvModelMismatch`).

    mission: "odin" (:func:`odin_mission`) or "random" (:func:`draw_mission` from ``seed``); duration [s];
    allocation: one of
    :data:`~robofdi.ftc.allocation.ALLOCATORS`; variant: one of :data:`VARIANTS`; health_source: the diagnoser whose
    health the "diagnosed" variant uses; calibration_runs × calibration_duration [s] of fault-free missions;
    threshold_margin ≥ 1; blanking [s] of start-up samples; current_map_filter [s]: time constant of the current
    map's filters (a flooded thruster's mismatch is persistent; 0.5 s as the digest's persistence); ekf_window [s]:
    the EKF bank's NIS window W; ekf_margin ≥ 1: its process noise is calibrated so that the fault-free nominal NIS
    peaks at bound/ekf_margin. mission "roby2": :func:`roby2_mission` (for a vehicle without sway thrust).
    plan: a given reference (a campaign's drawn mission) flown instead of ``mission``.
    """

    name: str = "ch4-auv"
    plant: AuvPlant = part(AuvPlant)
    mismatch: AuvModelMismatch = part(AuvModelMismatch)
    mission: str = "odin"
    duration: float = 120.0
    seed: int = 0
    faults: tuple = ()
    diagnosers: tuple = DIAGNOSERS
    allocation: str = "constrained"
    variant: str = "diagnosed"
    health_source: str = "voltage_residual"
    calibration_runs: int = 3
    calibration_duration: float = 240.0
    threshold_margin: float = 2.0
    blanking: float = 3.0
    start_depth: float = 5.0
    current_map_filter: float = 0.5
    depth_redundancy: bool = False
    ekf_window: float = 2.0
    ekf_margin: float = 1.1
    plan: Any = None

    def __post_init__(self):
        object.__setattr__(self, "faults", tuple(self.faults))
        object.__setattr__(self, "diagnosers", tuple(self.diagnosers))
        if self.mission not in ("odin", "random", "roby2"):
            raise RobofdiError(f"AuvScenario: field 'mission' must be 'odin', 'random' or 'roby2', got {self.mission!r}")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise RobofdiError(f"AuvScenario: field 'duration' must be > 0 s, got {self.duration!r}")
        unknown = [d for d in self.diagnosers if d not in ALL_DIAGNOSERS]
        if unknown:
            raise RobofdiError(f"AuvScenario: unknown diagnoser {unknown[0]!r}; expected some of {ALL_DIAGNOSERS}")
        if self.allocation not in ALLOCATIONS:
            raise RobofdiError(f"AuvScenario: field 'allocation' must be one of {ALLOCATIONS}, got {self.allocation!r}")
        if self.variant not in VARIANTS:
            raise RobofdiError(f"AuvScenario: field 'variant' must be one of {VARIANTS}, got {self.variant!r}")
        if self.variant == "diagnosed" and self.health_source not in self.diagnosers:
            raise RobofdiError(f"AuvScenario: field 'health_source' must be one of the diagnosers {self.diagnosers}, "
                               f"got {self.health_source!r}")
        if not (isinstance(self.calibration_runs, int) and self.calibration_runs >= 1):
            raise RobofdiError(f"AuvScenario: field 'calibration_runs' must be an integer >= 1, got {self.calibration_runs!r}")
        if not (np.isfinite(self.threshold_margin) and self.threshold_margin >= 1):
            raise RobofdiError(f"AuvScenario: field 'threshold_margin' must be >= 1, got {self.threshold_margin!r}")
        for f in self.faults:
            if not isinstance(f, Fault):
                raise RobofdiError(f"AuvScenario: field 'faults' must hold Fault objects, got {f!r}")

    def simulator(self) -> AuvSimulator:
        return self.plant.simulator(self.seed)

    def nominal_model(self, sim: AuvSimulator) -> AuvModel:
        return sim.nominal_model(self.mismatch)

    def reference(self) -> Mission:
        if self.plan is not None:                   # a given mission (a campaign's draw)
            return self.plan
        if self.mission == "odin":
            return odin_mission(self.duration, self.start_depth)
        if self.mission == "roby2":
            return roby2_mission(self.seed, self.duration, start_depth=self.start_depth)
        return draw_mission(self.seed, self.duration)

    @property
    def start_pose(self) -> np.ndarray:
        return np.array([0.0, 0.0, self.start_depth, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class AuvCalibration:
    """What calibration learned (picklable): the current characteristic θ (3,), each diagnoser's thresholds, the
    depth ARX, the EKF bank's force-mismatch level q [N²] and the supply resistance R̂_s [Ω]."""

    characteristic: np.ndarray
    thresholds: Mapping[str, np.ndarray]
    blanking: int
    sample_time: float
    arx: np.ndarray | None = None
    ekf_process_noise: float | None = None
    supply_resistance: float = 0.0


def _depth_vote(scenario: AuvScenario, model: AuvModel, channels, arx) -> DepthVote:
    plant = scenario.plant
    return DepthVote(model, channels, plant.control_dt, arx, plant.floor_depth, thrust_limit=plant.thrust_limit)


def _ekf_bank(scenario: AuvScenario, model: AuvModel, channels, process_noise: float) -> EkfBank:
    return EkfBank(model, channels, scenario.plant.control_dt, process_noise, window=scenario.ekf_window,
                   thrust_limit=scenario.plant.thrust_limit)


def _diagnosers(scenario: AuvScenario, model: AuvModel, channels, characteristic, arx=None, ekf_q=None,
                supply_resistance: float = 0.0) -> dict:
    T = scenario.plant.control_dt
    make = {
        "ekf_bank": lambda: _ekf_bank(scenario, model, channels, ekf_q or 1.0),
        "depth_vote": lambda: _depth_vote(scenario, model, channels, arx),
        "voltage_residual": lambda: VoltageResidual(model, channels, T, thrust_limit=scenario.plant.thrust_limit,
                                                    supply_resistance=supply_resistance),
        "current_map": lambda: CurrentMap(model, channels, T, characteristic, tau=scenario.current_map_filter,
                                          thrust_limit=scenario.plant.thrust_limit),
        "force_observer": lambda: ForceObserver(model, channels, T, thrust_limit=scenario.plant.thrust_limit),
    }
    return {name: make[name]() for name in scenario.diagnosers}


def _controller(model: AuvModel, allocation: str = "constrained"):
    if allocation == "smc_ca":
        from robofdi.ftc.smc_auv import SlidingModeAuvControl

        return SlidingModeAuvControl(model)
    return TaskSpaceAuvControl(model, kp=(1.0, 1.0, 1.0, 4.0, 4.0, 4.0), kv=(2.0, 2.0, 2.0, 4.0, 4.0, 4.0))


def _allocation(scenario: AuvScenario, model: AuvModel):
    limit = scenario.plant.thrust_limit
    if scenario.allocation == "smc_ca":
        from robofdi.ftc.smc_auv import HealthWeightedAllocation

        return HealthWeightedAllocation(model.B, model.thrusters, limit)
    return ThrustReallocation(model.B, model.thrusters, limit, scenario.allocation)


def _reference_columns() -> tuple[list[str], list[str]]:
    cols = [f"{n}_{part}" for part in ("d", "dot_d", "ddot_d") for n in POSE_NAMES]
    units = ["m"] * 3 + ["rad"] * 3 + ["m/s"] * 3 + ["rad/s"] * 3 + ["m/s²"] * 3 + ["rad/s²"] * 3
    return cols, units


#: Envelope of the calibration missions: wider than the missions flown (yaw ±45° vs ±30°, 0.25 m/s vs 0.2 m/s), so
#: thresholds cover the operating envelope rather than one trajectory.
CALIBRATION_LIMITS = MissionLimits(half_width=2.5, depth=(3.0, 8.0), yaw=np.pi / 4, speed=0.25, dwell=3.0)


def calibration_records(scenario: AuvScenario, progress: Callable[[int], None] | None = None) -> list[Record]:
    """Fault-free random missions over :data:`CALIBRATION_LIMITS` (their own mission streams and noise), no
    diagnoser in the loop."""
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    cols, units = _reference_columns()
    records = []
    for k in range(scenario.calibration_runs):
        draw = roby2_mission if scenario.mission == "roby2" else draw_mission
        ref = draw(scenario.seed, scenario.calibration_duration, CALIBRATION_LIMITS, name=f"calibration{k}")
        loop = ClosedLoop(sim, _controller(model, scenario.allocation), ref, accommodation=_allocation(scenario, model),
                          reference_columns=cols, reference_units=units)
        records.append(loop.run(scenario.calibration_duration, scenario.start_pose, seed=scenario.seed,
                                run_key=f"calibration{k}", scenario=f"calibration:{k}", progress=progress))
    return records


def calibration_description(scenario: AuvScenario) -> dict:
    """What an AUV calibration depends on: the scenario without what only a run has (name, faults, variant,
    duration, a given mission)."""
    return {"scenario": repr(replace(scenario, name="calibration", faults=(), variant="no_ftc", duration=1.0, plan=None))}


def calibration(scenario: AuvScenario, progress: Callable[[int], None] | None = None,
                cache: bool = True) -> tuple[AuvCalibration, bool]:
    """:func:`calibrate`, cached per configuration by :mod:`robofdi.calibration` (faults, variant and the mission
    flown play no part); returns (calibration, True if it came from the cache)."""
    return cached("auv", calibration_description(scenario), lambda: calibrate(scenario, progress), cache=cache)


def calibrate(scenario: AuvScenario, progress: Callable[[int], None] | None = None,
              records: list[Record] | None = None) -> AuvCalibration:
    """Identify the current characteristic on the calibration telemetry, then each diagnoser's thresholds
    (margin × peak |r| over the calibration runs, the start-up blanking skipped). ``progress(n)`` is told the
    ticks of the calibration runs and of their replays (one per diagnoser but the EKF bank)."""
    records = records if records is not None else calibration_records(scenario, progress)
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    channels = sim.sensor_channels
    p = len(sim.actuators)
    speed = np.vstack([r.signals["y_meas"][:, 13:13 + p] for r in records])
    current = np.vstack([r.signals["y_meas"][:, 13 + p:13 + 2 * p] for r in records])
    theta = identify_current_characteristic(speed, current, scenario.plant.control_dt, scenario.current_map_filter)
    arx = identify_depth_arx(*_arx_series(records, model, 5))
    skip = startup_samples(scenario.plant.control_dt, scenario.blanking)
    ekf_q = None
    runs = [diagnoser_inputs(r) for r in records]
    supply = identify_supply_resistance(VoltageResidual(model, channels, scenario.plant.control_dt,
                                                        thrust_limit=scenario.plant.thrust_limit), runs)
    if "ekf_bank" in scenario.diagnosers:
        ekf_q = calibrate_process_noise(runs, lambda q: _ekf_bank(scenario, model, channels, q), skip,
                                        scenario.ekf_margin)
    thresholds = {}
    for name, diagnoser in _diagnosers(scenario, model, channels, theta, arx, ekf_q, supply).items():
        if name == "ekf_bank":                     # the χ² 99 % bound of the windowed NIS, not a fitted peak
            thresholds[name] = np.full(len(diagnoser.components), diagnoser.bound)
            continue
        residuals = [diagnose_record(r, Diagnosis(diagnoser), progress=progress).residual for r in records]
        thresholds[name] = calibrate_thresholds(residuals, scenario.threshold_margin, skip)
    return AuvCalibration(theta, thresholds, skip, scenario.plant.control_dt, arx, ekf_q, supply)


def _arx_series(records: list[Record], model: AuvModel, decimation: int) -> tuple[np.ndarray, np.ndarray]:
    """Pressure depth [m] every ``decimation`` samples and the mean downward thruster force [N] over the interval
    ending there, concatenated over the records (the first samples of each run dropped)."""
    zs, Fs = [], []
    for r in records:
        y, u = r.signals["y_meas"], r.signals["u"]
        down = np.array([-vertical_force(model, y[k, 4:7], u[k]) for k in range(len(u))])
        n = (len(u) - 1) // decimation
        z = y[decimation::decimation, 2][:n]
        F = down[: n * decimation].reshape(n, decimation).mean(axis=1)
        zs.append(z[10:])
        Fs.append(F[10:])
    return np.concatenate(zs), np.concatenate(Fs)


def build_loop(scenario: AuvScenario, cal: AuvCalibration) -> ClosedLoop:
    """The scenario's closed loop: controller, allocation (health per ``scenario.variant``), diagnoses, faults."""
    if abs(cal.sample_time - scenario.plant.control_dt) > 1e-12:
        raise RobofdiError(f"build_loop: the calibration is for a sample time of {cal.sample_time} s, the scenario "
                           f"runs at {scenario.plant.control_dt} s")
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    diagnoses = {}
    for name, d in _diagnosers(scenario, model, sim.sensor_channels, cal.characteristic, cal.arx,
                               cal.ekf_process_noise, cal.supply_resistance).items():
        if name == "ekf_bank":
            decision = NisBankDecision(d.components, cal.thresholds[name], d.hypotheses, blanking=cal.blanking)
        else:
            decision = ThresholdDecision(d.components, cal.thresholds[name], d.signatures(), blanking=cal.blanking)
        diagnoses[name] = Diagnosis(d, decision)
    health = {"no_ftc": None, "oracle": ORACLE, "diagnosed": scenario.health_source}[scenario.variant]
    cols, units = _reference_columns()
    controller = _controller(model, scenario.allocation)
    if scenario.depth_redundancy:
        controller = DepthSwitchingControl(controller, _depth_vote(scenario, model, sim.sensor_channels, cal.arx))
    return ClosedLoop(sim, controller, scenario.reference(), scenario.faults, diagnoses,
                      accommodation=_allocation(scenario, model), health_source=health,
                      reference_columns=cols, reference_units=units)


def check_scenario(scenario: AuvScenario) -> None:
    """Raise before any calibration if a fault names an unknown target or kind for this vehicle."""
    check_faults(scenario.faults, scenario.simulator(), scenario.duration)


def tracking_rms(record: Record, since: float = 0.0) -> float:
    """RMS position tracking error [m] (3-D) for t ≥ ``since``."""
    keep = record.time >= since
    err = record.signals["reference"][keep, :3] - record.truth_state[keep, :3]
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1)))) if keep.any() else float("nan")


def current_map_regions(record: Record, faults, window: float = 1.0) -> dict:
    """Per thruster fault: the current map's region (:func:`~robofdi.observers.auv.current_map_region`) that holds
    most often over ``window`` s from the first sample isolating the fault's target (a persistence, as the
    digest's 0.5 s band persistence), with that isolation time [s]; region None when never isolated."""
    from collections import Counter

    from robofdi.observers.auv import current_map_region

    tr = record.diagnosers["current_map"]
    names = record.columns["signals/u"]
    p = len(names)
    out = {}
    for f in faults:
        if f.target not in names:
            continue
        i = names.index(f.target)
        hit = np.flatnonzero((tr.time >= f.onset) & np.array([f.target in str(s).split("+") for s in tr.isolated]))
        if not hit.size:
            out[f.name] = {"region": None, "time": None, "kind": f.kind}
            continue
        t0 = float(tr.time[hit[0]])
        span = (tr.time >= t0) & (tr.time < t0 + window)
        votes = Counter(current_map_region(r[i], r[p + i], tr.threshold[i], tr.threshold[p + i]) for r in tr.residual[span])
        votes = Counter({k: v for k, v in votes.items() if k != "nominal"}) or votes
        out[f.name] = {"region": votes.most_common(1)[0][0], "time": t0, "kind": f.kind}
    return out


def depth_switch_time(record: Record, diagnoser: str = "depth_vote") -> float | None:
    """When the depth vote disconnected the pressure sensor [s]: the first sample whose identified pressure error
    (pressure − accepted depth) is non-zero — before the switch the accepted depth is the pressure itself."""
    tr = record.diagnosers.get(diagnoser)
    if tr is None:
        return None
    col = tr.estimate_components.index("depth")
    hit = np.flatnonzero(np.abs(tr.estimate[:, col]) > 0)
    return float(tr.time[hit[0]]) if hit.size else None


def run_scenario(scenario: AuvScenario, cal: AuvCalibration, progress: Callable[[int], None] | None = None,
                 run_key: str = "run") -> Record:
    """One run → its record (:func:`robofdi.evaluate.summarize` gives its summary). The same seed and run_key give
    the same noise whatever the variant, so variants differ only by their accommodation."""
    return parts(scenario, cal, run_key).run(progress)


def parts(scenario: AuvScenario, cal: AuvCalibration, run_key: str = "run") -> Parts:
    """The scenario's run, built (:class:`~robofdi.protocols.Parts`): its closed loop (:func:`build_loop`), start
    pose, seed and record metadata."""
    plant = scenario.plant
    meta = {"mjcf": plant.mjcf, "variant": scenario.variant, "allocation": scenario.allocation,
            "current": list(plant.current), "mission": scenario.mission, "thrust_limit": plant.thrust_limit}
    return Parts(build_loop(scenario, cal), scenario.duration, scenario.start_pose, scenario.seed, run_key,
                 scenario.name, meta)


def with_variant(scenario: AuvScenario, variant: str) -> AuvScenario:
    return replace(scenario, variant=variant)


# ---------------------------------------------------------------------------------------------------- the system
#: The scenario of an AUV campaign's runs: random missions of 60 s (the campaign draws each run's mission, faults
#: and seed; :class:`AuvOptions` may change everything else).
CAMPAIGN_SCENARIO = AuvScenario(name="campaign-auv", mission="random", duration=60.0)
_DRAWN = ("name", "mission", "seed", "faults", "plan", "diagnosers")


@dataclass(frozen=True)
class AuvOptions:
    """The AUV system's configuration (a campaign's ``[system]`` table, :mod:`robofdi.systems.auv`, the 8-thruster
    ODIN-like vehicle): the runs' ``scenario`` (:class:`AuvScenario`, itself composed of the simulator's
    configuration and the belief's mismatch; default :data:`CAMPAIGN_SCENARIO`) and ``robot_seeds``. Any field of
    the scenario or its parts is named flat or nested (:mod:`robofdi.config`): duration [s] of each random
    mission (≤ 3600), calibration_runs × calibration_duration [s] of fault-free calibration missions, variant,
    allocation, health_source, current [m/s], threshold_margin, … The campaign draws the mission, faults and seed
    (and its ``diagnosers`` list names the diagnosers), so those are not options. robot_seeds: one calibration each
    (its fault-free calibration missions and noise)."""

    scenario: AuvScenario = part(AuvScenario, lambda: CAMPAIGN_SCENARIO)
    robot_seeds: tuple = (0,)

    def __post_init__(self):
        check_robot_seeds(self)
        sc = self.scenario
        check_not_set("system", sc, CAMPAIGN_SCENARIO, _DRAWN,
                      "the campaign draws each run's mission, "
                      "faults and seed, and its 'diagnosers' list names the diagnosers")
        check_fields("system", sc, [
            ("duration", is_positive(sc.duration, 3600), "a time in (0, 3600] s"),
            ("calibration_runs", is_int(sc.calibration_runs, 1), "an integer >= 1"),
            ("calibration_duration", is_positive(sc.calibration_duration, 3600), "a time in (0, 3600] s"),
        ])
        object.__setattr__(self, "scenario", replace(sc, duration=float(sc.duration),
                                                      calibration_duration=float(sc.calibration_duration),
                                                      threshold_margin=float(sc.threshold_margin)))

    def run_scenario(self, seed: int, diagnosers=None, plan=None, faults=()) -> AuvScenario:
        """The scenario of one run (every diagnoser unless named, plus the accommodation's health source)."""
        names = tuple(ALL_DIAGNOSERS if diagnosers is None else diagnosers)
        if self.scenario.variant == "diagnosed" and self.scenario.health_source not in names:
            names += (self.scenario.health_source,)          # the health the accommodation uses must be diagnosed
        return replace(self.scenario, seed=int(seed), faults=tuple(faults), diagnosers=names, plan=plan)


@register_system
class AuvSystem(RobotInstances):
    """The AUV: seeded random waypoint missions, thruster and navigation-sensor faults, the thruster diagnosers and
    the depth vote online, accommodation per ``variant`` (:mod:`robofdi.systems.auv`)."""

    name = "auv"
    options_type = AuvOptions

    def diagnosers(self, options):

        return ALL_DIAGNOSERS

    def targets(self, options):
        from robofdi.sims.auv import NAVIGATION_CHANNELS

        sc = options.run_scenario(0)
        sim = sc.simulator()
        ranges = {"m": 2 * sc.plant.floor_depth, "rad": np.pi, "m/s": 2.0, "rad/s": 1.0}   # sensor ranges of the vehicle
        thrusters = sim.actuators
        navigation = [(c, u) for c, u in zip(sim.sensor_channels, sim.units["y"]) if c in NAVIGATION_CHANNELS]
        return {"actuator": {t: TargetLimit(sc.plant.thrust_limit, "N") for t in thrusters},
                "sensor": {c: TargetLimit(ranges[u], u) for c, u in navigation},
                "component_thruster_blocking": {t: TargetLimit(1.0, "1") for t in thrusters},
                "component_thruster_flooding": {t: TargetLimit(1.0, "1") for t in thrusters}}

    def calibrate(self, options, key, diagnosers):
        # only the diagnosers asked for: each one's thresholds are its own, so a subset calibrates the same values
        # without the others' cost (the EKF bank's process-noise search is most of an AUV calibration)
        return calibration(options.run_scenario(int(key), diagnosers))

    def mission(self, options, key, generator):

        seed = int(generator.integers(2**31))
        duration = options.scenario.duration
        return CampaignMission(duration, draw_mission(seed, duration), {"mission_seed": seed})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        return parts(options.run_scenario(seed, diagnosers, mission.plan, faults), calibration, "campaign")
