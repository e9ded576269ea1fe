"""The campaign spec: a TOML file read into a validated dataclass tree, every error naming its field.

    seed = 0                       # campaign seed: run i's seed is robofdi.seeding.stream(seed, "campaign", "run", i)
    fault_free_runs = 100
    faulty_runs = 100              # one fault each, drawn from [[faults]] (weighted)
    diagnosers = ["simple", "momentum"]      # default: every diagnoser of the system (but its opt-in ones)
    records = false                # also save every run's record (records/run-<index>.h5)
    detection_level = 0.9          # detection probability that defines the minimum detectable fault
    # (a system without options can be given at the top instead: system = "linear")

    [system]                       # the system and its options (see its options dataclass)
    name = "arm"                   # a registered system, or "package.module:attribute" (imported: trusted specs only)
    robot = "arm6.xml"

    [[faults]]
    kind = "actuator_additive"
    targets = ["joint*"]           # names or shell patterns; default every target of the kind
    magnitude_fraction = [0.02, 0.4]     # of the target's limit (or: magnitude = [lo, hi] in the kind's unit)
    magnitude_draw = "uniform"     # or "log_uniform": sizes spread evenly over decades (needs low > 0)
    random_sign = true             # default true for additive, bias and drift kinds
    profiles = [{type = "step"}, {type = "ramp", duration = 0.5}]   # one drawn per fault; default step
    onset_fraction = [0.2, 0.6]    # onset drawn in this part of the run
    duration = [0.5, 1.5]          # optional: the fault ends after this long [s]; default: stays
    params = {}                    # kind parameters (hard_over: limit; sensor_delay: delay; …)
    weight = 1.0                   # relative probability of this entry

Kinds without a size (:data:`~robofdi.faults.MAGNITUDE_FREE`: lock in place, float, hard-over, freeze, dropout,
delay) need neither ``magnitude`` nor ``magnitude_fraction`` (``magnitude = [0.0, 0.0]`` is accepted, the same
entry), and campaign.json reports no minimum detectable fault for them.

``actuator_hard_over`` without ``params.limit``: the limit is drawn per run from the drawn target's own limit (the
robot's motor torque limit on an arm), ``± limit_fraction`` × that limit, the sign drawn (``limit_fraction`` a
range in (0, 1], default [1.0, 1.0]: the motor saturates; ``random_sign = false`` keeps +). With ``params.limit``
the one absolute value of the entry is used, as before.

Scale kinds (``actuator_scale``, ``sensor_scale``: gain 1 + m) take signed ranges: ``magnitude = [-0.5, 0.5]``
draws gains from 0.5 to 1.5 (m > −1: the gain stays positive), and ``random_sign = true`` mirrors a range
[0.1, 0.5] into gains 0.5–0.9 and 1.1–1.5.
"""
from __future__ import annotations

import fnmatch
import hashlib
import json
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib

from robofdi.config import compose
from robofdi.protocols import System
from robofdi.seeding import check_seed
from robofdi.systems import fault_limit, get_system
from robofdi.errors import RobofdiError
from robofdi.faults import FAULT_KINDS, MAGNITUDE_FREE, Fault, check_size
from robofdi.faults.profiles import profile_from_dict

__all__ = ["CampaignSpec", "FaultDistribution", "load_spec", "parse_spec", "SIGNED_KINDS", "SCALE_KINDS", "shipped_specs"]

#: The most runs a campaign may have (its results table is built in memory).
MAX_RUNS = 1_000_000
#: How a fault entry draws its size inside its range.
MAGNITUDE_DRAWS = ("uniform", "log_uniform")
#: Kinds whose magnitude has a sign that matters and a symmetric range (random_sign defaults to true).
SIGNED_KINDS = ("actuator_additive", "actuator_drift", "sensor_bias", "sensor_drift", "sensor_outliers")
#: Gain kinds (gain 1 + m): signed ranges with low > −1 (a gain below 1 and above 1), random_sign allowed (default
#: false).
SCALE_KINDS = ("actuator_scale", "sensor_scale")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _range(where: str, value, low=None, high=None) -> tuple[float, float]:
    if not (isinstance(value, (list, tuple)) and len(value) == 2 and all(_number(v) for v in value)):
        raise RobofdiError(f"{where}: expected [low, high] (two finite numbers), got {value!r}")
    lo, hi = float(value[0]), float(value[1])
    if lo > hi:
        raise RobofdiError(f"{where}: empty range [{lo:g}, {hi:g}] (low > high)")
    if (low is not None and lo < low) or (high is not None and hi > high):
        raise RobofdiError(f"{where}: [{lo:g}, {hi:g}] is outside [{low:g}, {high:g}]")
    return lo, hi


def _known_keys(where: str, table: dict, cls) -> None:
    if not isinstance(table, dict):
        raise RobofdiError(f"{where}: expected a table, got {table!r}")
    names = [f.name for f in fields(cls) if not f.name.startswith("_")]
    unknown = sorted(set(table) - set(names))
    if unknown:
        raise RobofdiError(f"{where}: unknown field {unknown[0]!r}; expected one of {', '.join(names)}")


@dataclass(frozen=True)
class FaultDistribution:
    """One ``[[faults]]`` entry (see the module docstring); ``targets`` resolved to names, ``limits`` per target."""

    kind: str
    targets: tuple = ("*",)
    magnitude: tuple | None = None
    magnitude_fraction: tuple | None = None
    magnitude_draw: str = "uniform"
    random_sign: bool | None = None
    profiles: tuple = ({"type": "step"},)
    onset_fraction: tuple = (0.2, 0.6)
    duration: tuple | None = None
    params: dict = field(default_factory=dict)
    weight: float = 1.0
    limit_fraction: tuple | None = None     # actuator_hard_over without params.limit: ± this × the target's limit
    limits: dict = field(default_factory=dict, compare=False)       # target -> (limit, unit), filled by resolve()

    @property
    def sized(self) -> bool:
        """Whether the entry's faults have a size (False for :data:`~robofdi.faults.MAGNITUDE_FREE` kinds)."""
        return self.kind not in MAGNITUDE_FREE

    @classmethod
    def resolve(cls, where: str, table: dict, system: System, options) -> FaultDistribution:
        _known_keys(where, table, cls)
        if "limits" in table:
            raise RobofdiError(f"{where}: unknown field 'limits'; the limits come from the system")
        kind = table.get("kind")
        if kind not in FAULT_KINDS:
            raise RobofdiError(f"{where}.kind: unknown fault kind {kind!r}; expected one of {', '.join(FAULT_KINDS)}")
        all_targets = system.targets(options)
        family = kind.split("_", 1)[0]
        pool = list(all_targets.get(family if family in ("actuator", "sensor") else kind, {}))
        if not pool:
            raise RobofdiError(f"{where}.kind: system {system.name!r} has no targets for {kind}")
        patterns = table.get("targets", ["*"])
        if isinstance(patterns, str):
            patterns = [patterns]
        if not isinstance(patterns, list) or not patterns or not all(isinstance(p, str) for p in patterns):
            raise RobofdiError(f"{where}.targets: expected a non-empty list of target names or patterns, got {patterns!r}")
        targets = []
        for p in patterns:
            hit = fnmatch.filter(pool, p)
            if not hit:
                raise RobofdiError(f"{where}.targets: unknown target {p!r} for {kind}; expected one of {', '.join(pool)}")
            targets += [t for t in hit if t not in targets]
        limits = {t: fault_limit(all_targets, kind, t) for t in targets}
        params = table.get("params", {})
        free_limit = kind == "actuator_hard_over" and isinstance(params, dict) and "limit" not in params
        if "limit_fraction" in table and not free_limit:
            raise RobofdiError(f"{where}.limit_fraction: only for actuator_hard_over without params.limit (the limit "
                               "drawn per target from its own limit), got it for "
                               f"{kind if kind != 'actuator_hard_over' else 'an entry with params.limit'}")
        limit_fraction = None
        if free_limit:
            limit_fraction = _range(f"{where}.limit_fraction", table.get("limit_fraction", [1.0, 1.0]), 0.0, 1.0)
            if limit_fraction[0] <= 0:
                raise RobofdiError(f"{where}.limit_fraction: expected fractions in (0, 1] of the target's limit, got "
                                   f"{list(limit_fraction)}")
        sign_kinds = SIGNED_KINDS + SCALE_KINDS + (("actuator_hard_over",) if free_limit else ())
        signed = table.get("random_sign", kind in SIGNED_KINDS or free_limit)
        if not isinstance(signed, bool):
            raise RobofdiError(f"{where}.random_sign: expected true or false, got {signed!r}")
        if signed and kind not in sign_kinds:
            raise RobofdiError(f"{where}.random_sign: {kind} has no sign to draw; expected false "
                               f"(true only for {', '.join(SIGNED_KINDS + SCALE_KINDS)} and a hard-over drawn from "
                               "the target's limit)")
        given = [k for k in ("magnitude", "magnitude_fraction") if k in table]
        if kind in MAGNITUDE_FREE and not given:
            given, table = ["magnitude"], {**table, "magnitude": [0.0, 0.0]}     # no size: the kind ignores it
        if len(given) != 1:
            raise RobofdiError(f"{where}: give exactly one of 'magnitude' (in the kind's unit) or 'magnitude_fraction' "
                               f"(of the target's limit), got {given or 'neither'}")
        low = -1.0 if not signed and kind in SIGNED_KINDS + SCALE_KINDS else 0.0
        if "magnitude_fraction" in table:
            magnitude, fraction = None, _range(f"{where}.magnitude_fraction", table["magnitude_fraction"], low, 1.0)
        else:
            fraction, magnitude = None, _range(f"{where}.magnitude", table["magnitude"])
            for t, lim in limits.items():
                if max(abs(magnitude[0]), abs(magnitude[1])) > lim.limit or (magnitude[0] < 0 and low == 0.0):
                    raise RobofdiError(f"{where}.magnitude: [{magnitude[0]:g}, {magnitude[1]:g}] is outside the limits of "
                                       f"target {t!r}: [{low * lim.limit:g}, {lim.limit:g}] {lim.unit}")
        if kind in SCALE_KINDS and (fraction or magnitude)[0] <= -1.0:
            raise RobofdiError(f"{where}.{given[0]}: a gain 1 + m must stay positive, expected low > -1, got "
                               f"[{(fraction or magnitude)[0]:g}, {(fraction or magnitude)[1]:g}]")
        draw = table.get("magnitude_draw", "uniform")
        if draw not in MAGNITUDE_DRAWS:
            raise RobofdiError(f"{where}.magnitude_draw: expected one of {', '.join(MAGNITUDE_DRAWS)}, got {draw!r}")
        if draw == "log_uniform" and (fraction or magnitude)[0] <= 0:
            raise RobofdiError(f"{where}.magnitude_draw: log_uniform needs a range with low > 0 (the sign comes from "
                               f"random_sign), got [{(fraction or magnitude)[0]:g}, {(fraction or magnitude)[1]:g}]")
        profiles = table.get("profiles", [{"type": "step"}])
        if not isinstance(profiles, list) or not profiles:
            raise RobofdiError(f"{where}.profiles: expected a non-empty list of profiles like {{type = \"step\"}}, "
                               f"got {profiles!r}")
        onset = _range(f"{where}.onset_fraction", table.get("onset_fraction", [0.2, 0.6]), 0.0, 1.0)
        if onset[1] >= 1.0:
            raise RobofdiError(f"{where}.onset_fraction: the onset must come before the run's end, expected high < 1")
        duration = None if "duration" not in table else _range(f"{where}.duration", table["duration"], 0.0)
        if duration is not None and duration[0] <= 0:
            raise RobofdiError(f"{where}.duration: expected durations > 0 s, got {list(duration)}")
        weight = table.get("weight", 1.0)
        if not (_number(weight) and weight > 0):
            raise RobofdiError(f"{where}.weight: expected a number > 0, got {weight!r}")
        parsed = []
        for i, p in enumerate(profiles):
            try:
                profile = profile_from_dict(p if isinstance(p, dict) else {"type": p})
                probe = max(limits.values(), key=lambda lim: lim.limit)
                low_high = [v * probe.limit for v in fraction] if fraction else list(magnitude)
                size = max(low_high, key=abs)                 # 0 only when the range is [0, 0]
                probe_params = {**params, "limit": probe.limit} if free_limit else params
                check_size(Fault("probe", kind, targets[0], onset=0.0, magnitude=size, profile=profile,
                                 params=probe_params))
            except RobofdiError as exc:
                raise RobofdiError(f"{where}.profiles[{i}]: {exc}") from None
            parsed.append(profile.to_dict())
        return cls(kind, tuple(targets), magnitude, fraction, draw, signed, tuple(parsed), onset, duration, dict(params),
                   float(weight), limit_fraction, {t: (lim.limit, lim.unit) for t, lim in limits.items()})


@dataclass(frozen=True)
class CampaignSpec:
    """A validated campaign (see the module docstring). ``options``: the system's options dataclass."""

    system: str
    seed: int = 0
    fault_free_runs: int = 0
    faulty_runs: int = 0
    diagnosers: tuple = ()
    records: bool = False
    detection_level: float = 0.9
    options: Any = None
    faults: tuple = ()
    source: str = field(default="", compare=False)

    @property
    def runs(self) -> int:
        return self.fault_free_runs + self.faulty_runs

    @property
    def campaign_system(self) -> System:
        return get_system(self.system)

    def to_dict(self) -> dict:
        """The spec as plain data (what campaign.json records and --resume compares)."""
        from dataclasses import asdict

        opts = asdict(self.options) if self.options is not None else {}
        return {"system": self.system, "seed": self.seed, "fault_free_runs": self.fault_free_runs,
                "faulty_runs": self.faulty_runs, "diagnosers": list(self.diagnosers), "records": self.records,
                "detection_level": self.detection_level, "system_options": json.loads(json.dumps(opts, default=list)),
                "faults": [{k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(f).items()
                            if not (k == "limit_fraction" and v is None)}      # as before it existed: same fingerprint
                           for f in self.faults]}

    def fingerprint(self) -> str:
        """A hash of everything that decides the runs' results."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True, default=str).encode()).hexdigest()[:16]


_TOP = ("system", "seed", "fault_free_runs", "faulty_runs", "diagnosers", "records", "detection_level", "faults")


def parse_spec(data: dict, source: str = "spec") -> CampaignSpec:
    """Validate a spec given as a dict (what tomllib returns); errors name the field."""
    if not isinstance(data, dict):
        raise RobofdiError(f"{source}: expected a table, got {type(data).__name__}")
    unknown = sorted(set(data) - set(_TOP) - {"system"})
    if unknown:
        raise RobofdiError(f"{source}: unknown field {unknown[0]!r}; expected one of {', '.join(_TOP)} and a [system] table")
    name = data.get("system")
    options_table = {}
    if isinstance(name, dict):       # [system] table with name = "arm"
        options_table = dict(name)
        name = options_table.pop("name", None)
    if name is None:
        raise RobofdiError(f"{source}: field 'system' is required (e.g. system = \"arm\", or [system] with name = \"arm\")")
    if not isinstance(name, str) or not name:
        raise RobofdiError(f"{source}: field 'system' must be a system name, got {name!r}")
    # everything that does not need the system first: a 'package.module:attribute' system is imported (its code
    # runs) only for a spec that is otherwise valid
    seed = check_seed(f"{source}: field 'seed'", data.get("seed", 0))
    counts = {}
    for key in ("fault_free_runs", "faulty_runs"):
        v = data.get(key, 0)
        if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
            raise RobofdiError(f"{source}: field {key!r} must be an integer >= 0, got {v!r}")
        counts[key] = v
    if counts["fault_free_runs"] + counts["faulty_runs"] == 0:
        raise RobofdiError(f"{source}: fields 'fault_free_runs' + 'faulty_runs' must be > 0, got no runs")
    if counts["fault_free_runs"] + counts["faulty_runs"] > MAX_RUNS:
        raise RobofdiError(f"{source}: fields 'fault_free_runs' + 'faulty_runs' must be <= {MAX_RUNS:,} (the results "
                           f"table, one row per run and diagnoser, is held in memory), got "
                           f"{counts['fault_free_runs'] + counts['faulty_runs']:,}")
    records = data.get("records", False)
    if not isinstance(records, bool):
        raise RobofdiError(f"{source}: field 'records' must be true or false, got {records!r}")
    level = data.get("detection_level", 0.9)
    if not (_number(level) and 0 < level < 1):
        raise RobofdiError(f"{source}: field 'detection_level' must be a probability in (0, 1), got {level!r}")
    tables = data.get("faults", [])
    if not isinstance(tables, list):
        raise RobofdiError(f"{source}: field 'faults' must be [[faults]] tables, got {tables!r}")
    if counts["faulty_runs"] and not tables:
        raise RobofdiError(f"{source}: field 'faults': faulty_runs = {counts['faulty_runs']} needs at least one [[faults]] entry")
    try:
        system = get_system(name)
    except RobofdiError as exc:
        raise RobofdiError(f"{source}: {exc}") from None
    options = _options(f"{source}: system", system, options_table)
    try:                       # the robot file, joints, instances: checked now, not after the folder is written
        system.targets(options)
        system.calibration_keys(options)
    except RobofdiError as exc:
        raise RobofdiError(f"{source}: {exc}") from None
    available = tuple(system.diagnosers(options))
    default = getattr(system, "default_diagnosers", system.diagnosers)(options)    # opt-in diagnosers only by name
    diagnosers = data.get("diagnosers", list(default))
    if not isinstance(diagnosers, list) or not diagnosers:
        raise RobofdiError(f"{source}: field 'diagnosers' must be a non-empty list, got {diagnosers!r}")
    for d in diagnosers:
        if d not in available:
            raise RobofdiError(f"{source}: field 'diagnosers': unknown diagnoser {d!r} for system {system.name!r}; "
                               f"expected some of {', '.join(available)}")
    faults = tuple(FaultDistribution.resolve(f"{source}: faults[{i}]", t, system, options) for i, t in enumerate(tables))
    return CampaignSpec(name, seed, counts["fault_free_runs"],
                        counts["faulty_runs"], tuple(diagnosers), records, float(level), options, faults, source)


def _options(where: str, system: System, table: dict):
    if not isinstance(table, dict):
        raise RobofdiError(f"{where}: expected a table, got {table!r}")
    try:
        return compose(system.options_type, table, where)   # flat names or nested tables per part
    except RobofdiError as exc:
        if str(exc).startswith(f"{where}:"):
            raise
        raise RobofdiError(f"{where}: {exc}".replace("system: system", "system")) from None
    except TypeError as exc:
        raise RobofdiError(f"{where}: {exc}") from None


def shipped_specs() -> dict[str, Path]:
    """The example specs installed with robofdi (``experiments/campaigns/*.toml``) by name."""
    from importlib import resources

    folder = resources.files("robofdi.experiments") / "campaigns"
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir() if str(p).endswith(".toml")}


def load_spec(spec) -> CampaignSpec:
    """A spec from a TOML file path, the name of a shipped spec ("arm", "auv", …), TOML text, a dict, or a
    CampaignSpec (returned as is)."""
    if isinstance(spec, CampaignSpec):
        return spec
    if isinstance(spec, dict):
        return parse_spec(spec)
    if isinstance(spec, str) and "\n" in spec:
        try:
            return parse_spec(tomllib.loads(spec), "spec")
        except tomllib.TOMLDecodeError as exc:
            raise RobofdiError(f"spec: not valid TOML: {exc}") from None
    path = Path(spec)
    if not path.is_file():
        shipped = shipped_specs()
        if str(spec) in shipped:
            path = shipped[str(spec)]
        else:
            raise RobofdiError(f"SPEC: no file {str(spec)!r}; expected a TOML file or a shipped spec "
                               f"({', '.join(sorted(shipped))})")
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise RobofdiError(f"{path.name}: not UTF-8 text (byte {exc.start}); expected a TOML file in UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise RobofdiError(f"{path.name}: not valid TOML: {exc}") from None
    return parse_spec(data, path.name)
