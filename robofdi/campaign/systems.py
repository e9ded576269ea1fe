"""What a system gives a campaign: the :class:`CampaignSystem` protocol, the registry, and the shipped systems.

A system plugs in with a few lines: an options dataclass (the spec's ``[system]`` table, validated by its
constructor), its fault targets with their limits, its diagnosers, its calibration keys (one calibration per
(robot, seed)), and three functions — calibrate, draw a mission, run one mission with faults to a
:class:`~robofdi.record.Record`. Then ``register_system(MySystem())``, or name it in the spec as
``system = "package.module:attribute"`` (importable on every worker). Every function must be deterministic in
its arguments: a run's result may depend only on (options, calibration, robot seed, run seed, faults).
"""
from __future__ import annotations

import functools
from collections.abc import Hashable
from dataclasses import dataclass, field, fields
from importlib import import_module
from typing import Any, Protocol, runtime_checkable

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.faults import FAULT_KINDS
from robofdi.record import Record
from robofdi.seeding import rng

__all__ = ["TargetLimit", "Mission", "CampaignSystem", "SYSTEMS", "register_system", "get_system", "fault_limit",
           "ArmCampaign", "LinearCampaign", "ArmOptions", "LinearOptions", "AuvCampaign", "AuvOptions",
           "HydraulicCampaign", "HydraulicOptions", "HelicopterCampaign", "HelicopterOptions", "RobosuiteLiftCampaign",
           "RobosuiteLiftOptions", "CartpoleCampaign", "CartpoleOptions"]


@dataclass(frozen=True)
class TargetLimit:
    """A fault target's limit in its own unit: the motor torque limit of an actuator, the range of a sensor
    channel, the mass of a link. Magnitudes "as a fraction of the limit" multiply it."""

    limit: float
    unit: str


@dataclass(frozen=True)
class Mission:
    """One drawn mission: its run duration [s] and the system's own description of it (a trajectory, setpoints)."""

    duration: float
    plan: Any
    description: dict = field(default_factory=dict)


@runtime_checkable
class CampaignSystem(Protocol):
    """The protocol a system implements to run campaigns (see the module docstring)."""

    name: str
    options_type: type

    def diagnosers(self, options) -> tuple[str, ...]: ...

    def targets(self, options) -> dict[str, dict[str, TargetLimit]]:
        """{"actuator": {name: limit}, "sensor": {...}, "component_<kind>": {...}}."""

    def calibration_keys(self, options) -> list[Hashable]: ...

    def calibrate(self, options, key, diagnosers) -> tuple[Any, bool]:
        """(calibration, True if it came from the cache)."""

    def mission(self, options, key, generator: np.random.Generator) -> Mission: ...

    def run(self, options, calibration, key, mission: Mission, faults, seed: int, diagnosers) -> Record: ...


SYSTEMS: dict[str, CampaignSystem] = {}


def register_system(system: CampaignSystem) -> CampaignSystem:
    """Make ``system`` available to specs as ``system = "<system.name>"``."""
    if not isinstance(system, CampaignSystem):
        raise RobofdiError(f"register_system: {system!r} does not implement the CampaignSystem protocol")
    SYSTEMS[system.name] = system
    return system


def get_system(name: str) -> CampaignSystem:
    """A registered system by name, or ``"package.module:attribute"`` (a CampaignSystem instance)."""
    if not isinstance(name, str) or not name:
        raise RobofdiError(f"system: expected a non-empty name, got {name!r}")
    if name in SYSTEMS:
        return SYSTEMS[name]
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            system = getattr(import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise RobofdiError(f"system: cannot import {name!r} ({exc})") from None
        if isinstance(system, type):
            system = system()
        if not isinstance(system, CampaignSystem):
            raise RobofdiError(f"system: {name!r} does not implement the CampaignSystem protocol")
        return system
    raise RobofdiError(f"system: unknown system {name!r}; expected one of {', '.join(sorted(SYSTEMS))} "
                       "or 'package.module:attribute'")


def fault_limit(targets: dict[str, dict[str, TargetLimit]], kind: str, target: str) -> TargetLimit:
    """The limit of a fault of ``kind`` on ``target``: the target's limit in the kind's unit (per second for
    drifts; 1 for the dimensionless kinds — loss of effectiveness, scale, friction factor)."""
    family = kind.split("_", 1)[0]
    table = targets.get(family if family in ("actuator", "sensor") else kind, {})
    if target not in table:
        raise RobofdiError(f"target {target!r} is not a target of {kind}; expected one of {', '.join(table) or 'none'}")
    base = table[target]
    unit = FAULT_KINDS[kind].unit
    if unit == "1":
        return TargetLimit(1.0, "1")
    if unit == "target/s":
        return TargetLimit(base.limit, f"{base.unit}/s")
    return base


def _check_fields(where: str, obj, checks) -> None:
    for name, ok, expected in checks:
        if not ok:
            raise RobofdiError(f"{where}: field {name!r} must be {expected}, got {getattr(obj, name)!r}")


def _is_int(v, least=0) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= least


# ----------------------------------------------------------------------------------------------------- arm
@dataclass(frozen=True)
class ArmOptions:
    """The ``[system]`` table of an arm campaign.

    robot: MJCF file (default the shipped arm6.xml); joints / torque_motors: as :class:`ArmScenario`;
    robot_seeds: one robot instance per seed (ripple phases, nominal-model errors), one calibration each, runs
    cycle through them; speed: "fast" | "normal" | "slow" or a factor >= 1 (:data:`robofdi.control.SPEEDS`);
    segments: point-to-point segments per motion; tail: time after the motion's end [s]; injection: "online" |
    "offline"."""

    robot: str = "arm6.xml"
    joints: tuple | None = None
    torque_motors: bool = False
    robot_seeds: tuple = (0,)
    speed: Any = "normal"
    segments: int = 1
    tail: float = 1.0
    injection: str = "online"

    def __post_init__(self):
        from robofdi.control import SPEEDS

        object.__setattr__(self, "robot_seeds", tuple(self.robot_seeds))
        if self.joints is not None:
            object.__setattr__(self, "joints", tuple(self.joints))
        _check_fields("system", self, [
            ("robot", isinstance(self.robot, str) and self.robot, "an MJCF file name or path"),
            ("robot_seeds", self.robot_seeds and all(_is_int(s) for s in self.robot_seeds), "a non-empty list of integers >= 0"),
            ("speed", self.speed in SPEEDS or (isinstance(self.speed, (int, float)) and not isinstance(self.speed, bool)
                                                and self.speed >= 1), f"one of {sorted(SPEEDS)} or a number >= 1"),
            ("segments", _is_int(self.segments, 1), "an integer >= 1"),
            ("tail", isinstance(self.tail, (int, float)) and 0 <= self.tail < 60, "a time in [0, 60) s"),
            ("injection", self.injection in ("online", "offline"), "'online' or 'offline'"),
            ("torque_motors", isinstance(self.torque_motors, bool), "true or false"),
        ])


@functools.lru_cache(maxsize=8)
def _arm(robot: str, joints, torque_motors: bool):
    """(simulator, catalogue model, motion limits) of a robot, once per process (the catalogue model plans motions)."""
    from robofdi.control import MotionLimits
    from robofdi.sims import ArmSimulator

    sim = ArmSimulator(robot, joints=joints, torque_motors=torque_motors)
    model = sim.nominal_model()
    return sim, model, MotionLimits.from_ranges(sim.joint_range[:, 0], sim.joint_range[:, 1], model.torque_limit)


class ArmCampaign:
    """Any MJCF arm: seeded point-to-point motions from random start poses, faults injected online, the book's
    schemes and the momentum observer in the loop (:mod:`robofdi.scenarios.arm`)."""

    name = "arm"
    options_type = ArmOptions

    def _base(self, options: ArmOptions):
        try:
            return _arm(options.robot, options.joints, options.torque_motors)
        except RobofdiError as exc:
            raise RobofdiError(f"system.robot: {exc}") from None

    def diagnosers(self, options):
        from robofdi.observers.arm_schemes import SCHEMES

        return SCHEMES

    def targets(self, options):
        sim, model, _ = self._base(options)
        n = sim.n
        width = sim.joint_range[:, 1] - sim.joint_range[:, 0]
        sensors = {ch: TargetLimit(float(width[i % n]), "rad" if i < n else "rad/s")
                   for i, ch in enumerate(sim.sensor_channels)}          # velocity channels: one range per second
        masses = {b: TargetLimit(float(sim.model.body_mass[i]), "kg") for b, (i, _) in sim._mass_points.items()}
        masses["payload"] = TargetLimit(max(v.limit for k, v in masses.items() if k != "payload"), "kg")
        return {"actuator": {a: TargetLimit(float(model.torque_limit[i]), "N·m") for i, a in enumerate(sim.actuators)},
                "sensor": sensors,
                "component_friction": {j: TargetLimit(1.0, "1") for j in sim.component_kinds["component_friction"]},
                "component_mass": {b: masses[b] for b in sim.component_kinds["component_mass"]}}

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def _scenario(self, options, key, diagnosers, motion=None, duration=None, faults=()):
        from robofdi.scenarios.arm import ArmScenario

        sim, model, limits = self._base(options)
        if motion is None:
            motion = self.mission(options, key, rng(key, "campaign", "calibration-placeholder")).plan
        return ArmScenario("campaign-arm", motion=motion, duration=duration, faults=tuple(faults),
                           injection=options.injection, mjcf=options.robot, joints=tuple(sim.joint_names),
                           torque_motors=options.torque_motors, seed=int(key), schemes=tuple(diagnosers))

    def calibrate(self, options, key, diagnosers):
        from robofdi.scenarios.arm import calibration

        return calibration(self._scenario(options, key, diagnosers))

    def mission(self, options, key, generator):
        from robofdi.control import random_point_to_point

        _, model, limits = self._base(options)
        motion = random_point_to_point(model, limits, generator, options.segments, speed=options.speed)
        start = np.asarray(motion(0.0)[0], dtype=float)
        return Mission(float(motion.end) + float(options.tail), motion,
                       {"start_pose": [round(float(v), 6) for v in start], "motion_end": float(motion.end)})

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        from robofdi.scenarios.arm import build_loop

        sc = self._scenario(options, key, diagnosers, mission.plan, mission.duration, faults)
        return build_loop(sc, calibration).run(sc.run_duration, sc.start_pose, seed=seed, run_key="campaign",
                                               scenario=sc.name, meta={"robot_seed": int(key)})


# -------------------------------------------------------------------------------------------------- linear
def _linear_settings():
    from robofdi.scenarios.linear import LinearSettings

    return LinearSettings


@dataclass(frozen=True)
class LinearOptions(_linear_settings()):
    """The ``[system]`` table of a linear-plant campaign (the wheel-speed plant of :mod:`robofdi.scenarios.linear`):
    robot_seeds: one belief (seeded parameter errors) per seed, one calibration each; mismatch, margin,
    calibration_runs, duration [s], blanking [s]: those of :class:`robofdi.scenarios.linear.LinearSettings`."""

    robot_seeds: tuple = (0,)

    def __post_init__(self):
        object.__setattr__(self, "robot_seeds", tuple(self.robot_seeds))
        _check_fields("system", self, [("robot_seeds", self.robot_seeds and all(_is_int(s) for s in self.robot_seeds),
                                        "a non-empty list of integers >= 0")])
        try:
            super().__post_init__()
        except RobofdiError as exc:
            raise RobofdiError(f"system: {exc}") from None

    @property
    def settings(self):
        """The scenario's settings alone (what a calibration depends on; the robot seed is its key)."""
        base = _linear_settings()
        return base(**{f.name: getattr(self, f.name) for f in fields(base)})


class LinearCampaign:
    """The differential-drive wheel-speed plant with its observer residual (:mod:`robofdi.scenarios.linear`)."""

    name = "linear"
    options_type = LinearOptions

    def diagnosers(self, options):
        from robofdi.scenarios.linear import DIAGNOSER

        return (DIAGNOSER,)

    def targets(self, options):
        from robofdi.scenarios.linear import SENSOR_RANGE, TORQUE_LIMIT

        return {"actuator": {a: TargetLimit(TORQUE_LIMIT, "N*m") for a in ("tau_L", "tau_R")},
                "sensor": {s: TargetLimit(v, "rad/s") for s, v in SENSOR_RANGE.items()}}

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def calibrate(self, options, key, diagnosers):
        from robofdi.scenarios.linear import linear_calibration

        return linear_calibration(int(key), options.settings)

    def mission(self, options, key, generator):
        from robofdi.scenarios.linear import draw_mission

        mission = draw_mission(generator)
        return Mission(float(options.duration), mission, {k: list(v) for k, v in mission.__dict__.items()})

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        from robofdi.scenarios.linear import run_linear

        return run_linear(mission.plan, faults, calibration, int(key), seed, options.settings, run_key="campaign")


register_system(ArmCampaign())
register_system(LinearCampaign())


# ------------------------------------------------------------------------------------ calibration cache (pickled)
def _cached_calibration(system: str, description: dict, compute) -> tuple[Any, bool]:
    """``compute()`` once per ``description`` (system options, robot seed) and robofdi's code
    (:func:`~robofdi.scenarios.arm.code_fingerprint`), pickled in :func:`robofdi.scenarios.arm.cache_dir`;
    returns (calibration, True if it came from the cache)."""
    import hashlib
    import json
    import pickle

    from robofdi.scenarios.arm import cache_dir, code_fingerprint

    key = hashlib.sha256(json.dumps({**description, "system": system, "code": code_fingerprint()}, sort_keys=True,
                                    default=repr).encode()).hexdigest()[:20]
    path = cache_dir() / f"{system}-calibration-{key}.pkl"
    if path.is_file():
        try:
            with path.open("rb") as fh:
                return pickle.load(fh), True
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError):
            pass                                    # a torn or stale file is recomputed
    cal = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.name}.{np.random.default_rng().integers(1 << 62)}.tmp")
        with tmp.open("wb") as fh:
            pickle.dump(cal, fh)
        tmp.replace(path)
    except OSError:
        pass  # a read-only cache only costs the next campaign its calibration
    return cal, False


def _robot_seeds(options) -> None:
    object.__setattr__(options, "robot_seeds", tuple(options.robot_seeds))
    _check_fields("system", options, [("robot_seeds", options.robot_seeds and all(_is_int(s) for s in options.robot_seeds),
                                       "a non-empty list of integers >= 0")])


def _positive(v, high=float("inf")) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v <= high


# ----------------------------------------------------------------------------------------------------- AUV
@dataclass(frozen=True)
class AuvOptions:
    """The ``[system]`` table of an AUV campaign (:mod:`robofdi.scenarios.auv`, the 8-thruster ODIN-like vehicle).

    robot_seeds: one calibration each (its fault-free calibration missions and noise; the vehicle and its
    nominal-model errors are those of :class:`~robofdi.models.auv.AuvModelMismatch`); duration [s]: each random
    mission; calibration_runs × calibration_duration [s]: the fault-free calibration missions; variant /
    allocation / health_source / current [m/s] / threshold_margin: those of :class:`~robofdi.scenarios.auv.AuvScenario`."""

    robot_seeds: tuple = (0,)
    duration: float = 60.0
    calibration_runs: int = 3
    calibration_duration: float = 240.0
    variant: str = "diagnosed"
    allocation: str = "constrained"
    health_source: str = "voltage_residual"
    current: tuple = (0.10, 0.05, 0.0)
    threshold_margin: float = 2.0

    def __post_init__(self):
        _robot_seeds(self)
        object.__setattr__(self, "current", tuple(self.current))
        _check_fields("system", self, [
            ("duration", _positive(self.duration, 3600), "a time in (0, 3600] s"),
            ("calibration_runs", _is_int(self.calibration_runs, 1), "an integer >= 1"),
            ("calibration_duration", _positive(self.calibration_duration, 3600), "a time in (0, 3600] s"),
        ])
        try:
            self.scenario(0)                        # the scenario validates the rest (variant, allocation, …)
        except RobofdiError as exc:
            raise RobofdiError(f"system: {exc}") from None

    def scenario(self, seed: int, diagnosers=None, plan=None, faults=()):
        """The :class:`~robofdi.scenarios.auv.AuvScenario` of these options (every diagnoser unless named)."""
        from robofdi.scenarios.auv import ALL_DIAGNOSERS

        names = tuple(ALL_DIAGNOSERS if diagnosers is None else diagnosers)
        if self.variant == "diagnosed" and self.health_source not in names:
            names += (self.health_source,)          # the health the accommodation uses must be diagnosed
        return _PlannedAuvScenario(name="campaign-auv", mission="random", duration=float(self.duration), seed=int(seed),
                                   faults=tuple(faults), current=self.current, diagnosers=names,
                                   allocation=self.allocation, variant=self.variant, health_source=self.health_source,
                                   calibration_runs=self.calibration_runs,
                                   calibration_duration=float(self.calibration_duration),
                                   threshold_margin=float(self.threshold_margin), plan=plan)


def _planned_auv_scenario():
    from robofdi.scenarios.auv import AuvScenario

    @dataclass(frozen=True)
    class PlannedAuvScenario(AuvScenario):
        """An AuvScenario flying a given mission (``plan``) instead of the one its seed would draw."""

        plan: Any = None

        def reference(self):
            return super().reference() if self.plan is None else self.plan

    return PlannedAuvScenario


_PlannedAuvScenario = _planned_auv_scenario()


class AuvCampaign:
    """The AUV: seeded random waypoint missions, thruster and navigation-sensor faults, the thruster diagnosers and
    the depth vote online, accommodation per ``variant`` (:mod:`robofdi.scenarios.auv`)."""

    name = "auv"
    options_type = AuvOptions

    def diagnosers(self, options):
        from robofdi.scenarios.auv import ALL_DIAGNOSERS

        return ALL_DIAGNOSERS

    def targets(self, options):
        from robofdi.sims.auv import NAVIGATION_CHANNELS

        sc = options.scenario(0)
        sim = sc.simulator()
        ranges = {"m": 2 * sc.floor_depth, "rad": np.pi, "m/s": 2.0, "rad/s": 1.0}   # sensor ranges of the vehicle
        thrusters = sim.actuators
        navigation = [(c, u) for c, u in zip(sim.sensor_channels, sim.units["y"]) if c in NAVIGATION_CHANNELS]
        return {"actuator": {t: TargetLimit(sc.thrust_limit, "N") for t in thrusters},
                "sensor": {c: TargetLimit(ranges[u], u) for c, u in navigation},
                "component_thruster_blocking": {t: TargetLimit(1.0, "1") for t in thrusters},
                "component_thruster_flooding": {t: TargetLimit(1.0, "1") for t in thrusters}}

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def calibrate(self, options, key, diagnosers):
        from robofdi.scenarios.auv import calibrate

        sc = options.scenario(int(key))
        description = {k: getattr(sc, k) for k in ("mjcf", "seed", "current", "control_dt", "sensors", "mismatch",
                                                   "thrust_limit", "calibration_runs", "calibration_duration",
                                                   "threshold_margin", "blanking", "start_depth", "current_map_filter",
                                                   "floor_depth", "allocation", "diagnosers")}
        return _cached_calibration("auv", description, lambda: calibrate(sc))

    def mission(self, options, key, generator):
        from robofdi.scenarios.auv import draw_mission

        seed = int(generator.integers(2**31))
        return Mission(float(options.duration), draw_mission(seed, float(options.duration)), {"mission_seed": seed})

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        from robofdi.scenarios.auv import run_scenario

        sc = options.scenario(seed, diagnosers, mission.plan, faults)
        return run_scenario(sc, calibration, run_key="campaign")[0]


# ------------------------------------------------------------------------------------------------ hydraulic
@dataclass(frozen=True)
class HydraulicOptions:
    """The ``[system]`` table of a hydraulic-rig campaign (:mod:`robofdi.scenarios.hydraulic`).

    robot_seeds: one calibration each (fault-free runs on the random operating profiles of seeds
    1000·(1 + robot seed) + i); duration [s] of every run; calibration_runs (>= 2: half train the NNAR and fit the
    better model, all set thresholds); margin: threshold margin >= 1."""

    robot_seeds: tuple = (0,)
    duration: float = 8.0
    calibration_runs: int = 8
    margin: float = 1.3

    def __post_init__(self):
        _robot_seeds(self)
        _check_fields("system", self, [
            ("duration", _positive(self.duration, 600) and self.duration >= 3, "a time in [3, 600] s"),
            ("calibration_runs", _is_int(self.calibration_runs, 2), "an integer >= 2"),
            ("margin", _positive(self.margin) and self.margin >= 1, "a number >= 1"),
        ])

    def scenario(self, **kw):
        from robofdi.scenarios.hydraulic import HydraulicScenario

        return HydraulicScenario(name="campaign-hydraulic", duration=float(self.duration), margin=float(self.margin), **kw)


class HydraulicCampaign:
    """The hydraulic wheel-actuator rig: random operating profiles (target speed, ramp, load throttle), valve,
    leak and tachometer faults, the nlar residuals and their baselines online (:mod:`robofdi.scenarios.hydraulic`)."""

    name = "hydraulic"
    options_type = HydraulicOptions

    def diagnosers(self, options):
        from robofdi.scenarios.hydraulic import DIAGNOSERS

        return DIAGNOSERS

    def targets(self, options):
        from robofdi.scenarios.hydraulic import FAULT_TARGETS

        limits = {"shaft_speed": (2.0, "rad/s"), "load_pressure": (2e7, "Pa"), "pump_pressure": (2e7, "Pa"),
                  "supply_pressure": (2e7, "Pa")}                     # sensor ranges (tachometer, 200 bar gauges)
        comps = {kind: {t: TargetLimit(hi, "mm^2" if kind == "component_leak" else "1") for t, (_, hi) in tg.items()}
                 for kind, tg in FAULT_TARGETS["component"].items()}
        return {"actuator": {"servovalve": TargetLimit(1.0, "1 (valve stroke)")},
                "sensor": {c: TargetLimit(*v) for c, v in limits.items()}, **comps}

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def calibrate(self, options, key, diagnosers):
        from robofdi.scenarios.hydraulic import calibrate

        base = options.scenario()
        seed = 1000 * (1 + int(key))
        return _cached_calibration("hydraulic", {"base": repr(base), "runs": options.calibration_runs, "seed": seed},
                                   lambda: calibrate(base, options.calibration_runs, seed))

    def mission(self, options, key, generator):
        from robofdi.scenarios.hydraulic import operating_profile

        profile = operating_profile(int(generator.integers(2**31)))
        return Mission(float(options.duration), profile, dict(profile))

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        from robofdi.scenarios.hydraulic import run_scenario

        sc = options.scenario(faults=tuple(faults), seed=int(seed), diagnosers=tuple(diagnosers), **mission.plan)
        return run_scenario(sc, calibration, run_key="campaign")


# ---------------------------------------------------------------------------------------------- helicopter
@dataclass(frozen=True)
class HelicopterOptions:
    """The ``[system]`` table of a helicopter campaign (Jiang & Chowdhury 2005 Sec. V, :mod:`robofdi.scenarios.helicopter`):
    robot_seeds: one belief (seeded relative parameter errors of size ``mismatch``) and calibration each;
    duration [s]; noise: the paper's process and sensor noise; accommodation: u = (I − R̂)⁻¹u fed by the diagnosis;
    calibration_runs: fault-free runs setting the thresholds."""

    robot_seeds: tuple = (0,)
    duration: float = 10.0
    mismatch: float = 0.05
    noise: bool = True
    accommodation: bool = True
    calibration_runs: int = 3

    def __post_init__(self):
        _robot_seeds(self)
        _check_fields("system", self, [
            ("duration", _positive(self.duration, 600), "a time in (0, 600] s"),
            ("mismatch", isinstance(self.mismatch, (int, float)) and 0 <= self.mismatch < 0.5, "a fraction in [0, 0.5)"),
            ("noise", isinstance(self.noise, bool), "true or false"),
            ("accommodation", isinstance(self.accommodation, bool), "true or false"),
            ("calibration_runs", _is_int(self.calibration_runs, 1), "an integer >= 1"),
        ])

    def scenario(self, key: int, faults=()):
        """The scenario of belief ``key`` (its seed seeds the belief's errors; run noise comes from the run seed)."""
        from robofdi.scenarios.helicopter import HelicopterScenario

        return HelicopterScenario(faults=tuple(faults), seed=int(key), duration=float(self.duration), noise=self.noise,
                                  accommodation=self.accommodation, mismatch=float(self.mismatch),
                                  calibration_runs=self.calibration_runs)


class HelicopterCampaign:
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

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def calibrate(self, options, key, diagnosers):
        from robofdi.scenarios.helicopter import calibrate

        sc = options.scenario(key)
        return _cached_calibration("helicopter", {"scenario": repr(sc)}, lambda: calibrate(sc))

    def mission(self, options, key, generator):
        return Mission(float(options.duration), None, {"excitation": "sin(pi t), cos(0.6 pi t)"})

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        from robofdi.scenarios.helicopter import build_loop

        sc = options.scenario(key, faults)
        return build_loop(sc, calibration).run(sc.duration, seed=seed, run_key="campaign", scenario="campaign-helicopter",
                                               meta={"noise": sc.noise, "robot_seed": int(key)})


register_system(AuvCampaign())
register_system(HydraulicCampaign())
register_system(HelicopterCampaign())


# ------------------------------------------------------------------------------------------------ adapters
def _adapter(module: str, extra: str):
    """An adapter module, or one clear error naming the optional extra it needs."""
    try:
        return import_module(module)
    except ImportError as exc:
        raise RobofdiError(f"system: {module} needs the optional extra: pip install 'robofdi[{extra}]' ({exc})") from None


@dataclass(frozen=True)
class RobosuiteLiftOptions:
    """The ``[system]`` table of a robosuite Lift campaign (:mod:`robofdi.adapters.robosuite_diagnosis`: the Panda
    with OSC_POSE and the scripted grasp). robot_seeds: one calibration each, on ``calibration_episodes``
    fault-free episodes of seeds 1000·(1 + robot seed) + i; episode_steps: policy steps (20 Hz) per episode;
    accommodation: effectiveness compensation fed by ``health_source``."""

    robot_seeds: tuple = (0,)
    calibration_episodes: int = 30
    episode_steps: int = 140
    accommodation: bool = False
    health_source: str = "momentum"

    def __post_init__(self):
        _robot_seeds(self)
        _check_fields("system", self, [
            ("calibration_episodes", _is_int(self.calibration_episodes, 2), "an integer >= 2"),
            ("episode_steps", _is_int(self.episode_steps, 20) and self.episode_steps <= 2000, "an integer in [20, 2000]"),
            ("accommodation", isinstance(self.accommodation, bool), "true or false"),
            ("health_source", self.health_source in ("momentum", "momentum_friction"), "'momentum' or 'momentum_friction'"),
        ])

    def calibration_seeds(self, key: int) -> tuple:
        return tuple(1000 * (1 + int(key)) + i for i in range(self.calibration_episodes))


@functools.lru_cache(maxsize=1)
def _lift_env():
    """One robosuite Lift per process, reused by every run (robosuite.make takes seconds)."""
    return _adapter("robofdi.adapters.robosuite_diagnosis", "robosuite").make_lift()


class RobosuiteLiftCampaign:
    """robosuite's Lift with the Panda (OSC_POSE, scripted grasp; the script's variations are the mission), arm
    faults through :class:`~robofdi.adapters.robosuite.FaultyRobosuiteEnv`, the momentum diagnosers online."""

    name = "robosuite-lift"
    options_type = RobosuiteLiftOptions

    def diagnosers(self, options):
        return _adapter("robofdi.adapters.robosuite_diagnosis", "robosuite").DIAGNOSERS

    def targets(self, options):
        from robofdi.adapters.robosuite import RobotArm

        arm = RobotArm(_lift_env())
        width = arm.joint_range[:, 1] - arm.joint_range[:, 0]
        sensors = {ch: TargetLimit(float(width[i % arm.n]), "rad" if i < arm.n else "rad/s")
                   for i, ch in enumerate(arm.sensor_channels)}          # velocity channels: one range per second
        return {"actuator": {j: TargetLimit(float(np.abs(arm.torque_range[i]).max()), "N·m") for i, j in enumerate(arm.joints)},
                "sensor": sensors,
                "component_friction": {j: TargetLimit(1.0, "1") for j in arm.joints},
                "component_mass": {"payload": TargetLimit(3.0, "kg")}}      # the Panda's rated payload

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def calibrate(self, options, key, diagnosers):
        rd = _adapter("robofdi.adapters.robosuite_diagnosis", "robosuite")
        return rd.lift_calibration(options.calibration_seeds(key), steps=options.episode_steps)

    def mission(self, options, key, generator):
        script = int(generator.integers(2**31))
        return Mission(options.episode_steps / 20.0, script, {"script_seed": script})

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        rd = _adapter("robofdi.adapters.robosuite_diagnosis", "robosuite")
        return rd.run_lift(calibration, faults, seed, accommodation=options.accommodation,
                           health_source=options.health_source, diagnosers=tuple(diagnosers), env=_lift_env(),
                           steps=options.episode_steps, scenario="campaign-robosuite-lift", policy_seed=mission.plan,
                           meta={"robot_seed": int(key)})[1]


@dataclass(frozen=True)
class CartpoleOptions:
    """The ``[system]`` table of a dm_control cartpole campaign (:mod:`robofdi.adapters.dm_control_diagnosis`: the
    momentum residual on both joints of the suite's cart-pole). robot_seeds: one belief (mass ±``mismatch``, damping
    ±4·``mismatch``) and calibration each, on ``calibration_episodes`` fault-free episodes; steps: 10 ms control
    steps per episode; blanking: start-up samples without alarms."""

    robot_seeds: tuple = (0,)
    calibration_episodes: int = 30
    steps: int = 300
    mismatch: float = 0.05
    blanking: int = 5

    def __post_init__(self):
        _robot_seeds(self)
        _check_fields("system", self, [
            ("calibration_episodes", _is_int(self.calibration_episodes, 2), "an integer >= 2"),
            ("steps", _is_int(self.steps, 20) and self.steps <= 100_000, "an integer in [20, 100000]"),
            ("mismatch", isinstance(self.mismatch, (int, float)) and 0 <= self.mismatch < 0.125, "a fraction in [0, 0.125)"),
            ("blanking", _is_int(self.blanking, 0) and self.blanking < self.steps, "an integer in [0, steps)"),
        ])


class CartpoleCampaign:
    """dm_control's cartpole (swingup) under a seeded excitation policy (the mission), faults through
    :class:`~robofdi.adapters.dm_control.FaultyEnvironment`, the momentum residual with calibrated thresholds."""

    name = "dm_control-cartpole"
    options_type = CartpoleOptions

    def diagnosers(self, options):
        return ("momentum",)

    def _diagnoser(self, options, key):
        from robofdi.models.manipulator import ModelMismatch

        dc = _adapter("robofdi.adapters.dm_control_diagnosis", "dm_control")
        belief = ModelMismatch(mass=options.mismatch, damping=4 * options.mismatch, seed=int(key))
        return dc, dc.CartpoleDiagnoser(dc.suite_model("cartpole", belief), 0.01)

    def targets(self, options):
        dc, _ = self._diagnoser(options, 0)
        env = dc.cartpole_env()
        ranges = {"position[0]": 3.6, "position[1]": 2.0, "position[2]": 2.0, "velocity[0]": 5.0, "velocity[1]": 20.0}
        return {"actuator": {a: TargetLimit(1.0, "1 (action)") for a in env.actuators},
                "sensor": {c: TargetLimit(ranges[c], "observation unit") for c in env.sensors if c in ranges}}

    def calibration_keys(self, options):
        return list(options.robot_seeds)

    def calibrate(self, options, key, diagnosers):
        dc, diagnoser = self._diagnoser(options, key)
        seeds = range(1000 * (1 + int(key)), 1000 * (1 + int(key)) + options.calibration_episodes)
        return _cached_calibration("dm_control-cartpole", {"options": repr(options), "key": int(key)},
                                   lambda: dc.calibrate_cartpole(diagnoser, seeds, options.steps, options.blanking))

    def mission(self, options, key, generator):
        policy = int(generator.integers(2**31))
        return Mission(options.steps * 0.01, policy, {"policy_seed": policy})

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        dc, diagnoser = self._diagnoser(options, key)
        return dc.cartpole_record(faults, seed, diagnoser, calibration, options.steps, policy_seed=mission.plan,
                                  scenario="campaign-dm_control-cartpole")


register_system(RobosuiteLiftCampaign())
register_system(CartpoleCampaign())
