"""A real robot's logs: joint positions, velocities and commanded torques from a file, diagnosed offline.

The diagnosers run on a log exactly as they run on a simulated record (:func:`robofdi.loop.diagnose_record`):
the same residual generators on the nominal model of the robot's file (MJCF or URDF), the same
:class:`~robofdi.decision.ThresholdDecision`. What a log adds is the checking and the calibration:

1. :func:`read_arm_log` reads CSV (``.csv``, ``.csv.gz``), Parquet or a ROS 2 bag (``.mcap`` of
   ``sensor_msgs/msg/JointState``, :mod:`robofdi.rosbag`), renames the log's own columns (``columns``: log name →
   robofdi name; a joint's name stands for its three columns), and checks it: every column present and finite, time
   strictly increasing, positions inside the joint ranges [rad or m], velocities consistent with the positions'
   derivative [rad/s or m/s] and torques inside 1.5 × the drives' limits [N·m or N] (a log in degrees or in motor
   units is refused, naming the column). It then puts the log on a uniform grid at ``rate`` (default: the median
   sample rate): positions and velocities interpolated linearly, torques held from the last logged sample
   (zero-order hold, as a drive holds its command); jitter and dropped rows are measured and reported.
2. :func:`calibrate_on_segment` sets each diagnoser's thresholds from a fault-free segment the user names,
   ρ_i = margin · max |r_i| (Caccavale & Villani Sec. 6, the book's rule), start-up samples blanked.
3. :func:`diagnose_log` runs every chosen diagnoser over the whole log with its decision and returns the record
   (``signals/y_meas``, ``signals/u_diag``; ``truth/state`` holds the *measured* positions and velocities, for the
   replay — a log has no truth) and a summary: first alarm, isolated hypothesis and estimate per diagnoser.

Column names robofdi expects (after ``columns``): ``time`` [s], and per arm joint ``<joint>_q``, ``<joint>_qd``,
``<joint>_tau`` (the commanded torque). The diagnosers are those whose calibration needs no learnt design or
spectral fit (:func:`robofdi.observers.arm_schemes.scheme_calibration`): the consistency and adaptive schemes need
the simulated calibration motions of :mod:`robofdi.systems.arm` and are refused here with that reason.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robofdi.decision import ThresholdDecision, calibrate_thresholds, startup_samples
from robofdi.errors import RobofdiError
from robofdi.loop import Diagnosis, Rates, diagnose_record
from robofdi.models import ManipulatorModel
from robofdi.observers.arm_schemes import SCHEMES, ArmSchemeSettings, arm_schemes, scheme_calibration
from robofdi.record import Record

__all__ = ["ArmLog", "read_arm_log", "log_record", "calibrate_on_segment", "diagnose_log", "LOG_SCHEMES"]

#: The arm diagnosers a log can calibrate by itself (no learnt design, no ripple fit), best first.
LOG_SCHEMES = ("momentum", "recursive", "simple", "time_delayed", "position_only")
#: Rows further apart than this many sample periods count as a dropout.
DROPOUT_PERIODS = 1.5
#: Torques beyond this factor × the drive's limit mean the column is not in N·m (motor units, mN·m, per-unit).
TORQUE_SLACK = 1.5


@dataclass(frozen=True)
class ArmLog:
    """A checked log on a uniform grid: ``time`` (N,) [s], ``q``, ``qd``, ``tau`` (N, n) [rad, rad/s, N·m (m,
    m/s, N for slide joints)], the ``joints`` in arm order, its ``rate_hz``, the ``source`` file, and what the
    grid hid: rows logged, dropouts (gaps longer than 1.5 periods; their count and the longest [s]), and the
    timing jitter (standard deviation of the logged stamps from the grid [s])."""

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    joints: tuple
    rate_hz: float
    source: str
    rows: int
    dropouts: int
    longest_gap: float
    jitter: float
    renamed: dict = field(default_factory=dict)
    origin: dict = field(default_factory=dict)

    def report(self) -> dict:
        return {"source": self.source, "rows": self.rows, "rate_hz": self.rate_hz, "samples": int(self.time.size),
                "duration_s": float(self.time[-1] - self.time[0]), "dropouts": self.dropouts,
                "longest_gap_s": round(self.longest_gap, 6), "jitter_s": float(f"{self.jitter:.3g}"),
                "columns": dict(self.renamed), **self.origin}


def parse_topics(topics) -> tuple[str, str | None]:
    """``"STATE[,COMMAND]"`` (the CLI's ``--topics``) or a (state, command) pair → (state topic, command topic)."""
    if topics is None:
        return "/joint_states", None
    parts = [p.strip() for p in topics.split(",")] if isinstance(topics, str) else [str(p) if p else "" for p in topics]
    if not 1 <= len(parts) <= 2 or not parts[0] or not all(p.startswith("/") for p in parts if p):
        raise RobofdiError(f"--topics: expected STATE[,COMMAND] ROS 2 topic names such as /joint_states,/joint_commands, "
                           f"got {topics!r}")
    return parts[0], (parts[1] or None) if len(parts) == 2 else None


def _read_table(path: Path, topics=None):
    """The log's table and what its format adds to the report (a bag: its topics and where the torques came from)."""
    import pandas as pd

    name = path.name.lower()
    if name.endswith(".mcap"):
        from robofdi.rosbag import read_joint_states

        return read_joint_states(path, *parse_topics(topics))
    if topics is not None:
        raise RobofdiError(f"--topics: {path.name} is not a ROS 2 bag (.mcap); topics name a bag's JointState topics")
    try:
        if name.endswith((".csv", ".csv.gz")):
            return pd.read_csv(path), {}
        if name.endswith((".parquet", ".pq")):
            return pd.read_parquet(path), {}
    except Exception as exc:                                    # malformed content: one line, naming the file
        raise RobofdiError(f"log {path.name}: cannot be read ({' '.join(str(exc).split())})") from None
    raise RobofdiError(f"log {path.name}: unknown format; expected .csv, .csv.gz, .parquet or .mcap (a ROS 2 bag)")


def _joint_renames(renamed: Mapping[str, str], columns) -> dict[str, str]:
    """A mapping entry naming a joint (``shoulder_pan=joint1``: the log has ``shoulder_pan_q``, ``_qd``, ``_tau``)
    stands for its three columns; every other entry is kept as it is."""
    out = {}
    for key, value in renamed.items():
        triple = [f"{key}_{k}" for k in ("q", "qd", "tau")]
        if key not in columns and all(c in columns for c in triple):
            out.update({c: f"{value}_{k}" for c, k in zip(triple, ("q", "qd", "tau"))})
        else:
            out[key] = value
    return out


def parse_columns(text: str | Mapping[str, str] | None) -> dict[str, str]:
    """``"t=time,pos1=joint1_q"`` (the CLI's ``--columns``) or a mapping → {log name: robofdi name}."""
    if text is None:
        return {}
    if isinstance(text, Mapping):
        return {str(k): str(v) for k, v in text.items()}
    out = {}
    for item in (s.strip() for s in str(text).split(",")):
        if not item:
            continue
        log_name, sep, name = item.partition("=")
        if not sep or not log_name.strip() or not name.strip():
            raise RobofdiError(f"--columns: {item!r} is not LOG_NAME=ROBOFDI_NAME")
        out[log_name.strip()] = name.strip()
    return out


def _check_units(name: str, col: str, values: np.ndarray, lo: float, hi: float, unit: str) -> None:
    if np.isfinite(lo) and np.isfinite(hi):
        slack = 0.1 * (hi - lo)
        if values.min() < lo - slack or values.max() > hi + slack:
            raise RobofdiError(f"log {name}: column {col!r} reaches {values.min():.4g} .. {values.max():.4g}, outside "
                               f"the joint range [{lo:.4g}, {hi:.4g}] {unit}; expected {unit}")


def _check_velocity(name: str, col: str, t: np.ndarray, q: np.ndarray, qd: np.ndarray, unit: str) -> None:
    """The logged velocity against the positions' central difference: refused when it is off by more than a
    factor 2 where the joint really moves (e.g. deg/s beside rad, or rpm)."""
    dq = np.gradient(q, t)
    moving = np.abs(dq) > max(0.05 * np.abs(dq).max(), 1e-6)
    if moving.sum() < 10:
        return
    scale = float(np.dot(qd[moving], dq[moving]) / max(np.dot(dq[moving], dq[moving]), 1e-300))
    if not 0.5 < scale < 2.0:
        raise RobofdiError(f"log {name}: column {col!r} is {scale:.3g} × the derivative of the positions; expected "
                           f"{unit} (the positions' rate of change)")


def read_arm_log(path: str | Path, model: ManipulatorModel, columns: Mapping[str, str] | str | None = None,
                 rate: float | None = None, topics=None) -> ArmLog:
    """Read, check and resample a log of the arm ``model`` (its joint names, ranges and torque limits); see the
    module docstring. ``rate`` [Hz]: the grid (default: the log's median sample rate, rounded to 0.1 Hz).
    ``topics``: a ROS 2 bag's (state, command) JointState topics (:mod:`robofdi.rosbag`; default
    ``/joint_states`` and no command topic)."""
    path = Path(path)
    name = path.name
    if not path.is_file():
        raise RobofdiError(f"log: file {str(path)!r} does not exist")
    table, origin = _read_table(path, topics)
    renamed = _joint_renames(parse_columns(columns), table.columns)
    table = table.rename(columns=renamed)
    joints = tuple(model.joint_names)
    need = ["time"] + [f"{j}_{k}" for k in ("q", "qd", "tau") for j in joints]
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise RobofdiError(f"log {name}: column {missing[0]!r} is missing ({len(missing)} of {len(need)} missing); "
                           f"expected time [s] and <joint>_q, <joint>_qd, <joint>_tau for joints {list(joints)}; "
                           f"the log has {list(table.columns)[:8]}{'…' if table.shape[1] > 8 else ''} "
                           "(rename with --columns LOG_NAME=NAME,...)")
    data = {}
    for c in need:
        try:
            v = np.asarray(table[c], dtype=float)
        except (TypeError, ValueError):
            raise RobofdiError(f"log {name}: column {c!r} holds values that are not numbers") from None
        bad = ~np.isfinite(v)
        if bad.any():
            row = int(np.argmax(bad))
            raise RobofdiError(f"log {name}: column {c!r} has {int(bad.sum())} non-finite value(s), the first in row "
                               f"{row + 1} (time {table['time'].iloc[row]!r}); expected finite numbers")
        data[c] = v
    t = data["time"]
    if t.size < 10:
        raise RobofdiError(f"log {name}: {t.size} rows; expected at least 10")
    steps = np.diff(t)
    if np.any(steps <= 0):
        row = int(np.argmax(steps <= 0)) + 1
        raise RobofdiError(f"log {name}: column 'time' is not strictly increasing at row {row + 1} ({t[row - 1]!r} "
                           f"then {t[row]!r}); expected increasing time stamps [s]")
    lo, hi = model.joint_range.T
    for i, (j, unit, speed, torque_unit) in enumerate(zip(joints, *_units(model))):
        _check_units(name, f"{j}_q", data[f"{j}_q"], lo[i], hi[i], unit)
        _check_velocity(name, f"{j}_qd", t, data[f"{j}_q"], data[f"{j}_qd"], speed)
        limit = float(model.torque_limit[i])
        if np.abs(data[f"{j}_tau"]).max() > TORQUE_SLACK * limit:
            raise RobofdiError(f"log {name}: column {j + '_tau'!r} reaches {np.abs(data[f'{j}_tau']).max():.4g}, "
                               f"beyond {TORQUE_SLACK} × the drive's limit {limit:.4g} {torque_unit}; expected the "
                               f"joint torque in {torque_unit}")
    median = float(np.median(steps))
    if rate is None:
        rate = round(1.0 / median, 1)
    if not (isinstance(rate, (int, float)) and np.isfinite(rate) and rate > 0):
        raise RobofdiError(f"rate: expected a sample rate > 0 Hz, got {rate!r}")
    if not 0.5 < rate * median < 2.0:
        raise RobofdiError(f"rate: {rate:g} Hz, but the log's median sample period is {median:.6g} s "
                           f"({1 / median:.4g} Hz); expected a rate within a factor 2 of it")
    dt = 1.0 / rate
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    gaps = steps > DROPOUT_PERIODS * dt
    nearest = np.clip(np.rint((t - t[0]) / dt).astype(int), 0, grid.size - 1)
    jitter = float(np.std(t - grid[nearest]))
    held = np.clip(np.searchsorted(t, grid + 1e-9 * dt, side="right") - 1, 0, t.size - 1)
    q = np.column_stack([np.interp(grid, t, data[f"{j}_q"]) for j in joints])
    qd = np.column_stack([np.interp(grid, t, data[f"{j}_qd"]) for j in joints])
    tau = np.column_stack([data[f"{j}_tau"][held] for j in joints])
    return ArmLog(grid - grid[0], q, qd, tau, joints, float(rate), str(path), int(t.size), int(gaps.sum()),
                  float(steps[gaps].max()) if gaps.any() else 0.0, jitter, renamed, origin)


def _units(model: ManipulatorModel) -> tuple[list[str], list[str], list[str]]:
    """Position, velocity and torque units of the arm joints (a slide joint in m, m/s, N)."""
    slide = [k == "slide" for k in model.joint_kinds]
    return (["m" if s else "rad" for s in slide], ["m/s" if s else "rad/s" for s in slide],
            ["N" if s else "N·m" for s in slide])


def log_record(log: ArmLog, model: ManipulatorModel) -> Record:
    """The log as a :class:`~robofdi.record.Record` the diagnosers replay: ``y_meas`` = [q, q̇], ``u_diag`` =
    ``u_cmd`` = the commanded torques; ``truth/state`` holds the measurements (a log has no truth)."""
    y = np.column_stack([log.q, log.qd])
    pos, vel, torque = _units(model)
    state = [f"{j}_q" for j in log.joints] + [f"{j}_qd" for j in log.joints]
    joints = list(log.joints)
    return Record(
        system=model.system, scenario=f"log:{Path(log.source).name}", seed=None,
        rates={"control_hz": log.rate_hz, "diagnosis_hz": log.rate_hz}, time=log.time, truth_state=y,
        signals={"y_meas": y, "u_diag": log.tau, "u_cmd": log.tau}, u_applied=log.tau,
        meta={"log": log.report(), "joint_names": joints, "mjcf": str(model.path), "faults": [],
              "truth": "none: a logged robot; truth/state holds the measured positions and velocities",
              "duration": float(log.time[-1]), "injection": "online"},
        columns={"truth/state": state, "truth/u_applied": joints, "signals/y_meas": state,
                 "signals/u_diag": joints, "signals/u_cmd": joints},
        units={"truth/state": pos + vel, "truth/u_applied": torque, "signals/y_meas": pos + vel,
               "signals/u_diag": torque, "signals/u_cmd": torque},
    )


def _segment(record: Record, t0: float, t1: float) -> Record:
    keep = (record.time >= t0) & (record.time <= t1)
    return Record(record.system, record.scenario, record.seed, record.rates, record.time[keep] - t0,
                  record.truth_state[keep], signals={k: v[keep] for k, v in record.signals.items()},
                  meta=record.meta, columns=record.columns, units=record.units)


def _check_schemes(schemes: Sequence[str]) -> tuple[str, ...]:
    schemes = tuple(schemes)
    if not schemes:
        raise RobofdiError(f"diagnosers: expected at least one of {list(LOG_SCHEMES)}")
    for s in schemes:
        if s not in SCHEMES:
            raise RobofdiError(f"diagnosers: unknown diagnoser {s!r}; expected some of {list(LOG_SCHEMES)}")
        if scheme_calibration(s).design is not None or s == "adaptive":
            raise RobofdiError(f"diagnosers: {s!r} needs the simulated calibration motions of robofdi run arm (a learnt "
                               f"design or a ripple fit), not a logged segment; expected some of {list(LOG_SCHEMES)}")
    return schemes


def calibrate_on_segment(record: Record, model: ManipulatorModel, segment: tuple[float, float],
                         schemes: Sequence[str] = LOG_SCHEMES, margin: float = 1.2,
                         settings: ArmSchemeSettings | None = None) -> dict[str, np.ndarray]:
    """Thresholds per diagnoser from the fault-free ``segment`` = (t0, t1) [s] of the log's record:
    ρ_i = ``margin`` · max |r_i| over it, the start-up samples blanked (Caccavale & Villani Sec. 6)."""
    schemes = _check_schemes(schemes)
    t0, t1 = (float(v) for v in segment)
    if not (0 <= t0 < t1 <= record.time[-1] + 1e-9):
        raise RobofdiError(f"fault-free segment: ({t0:g}, {t1:g}) s is not inside the log (0 .. "
                           f"{record.time[-1]:g} s); expected T0 < T1 inside it")
    settings = settings or ArmSchemeSettings()
    T = 1.0 / record.rates["diagnosis_hz"]
    settings = ArmSchemeSettings(**{**settings.__dict__, "T": T})
    skip = startup_samples(T)
    part = _segment(record, t0, t1)
    if part.time.size <= skip + 10:
        raise RobofdiError(f"fault-free segment: ({t0:g}, {t1:g}) s holds {part.time.size} samples; expected more than "
                           f"the {skip} start-up samples the decision blanks, plus 10")
    rates = Rates(record.rates["control_hz"], record.rates["diagnosis_hz"])
    out = {}
    for name, diagnoser in arm_schemes(model, settings, None, schemes).items():
        out[name] = calibrate_thresholds([diagnose_record(part, Diagnosis(diagnoser), rates).residual], margin, skip)
    return out


def diagnose_log(path: str | Path, robot: str | Path, fault_free: tuple[float, float], *, columns=None,
                 rate: float | None = None, schemes: Sequence[str] = LOG_SCHEMES, margin: float = 1.2,
                 joints=None, torque_motors: bool = False, drive_inertia: float = 0.0, topics=None) -> tuple[Record, dict]:
    """Read the log of ``robot`` (MJCF or URDF), calibrate on its ``fault_free`` segment, diagnose all of it.
    Returns (the record with every diagnoser's trace, a summary: the log's report, thresholds, and per
    diagnoser its alarms in the calibration segment, first alarm after it, isolated hypothesis and estimate)."""
    schemes = _check_schemes(schemes)
    model = ManipulatorModel(robot, joints=joints, torque_motors=torque_motors, drive_inertia=drive_inertia)
    log = read_arm_log(path, model, columns, rate, topics)
    record = log_record(log, model)
    thresholds = calibrate_on_segment(record, model, fault_free, schemes, margin)
    T = 1.0 / log.rate_hz
    settings = ArmSchemeSettings(T=T)
    skip = startup_samples(T)
    rates = Rates(log.rate_hz, log.rate_hz)
    summary = {"experiment": "diagnose", "system": model.system, "log": log.report(),
               "fault_free_segment_s": [float(fault_free[0]), float(fault_free[1])], "margin": margin,
               "diagnosers": {}}
    for name, diagnoser in arm_schemes(model, settings, None, schemes).items():
        decision = ThresholdDecision(diagnoser.components, thresholds[name], diagnoser.signatures(), blanking=skip)
        trace = diagnose_record(record, Diagnosis(diagnoser, decision), rates)
        record.diagnosers[name] = trace
        alarm = trace.alarm.any(axis=1)
        inside = (trace.time >= fault_free[0]) & (trace.time <= fault_free[1])
        after = np.flatnonzero(alarm & (trace.time > fault_free[1]))
        first = int(after[0]) if after.size else None
        isolated = next((trace.isolated[k] for k in range(first, len(trace.time)) if trace.isolated[k]), "") \
            if first is not None else ""
        summary["diagnosers"][name] = {
            "alarm_samples_in_fault_free_segment": int(alarm[inside].sum()),
            "first_alarm_s": None if first is None else float(trace.time[first]),
            "isolated": isolated,
            "estimate": {c: float(trace.estimate[-1, i]) for i, c in enumerate(trace.estimate_components)
                         if isolated and c in isolated.split("+")},
            "thresholds": {c: float(v) for c, v in zip(trace.components, thresholds[name])},
            "units": trace.units.get("residual"),
        }
    record.meta["lead_diagnoser"] = schemes[0]
    return record, summary


def print_table(summary: Mapping) -> str:
    """The summary as the lines ``robofdi diagnose`` prints."""
    seg = summary["fault_free_segment_s"]
    lines = [f"{'diagnoser':14s} {'first alarm [s]':>15s}  {'isolated':14s} {'estimate':>12s}  alarms in {seg[0]:g}-{seg[1]:g} s"]
    for name, d in summary["diagnosers"].items():
        first = "-" if d["first_alarm_s"] is None else f"{d['first_alarm_s']:.3f}"
        est = ", ".join(f"{v:.4g}" for v in d["estimate"].values()) or "-"
        lines.append(f"{name:14s} {first:>15s}  {d['isolated'] or '-':14s} {est:>12s}  "
                     f"{d['alarm_samples_in_fault_free_segment']}")
    return "\n".join(lines)
