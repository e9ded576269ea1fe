"""The closed-loop runner: where the simulator (truth) and the diagnosers (belief) meet.

One control tick j at time t_j = j / control_hz::

    y_j ─► sensor faults ─► ȳ_j ─► controller ─► u_cmd_j ─► accommodation(health) ─► u_j ─► actuator faults ─► plant
                             │                                   ▲                               (saturates: u_applied)
                             └──► diagnosers every control_hz/diagnosis_hz ticks, with ū = the inputs u held over
                                  the diagnosis interval that just ended (mean, or first, of them) ─► health,
                                  used by the accommodation from the next diagnosis sample on (one sample late)

``injection="online"``: faults act in the loop (the plant gets the faulty input, the controller sees the faulty
measurement, component faults change the plant). ``injection="offline"``: the run is fault-free and only the
diagnosers' view is corrupted — the emulation of Caccavale & Villani Sec. 7. It is exact only where the actuator
fault is invertible (the diagnosers are told ū with faulty(ū) = u, :meth:`FaultInjector.emulate`), so other kinds
are refused at construction.

Labels come from what the plant received: an actuator fault's value is its effect after saturation.

The engine's parts serve every loop (this one, the refiner's, the robosuite and dm_control adapters'):
:class:`DiagnosisRunner` steps one diagnosis (diagnoser → decision → identification → health) and keeps its
trace; :class:`DiagnosisBank` steps every diagnosis of a run and hands out the health one diagnosis sample late;
:class:`Recorder` collects the rows of a run and turns them into the arrays, labels, columns and units of a
:class:`~robofdi.record.Record`. Offline, :func:`diagnose_record` and :func:`replay` step a diagnoser over a
record's diagnoser view with the same input forming (ū(k−1), zeros at the first sample).
"""
from __future__ import annotations

import signal
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robofdi.columns import CHUNK, Column
from robofdi.decision import Identification
from robofdi.errors import RobofdiError
from robofdi.faults import FAULT_KINDS, Fault, FaultInjector, check_faults
from robofdi.interrupts import Interrupted, signal_of
from robofdi.protocols import (
    HEALTHY,
    Accommodation,
    Controller,
    Decision,
    Diagnoser,
    Health,
    Identifier,
    Reference,
    Simulator,
)
from robofdi.protocols import output_is_state as _output_is_state
from robofdi.record import DiagnoserTrace, FaultLabels, Record
from robofdi.seeding import stream

__all__ = ["Rates", "Diagnosis", "DiagnosisRunner", "DiagnosisBank", "Recorder", "ClosedLoop", "RunAborted",
           "RunInterrupted", "diagnose_record", "diagnoser_inputs", "replay", "ORACLE"]

#: ``health_source`` of the oracle accommodation: health read from the fault labels (a bound, never a diagnosis).
ORACLE = "oracle"


@dataclass(frozen=True)
class Rates:
    """Control and diagnosis rates [Hz]; the physics rate is the simulator's. ``input_hold``: how ū of a
    diagnosis interval is formed from the inputs in it ("mean" or "first")."""

    control_hz: float = 1000.0
    diagnosis_hz: float = 500.0
    input_hold: str = "mean"

    def __post_init__(self):
        if not (np.isfinite(self.control_hz) and self.control_hz > 0):
            raise RobofdiError(f"Rates: field 'control_hz' must be > 0, got {self.control_hz}")
        ratio = self.control_hz / self.diagnosis_hz if self.diagnosis_hz > 0 else np.nan
        if not (np.isfinite(ratio) and ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
            raise RobofdiError(
                f"Rates: field 'diagnosis_hz' must divide control_hz={self.control_hz} (got {self.diagnosis_hz})"
            )
        if self.input_hold not in ("mean", "first"):
            raise RobofdiError(f"Rates: field 'input_hold' must be 'mean' or 'first', got {self.input_hold!r}")

    @classmethod
    def for_simulator(cls, sim: Simulator, diagnosis_hz: float | None = None, input_hold: str = "mean") -> Rates:
        """The simulator's control rate, and ``diagnosis_hz`` (default: the control rate)."""
        control_hz = 1.0 / sim.control_dt
        return cls(control_hz, control_hz if diagnosis_hz is None else diagnosis_hz, input_hold)

    @property
    def ratio(self) -> int:
        return int(round(self.control_hz / self.diagnosis_hz))

    def as_dict(self, physics_dt: float | None = None) -> dict:
        d = {"control_hz": self.control_hz, "diagnosis_hz": self.diagnosis_hz, "input_hold": self.input_hold}
        if physics_dt:
            d["physics_hz"] = 1.0 / physics_dt
        return d


@dataclass
class Diagnosis:
    """A diagnoser (:class:`robofdi.protocols.Diagnoser`), optionally its decision
    (:class:`robofdi.protocols.Decision`) and its identification (:class:`robofdi.protocols.Identifier`; None:
    :class:`robofdi.decision.Identification` of the diagnoser's ``estimate_components`` / ``estimate_modes``)."""

    diagnoser: Diagnoser
    decision: Decision | None = None
    identification: Identifier | None = None


def protocol_members(protocol: type) -> list[str]:
    """The public attributes and methods a protocol class declares (its annotations and its functions)."""
    names = list(getattr(protocol, "__annotations__", {}))
    names += [k for k, v in vars(protocol).items() if callable(v) and not k.startswith("_") and k not in names]
    return names


def _check_diagnosis(name: str, d: Diagnosis) -> None:
    """A diagnosis whose parts do not implement the protocols is refused here, naming what is missing."""
    for field_name, part, protocol in (("diagnoser", d.diagnoser, Diagnoser), ("decision", d.decision, Decision),
                                       ("identification", d.identification, Identifier)):
        if part is None and field_name != "diagnoser":
            continue
        if not isinstance(part, protocol):
            missing = [m for m in protocol_members(protocol) if not hasattr(part, m)]
            raise RobofdiError(f"diagnosis {name!r}: field {field_name!r} does not implement the {protocol.__name__} "
                               f"protocol (missing: {', '.join(missing) or 'some members'})")


class RunAborted(RuntimeError):
    """A run failed part-way; ``record`` holds everything recorded up to the failure, ``partial_path`` where it
    was saved (set by :func:`robofdi.evaluate.run_folder.keep_partial`)."""

    def __init__(self, message: str, record: Record):
        super().__init__(message)
        self.record = record
        self.partial_path = None


class RunInterrupted(Interrupted):
    """SIGINT or SIGTERM during a run (a KeyboardInterrupt, not a failure: a campaign never journals it as an
    error row). ``record`` holds what was recorded so far, ``partial_path`` where it was saved."""

    def __init__(self, message: str, record: Record, signum: int):
        super().__init__(signum, message)
        self.record = record
        self.partial_path = None


class InputHold:
    """The input ū a diagnosis sample is handed, formed from the control-rate inputs of its interval
    (:attr:`Rates.input_hold`): their mean, summed in order (bit-identical to ``sum(inputs) / len``), or the first."""

    __slots__ = ("_ratio", "_mean", "_count", "_held")

    def __init__(self, rates: Rates):
        self._ratio, self._mean = rates.ratio, rates.input_hold == "mean"
        self.reset()

    def reset(self) -> None:
        self._count, self._held = 0, None        # inputs so far; their sum (or the first)

    def add(self, j: int, u_prev: np.ndarray) -> np.ndarray | None:
        """Control tick j's input held over the tick that just ended; ū on a diagnosis tick (a fresh array every
        interval), else None."""
        if self._count == 0:
            self._held = np.array(u_prev, dtype=float)
        elif self._mean:
            self._held += u_prev
        self._count += 1
        if j % self._ratio:
            return None
        u = self._held                    # a fresh array every interval: divided in place, the same quotient
        if self._mean:
            u /= self._count
        self._count = 0
        return u


class DiagnosisRunner:
    """Steps one diagnosis at the diagnosis rate from control-rate samples, keeps its trace and its health."""

    def __init__(self, diagnosis: Diagnosis, rates: Rates, name: str = "", chunk: int = CHUNK):
        self.diagnosis, self.rates, self.name, self.chunk = diagnosis, rates, name, chunk
        d = diagnosis.diagnoser
        self.identification = (diagnosis.identification if diagnosis.identification is not None
                               else Identification(d.estimate_components, d.estimate_modes))
        self.reset()

    def reset(self) -> None:
        d = self.diagnosis
        d.diagnoser.reset()
        if d.decision is not None:
            d.decision.reset()
        self.identification.reset()
        self._health, self._last = HEALTHY, None
        self._hold = InputHold(self.rates)
        self._isolated, self._joined = (), ""
        self._latest = None
        self._rows: dict[str, Column] = {k: Column(self.chunk)
                                         for k in ("time", "residual", "alarm", "isolated", "estimate")}
        # the trace columns' own appenders (:attr:`robofdi.columns.Column.appender`), settled every chunk samples
        self._add = tuple(column.appender for column in self._rows.values())
        self._pending = 0

    def push(self, j: int, t: float, y: np.ndarray, u_prev: np.ndarray) -> bool:
        """Control tick j at time t: y measured now, u_prev the input held over the tick that just ended
        (zeros at the first tick, which only initialises the diagnoser). True when a diagnosis sample was taken."""
        u = self._hold.add(j, u_prev)
        if u is None:
            return False
        self.sample(t, y, u)
        return True

    def sample(self, t: float, y: np.ndarray, u: np.ndarray) -> None:
        """One diagnosis sample at time t: y measured now, u the ū of the interval that just ended (the diagnoser
        is handed this very array) — what :meth:`push` does on a diagnosis tick, once ū is formed."""
        res = self.diagnosis.diagnoser.update(y, u)
        self.decide(t, res.r, res.estimate)

    def decide(self, t: float, r: np.ndarray, estimate: np.ndarray) -> None:
        """The rest of a diagnosis sample at time t once the diagnoser gave its residual ``r`` and identification
        candidates ``estimate``: the decision, the identification, the trace rows and the health — what
        :meth:`sample` does after the diagnoser's update (the lockstep engine, :mod:`robofdi.lockstep`, hands
        residuals it computed for many runs at once)."""
        decision = self.diagnosis.decision
        if decision is not None:
            alarms = decision.update(r)
            alarm, isolated = alarms.alarm, alarms.isolated
        else:
            alarm, isolated = np.zeros(r.size, dtype=bool), ()
        estimate = self.identification.update(estimate, isolated)
        add_time, add_residual, add_alarm, add_isolated, add_estimate = self._add
        add_time(t)
        add_residual(r)
        add_alarm(alarm)
        if isolated != self._isolated:
            self._isolated, self._joined = isolated, "+".join(isolated)
        add_isolated(self._joined)
        add_estimate(estimate)
        self._pending += 1
        if self._pending >= self.chunk:   # what Column.append does at a full chunk: convert the rows into blocks
            for column in self._rows.values():
                column.settle()
            self._pending = 0
        self._latest = (alarm, self._joined)
        if isolated:                      # the health is made when it is read (the health source's, one late)
            self._last, self._health = (t, isolated, estimate), None

    def latest(self) -> tuple[np.ndarray, str]:
        """(alarm per residual component, isolated hypotheses joined by "+") of the last diagnosis sample; no
        alarm and "" before the first."""
        if self._latest is None:
            return np.zeros(len(self.diagnosis.diagnoser.components), dtype=bool), ""
        alarm, isolated = self._latest
        return np.array(alarm, dtype=bool), isolated

    @property
    def health(self) -> Health:
        """The health after the last diagnosis sample: the isolated faults and their identified magnitudes."""
        if self._health is None:
            t, isolated, estimate = self._last
            self._health = Health(t, tuple(isolated), self.identification.magnitudes(estimate, isolated), self.name)
        return self._health

    def take(self) -> dict[str, np.ndarray]:
        """The trace rows since the last take (time, residual, alarm, isolated, estimate), forgotten here — a
        chunk of a streamed record (arrays valid until the next push)."""
        d = self.diagnosis.diagnoser
        widths = {"residual": len(d.components), "alarm": len(d.components), "estimate": len(d.estimate_components)}
        out = {}
        self._pending = 0
        for key, column in self._rows.items():
            rows = column.take()
            dtype = object if key == "isolated" else bool if key == "alarm" else float
            rows = np.asarray(rows, dtype=dtype)
            out[key] = rows.reshape(-1, widths[key]) if key in widths else rows
        return out

    def trace(self) -> DiagnoserTrace:
        d, rows = self.diagnosis, self._rows
        m, e = len(d.diagnoser.components), len(d.diagnoser.estimate_components)
        threshold = d.decision.threshold if d.decision is not None else np.full(m, np.inf)
        return DiagnoserTrace(
            time=np.asarray(rows["time"], dtype=float),
            residual=np.asarray(rows["residual"], dtype=float).reshape(-1, m),
            threshold=np.asarray(threshold, dtype=float),
            alarm=np.asarray(rows["alarm"], dtype=bool).reshape(-1, m),
            isolated=np.asarray(rows["isolated"], dtype=object),
            estimate=np.asarray(rows["estimate"], dtype=float).reshape(len(rows["time"]), e),
            components=list(d.diagnoser.components),
            estimate_components=list(d.diagnoser.estimate_components),
            units={k: list(v) for k, v in d.diagnoser.units.items()},
        )


class DiagnosisBank:
    """Every diagnosis of one run, stepped together (:class:`DiagnosisRunner` each, reset at construction).

    :attr:`health` is the health of ``health_source`` (a name in ``diagnoses``; None: always healthy) one diagnosis
    sample late — what the accommodation may use at this tick without an algebraic loop."""

    def __init__(self, diagnoses: Mapping[str, Diagnosis], rates: Rates, health_source: str | None = None,
                 chunk: int = CHUNK):
        if health_source is not None and health_source not in diagnoses:
            raise RobofdiError(f"DiagnosisBank: field 'health_source' must be one of the diagnoses "
                               f"{sorted(diagnoses)}, got {health_source!r}")
        self.runners = {name: DiagnosisRunner(d, rates, name, chunk) for name, d in diagnoses.items()}
        self._source = self.runners.get(health_source) if health_source is not None else None
        self._hold = InputHold(rates)
        self.health = self._pending = HEALTHY

    def reset(self) -> None:
        for runner in self.runners.values():
            runner.reset()
        self.health = self._pending = HEALTHY
        self._hold.reset()

    def push(self, j: int, t: float, y: np.ndarray, u_prev: np.ndarray) -> bool:
        """:meth:`DiagnosisRunner.push` of every diagnosis; True when a diagnosis sample was taken.

        Every runner has the bank's rates, so ū is formed once (as :meth:`DiagnosisRunner.push` forms it: the same
        sums and quotient) and each runner is handed its own copy (:meth:`DiagnosisRunner.sample`)."""
        runners = self.runners
        if not runners:
            return False
        u = self._hold.add(j, u_prev)
        if u is None:
            return False
        if len(runners) == 1:
            for runner in runners.values():
                runner.sample(t, y, u)
        else:                             # copies first: a diagnoser that changed its ū would not reach the others
            for runner, own in zip(runners.values(), [u] + [u.copy() for _ in range(len(runners) - 1)]):
                runner.sample(t, y, own)
        self.health = self._pending       # health moves on one diagnosis sample late: no algebraic loop
        if self._source is not None:
            self._pending = self._source.health
        return True

    @property
    def latest_health(self) -> Health:
        """The health source's health after the last diagnosis sample — for a loop that diagnoses after it
        actuates (a same-sample feedthrough, :mod:`robofdi.systems.refiner`), where that is already one late."""
        return self._source.health if self._source is not None else HEALTHY

    def traces(self) -> dict[str, DiagnoserTrace]:
        return {name: r.trace() for name, r in self.runners.items()}

    def take(self) -> dict[str, dict[str, np.ndarray]]:
        """:meth:`DiagnosisRunner.take` of every diagnosis."""
        return {name: r.take() for name, r in self.runners.items()}


class Recorder:
    """The rows of one run, appended tick by tick into preallocated blocks (:class:`robofdi.columns.Column`), and
    the arrays of its :class:`~robofdi.record.Record`.

    ``keys``: the row series; ``label_names``: the faults whose (active, value) labels are kept; ``chunk``: rows
    per block (and per chunk handed out by :meth:`take` when the record is streamed to disk); ``same``: series →
    an earlier series whose rows it always is (the same objects every tick, e.g. u_diag = u in online injection):
    only that one is kept, the other is its copy (:meth:`array`, :meth:`take`), and is never appended to."""

    def __init__(self, keys: Sequence[str], label_names: Sequence[str] = (), chunk: int = CHUNK,
                 same: Mapping[str, str] | None = None):
        self.chunk = chunk
        self.keys = tuple(keys)
        self.same: dict[str, str] = {}
        same = dict(same or {})
        for key, source in same.items():
            for _ in range(len(same)):           # follow chains (u_diag → u → u_cmd); a cycle is refused below
                source = same.get(source, source)
            if source in same or key not in self.keys or source not in self.keys or source == key:
                raise RobofdiError(f"Recorder: field 'same' maps {key!r} to {source!r}: both must be other series "
                                   f"of {list(self.keys)}")
            self.same[key] = source
        self.rows: dict[str, Column] = {k: Column(chunk) for k in self.keys if k not in self.same}
        self.labels: dict[str, tuple[Column, Column]] = {name: (Column(chunk), Column(chunk)) for name in label_names}

    def append(self, **values) -> None:
        rows = self.rows
        for key, value in values.items():
            rows[key].append(value)

    def appenders(self, *keys: str) -> tuple:
        """The :attr:`robofdi.columns.Column.appender` of each series in ``keys``: a hot loop appends one row a
        tick with them (the same rows as :meth:`append`) and calls :meth:`settle` every ``chunk`` ticks."""
        return tuple(self.rows[k].appender for k in keys)

    def label_appenders(self) -> list[tuple[str, Any, Any]]:
        """(fault name, appender of its active flags, appender of its values) of every label, in order."""
        return [(name, a.appender, v.appender) for name, (a, v) in self.labels.items()]

    def settle(self) -> None:
        """Convert every series' full chunk of pending rows into a block (:meth:`robofdi.columns.Column.settle`)."""
        for column in self.rows.values():
            column.settle()
        for pair in self.labels.values():
            for column in pair:
                column.settle()

    def append_labels(self, labels: Mapping[str, tuple[bool, float]]) -> None:
        """One tick of :attr:`robofdi.faults.FaultInjector.labels` (name → (active, value))."""
        for name, (active, value) in labels.items():
            columns = self.labels[name]
            columns[0].append(bool(active))
            columns[1].append(float(value))

    def last(self, key: str, default=None):
        rows = self.rows[self.same.get(key, key)]
        return rows[-1] if len(rows) else default

    def __len__(self) -> int:
        """Ticks recorded (and not yet taken) in full: the shortest series."""
        return min([len(c) for c in self.rows.values()] + [len(c) for pair in self.labels.values() for c in pair])

    def array(self, key: str, width: int | None = None, dtype=float) -> np.ndarray:
        """The rows of ``key`` as an array ((N,) for scalars; (N, width) when ``width`` is given)."""
        source = self.same.get(key)
        a = self.rows[key].array(dtype) if source is None else np.array(self.rows[source].array(dtype))
        return a if width is None else a.reshape(-1, width)

    def fault_labels(self, units: Mapping[str, str]) -> dict[str, FaultLabels]:
        """The labels as :class:`~robofdi.record.FaultLabels`, ``units``: fault name → unit of its value."""
        return {k: FaultLabels(a.array(bool), v.array(float), units[k]) for k, (a, v) in self.labels.items()}

    def take(self, rows: int | None = None) -> tuple[dict, dict]:
        """(series, labels) of the rows since the last take, every one cut to ``rows`` (None: all), and forget
        them — a chunk of a streamed record (arrays valid until the next append)."""
        def cut(a):
            return a if rows is None else a[:rows]

        taken = {k: cut(c.take()) for k, c in self.rows.items()}
        series = {k: taken[k] if k in taken else _copy_rows(taken[self.same[k]]) for k in self.keys}
        labels = {k: (cut(a.take()), cut(v.take())) for k, (a, v) in self.labels.items()}
        return series, labels


def _copy_rows(rows):
    """A copy of taken rows (an array, or a list of a list column)."""
    return rows.copy() if isinstance(rows, np.ndarray) else list(rows)


def _record_rates(record: Record) -> Rates:
    return Rates(**{k: record.rates[k] for k in ("control_hz", "diagnosis_hz", "input_hold") if k in record.rates})


def _ticks(record: Record):
    """(j, t, y_j, ū_{j−1}) of every control tick of the record's diagnoser view (zeros before the first)."""
    y, u = record.signals["y_meas"], record.signals["u_diag"]
    for j, t in enumerate(record.time):
        yield j, float(t), y[j], u[j - 1] if j else np.zeros_like(u[0])


def diagnose_record(record: Record, diagnosis: Diagnosis, rates: Rates | None = None, progress=None) -> DiagnoserTrace:
    """Run a diagnosis offline over a record's diagnoser view: signals ``y_meas`` (the measurement after
    sensor faults) and ``u_diag`` (the input the diagnosers are told). ``progress(k)`` is told every 1000 ticks."""
    runner = DiagnosisRunner(diagnosis, rates or _record_rates(record))
    for j, t, y, u in _ticks(record):
        runner.push(j, t, y, u)
        if progress is not None and j % 1000 == 999:
            progress(1000)
    if progress is not None:
        progress(len(record.time) % 1000)
    return runner.trace()


def replay(record: Record, diagnoser: Diagnoser, rates: Rates | None = None, tap=None) -> list:
    """Step ``diagnoser`` (reset first) over the record's diagnoser view as :func:`diagnose_record` does, without
    a decision; returns ``tap(diagnoser, residual)`` of every diagnosis sample (default: the residual) — for
    quantities a diagnoser keeps beside its residual (a bank's every residual, an estimator's state)."""
    out = []

    class _Tap:                           # the diagnoser's protocol face, recording what ``tap`` reads
        def __getattr__(self, name):
            return getattr(diagnoser, name)

        def update(self, y, u):
            res = diagnoser.update(y, u)
            out.append(res if tap is None else tap(diagnoser, res))
            return res

    diagnose_record(record, Diagnosis(_Tap()), rates)
    return out


def diagnoser_inputs(record: Record, rates: Rates | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The (y, u) pairs a diagnoser receives when :func:`diagnose_record` replays ``record``: (N, ny)
    measurements and (N, nu) inputs ū(k−1), one row per diagnosis sample — for designs that learn from
    fault-free runs sample by sample."""
    class _Tap:
        inputs, measurements, components, estimate_components, estimate_modes = [], [], ["tap"], ["tap"], ["level"]
        units = {"residual": ["1"], "estimate": ["1"]}

        def signatures(self):
            return []

        def __init__(self):
            self.seen = []

        def reset(self):
            self.seen = []

        def update(self, y, u):
            from robofdi.observers.residual import Residual

            self.seen.append((np.array(y, dtype=float), np.array(u, dtype=float)))
            return Residual(np.zeros(1), np.zeros(1))

    tap = _Tap()
    diagnose_record(record, Diagnosis(tap), rates)
    return np.array([y for y, _ in tap.seen]), np.array([u for _, u in tap.seen])


def _label_unit(fault: Fault, sim: Simulator) -> str:
    """Unit of a fault's label value: the kind's unit, "target" replaced by the target channel's unit."""
    unit = FAULT_KINDS[fault.kind].unit
    if "target" not in unit:
        return unit
    names, units = ((sim.actuators, sim.units.get("u")) if fault.family == "actuator"
                    else (sim.sensor_channels, sim.units.get("y")))
    target_unit = units[list(names).index(fault.target)] if units is not None else ""
    return unit.replace("target", target_unit)


def _flat(reference) -> np.ndarray:
    if isinstance(reference, tuple):
        return np.concatenate([np.atleast_1d(np.asarray(r, dtype=float)) for r in reference])
    return np.atleast_1d(np.asarray(reference, dtype=float))


def _ahead_blockable(ahead) -> bool:
    """True when read-ahead reference rows (q_d, q̇_d, q̈_d) are float64 arrays of one 2-D shape, so that the per-tick
    tuples ``(q_d[k], q̇_d[k], q̈_d[k])`` would stack (:class:`robofdi.columns.Column`) to :func:`_ahead_block`."""
    return (isinstance(ahead, tuple) and len(ahead) > 0
            and all(isinstance(p, np.ndarray) and p.dtype == np.float64 and p.ndim == 2 and p.shape == ahead[0].shape
                    for p in ahead))


def _ahead_block(ahead, start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of read-ahead reference parts as one (rows, parts, n) block: row k is
    ``np.asarray((q_d[k], q̇_d[k], q̈_d[k]))``, the same numbers as the per-tick tuples stacked."""
    return np.stack([p[start:stop] for p in ahead], axis=1)


def _stack_references(refs: list) -> np.ndarray:
    """(N, k) array of the references recorded as they came (arrays, or tuples of arrays such as (q, q̇, q̈))."""
    if len(refs) == 0:
        return np.zeros((0, 0))
    if isinstance(refs, np.ndarray):
        return np.asarray(refs, dtype=float).reshape(len(refs), -1)
    try:                          # the usual case, every tick alike: one vectorised conversion
        return np.asarray(refs, dtype=float).reshape(len(refs), -1)
    except ValueError:            # ragged parts (e.g. a tuple of vectors of different lengths)
        return np.asarray([_flat(r) for r in refs], dtype=float)


@dataclass
class ClosedLoop:
    """Wires simulator, reference, controller, accommodation, faults and diagnoses for one scenario.

    ``rates``: None = the simulator's control rate, diagnosis at the same rate. ``accommodation``: between the
    controller and the actuator faults (None = identity). ``health_source``: whose health the accommodation
    gets — a name in ``diagnoses``, or :data:`ORACLE` (the fault labels: a bound, not a diagnosis).
    ``reference_columns`` / ``reference_units`` name the entries of the flattened reference in the record.
    """

    simulator: Simulator
    controller: Controller
    reference: Reference
    faults: Sequence[Fault] = ()
    diagnoses: Mapping[str, Diagnosis] = field(default_factory=dict)
    rates: Rates | None = None
    injection: str = "online"
    accommodation: Accommodation | None = None
    health_source: str | None = None
    reference_columns: Sequence[str] | None = None
    reference_units: Sequence[str] | None = None

    def __post_init__(self):
        sim = self.simulator
        if self.injection not in ("online", "offline"):
            raise RobofdiError(f"ClosedLoop: field 'injection' must be 'online' or 'offline', got {self.injection!r}")
        if self.rates is None:
            self.rates = Rates.for_simulator(sim)
        if abs(sim.control_dt * self.rates.control_hz - 1.0) > 1e-9:
            raise RobofdiError(
                f"ClosedLoop: rates.control_hz={self.rates.control_hz} does not match the simulator's "
                f"control period {sim.control_dt} s"
            )
        for name, d in self.diagnoses.items():
            _check_diagnosis(name, d)
            for attr, expected, names in (("inputs", d.diagnoser.inputs, sim.actuators),
                                          ("measurements", d.diagnoser.measurements, sim.sensor_channels)):
                if list(expected) != list(names):
                    raise RobofdiError(
                        f"ClosedLoop: diagnoser {name!r} expects {attr} {list(expected)}, the simulator has {list(names)}"
                    )
        if self.health_source is not None and self.health_source != ORACLE and self.health_source not in self.diagnoses:
            raise RobofdiError(
                f"ClosedLoop: field 'health_source' must be {ORACLE!r} or one of the diagnoses "
                f"{sorted(self.diagnoses)}, got {self.health_source!r}"
            )
        # validates targets and kinds now, not after the first seconds of a run
        injector = self._injector(0)
        check_faults(self.faults, control_hz=self.rates.control_hz)
        if self.injection == "offline":
            injector.check_offline()

    def _injector(self, seed) -> FaultInjector:
        sim = self.simulator
        return FaultInjector(self.faults, sim.actuators, sim.sensor_channels, stream(seed, "faults"),
                             component_kinds=sim.component_kinds, saturate=sim.saturate)

    def run(
        self,
        duration: float,
        initial_state: Any = None,
        *,
        seed: int | None = None,
        run_key: str = "run",
        scenario: str = "",
        meta: dict | None = None,
        progress=None,
        diagnose: bool = True,
    ) -> Record:
        """Simulate ``duration`` seconds from ``initial_state`` (None: the plant's default); return the record.

        ``seed`` drives everything random in this run through independent streams (:mod:`robofdi.seeding`):
        the sensors' noise (``stream(seed, run_key, "sensors")``) and each fault (``stream(seed, run_key,
        "faults")``). Runs with different ``run_key`` (e.g. calibration runs and test runs) never share noise.
        If anything fails part-way, :class:`RunAborted` carries the record of what was done so far.

        ``diagnose=False``: the diagnoses are not stepped (the record's ``diagnosers`` is empty), for diagnosing
        the record afterwards (:func:`robofdi.lockstep.diagnose_lockstep`, many runs at once): the same series,
        since nothing in the loop reads a diagnosis unless an accommodation follows one (refused here).
        """
        if not diagnose and self.accommodation is not None and self.health_source not in (None, ORACLE):
            raise RobofdiError(f"run: field 'diagnose' must be True when the accommodation follows the diagnosis "
                               f"{self.health_source!r} (its health feeds back into the loop)")
        return self._simulate(duration, initial_state, seed, run_key, scenario, meta, progress, None, CHUNK,
                              diagnose)

    def run_to_file(
        self,
        path,
        duration: float,
        initial_state: Any = None,
        *,
        seed: int | None = None,
        run_key: str = "run",
        scenario: str = "",
        meta: dict | None = None,
        progress=None,
        chunk: int = CHUNK,
    ):
        """:meth:`run`, the record streamed to the HDF5 file ``path`` as the run goes, every ``chunk`` control
        ticks (:class:`robofdi.record.RecordWriter`: the layout of :meth:`Record.save`, read back by
        :func:`robofdi.record.load`), so memory stays bounded whatever ``duration``; returns ``path``. The same
        seed gives the same series as :meth:`run`. If the run fails or is interrupted, what was recorded stays in
        ``record.partial_name(path)`` (attribute ``partial`` = 1); :class:`RunAborted` / :class:`RunInterrupted`
        carry ``record`` None and that ``partial_path``. A crash keeps everything up to the last chunk there."""
        from pathlib import Path

        if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
            raise RobofdiError(f"run_to_file: field 'chunk' must be an integer >= 1 (control ticks), got {chunk!r}")
        return self._simulate(duration, initial_state, seed, run_key, scenario, meta, progress, Path(path), int(chunk))

    def _simulate(self, duration, initial_state, seed, run_key, scenario, meta, progress, path, chunk, diagnose=True):
        if not (np.isfinite(duration) and duration > 0):
            raise RobofdiError(f"run: field 'duration' must be > 0 s, got {duration}")
        sim, rates = self.simulator, self.rates
        dt = 1.0 / rates.control_hz
        steps = int(round(duration / dt))
        inj = self._injector(stream(seed, run_key))
        oracle = self.health_source == ORACLE
        diagnoses = self.diagnoses if diagnose else {}
        bank = DiagnosisBank(diagnoses, rates, None if oracle or not diagnoses else self.health_source, chunk)
        accommodation = self.accommodation
        if hasattr(self.controller, "reset"):     # stateful parts start every run afresh
            self.controller.reset()
        if accommodation is not None:
            accommodation.reset()
        online = self.injection == "online"
        components = inj.has_component_faults
        # series that are the same objects every tick are kept once: u = u_cmd without accommodation, u_diag = u in
        # online injection (and offline without actuator faults), y_true = state when the simulator says so
        # (:func:`robofdi.protocols.output_is_state`)
        output_is_state = _output_is_state(sim)
        same = {key: source for key, source, alike in (("u", "u_cmd", accommodation is None),
                                                       ("u_diag", "u", online or not inj.has_actuator_faults),
                                                       ("y_true", "state", output_is_state)) if alike}
        rec = Recorder(("time", "state", "u_applied", "reference", "u_cmd", "u", "u_diag", "y_true", "y_meas"),
                       inj.label_names, chunk, same)
        fault_by_name = {f.name: f for f in self.faults}
        writer = None
        if path is not None:
            from robofdi import __version__
            from robofdi.record import RecordWriter
            from robofdi.seeding import check_seed

            if seed is not None:
                check_seed("run: field 'seed'", seed)
            writer = RecordWriter(path, {"system": sim.system, "scenario": scenario, "seed": seed,
                                         "rates": self.rates.as_dict(sim.physics_dt), "version": __version__,
                                         "meta": self._meta(duration, run_key, meta)})
            label_units = {f.name: _label_unit(f, sim) for f in self.faults if f.name in inj.label_names}
            traces = {}

        # a reference that can be read ahead (``sample(times)``: Quintic, Sequence) is sampled a block of ticks at a
        # time, the same numbers as calling it every tick; any other reference is called every tick. The read-ahead
        # rows are recorded a block at a time too (:func:`_ahead_block`: the rows the per-tick tuples would stack to)
        sample = getattr(self.reference, "sample", None)
        time_column, ref_column = rec.rows["time"], rec.rows["reference"]
        ahead, ahead_whole, ahead_kept = None, False, 0

        def sync_reference() -> None:
            """Put the read-ahead reference rows of the ticks recorded so far into the reference column."""
            nonlocal ahead_kept
            if ahead_whole:
                missing = len(time_column) - len(ref_column)
                if missing > 0:
                    ref_column.extend(_ahead_block(ahead, ahead_kept, ahead_kept + missing))
                    ahead_kept += missing

        def record() -> Record:
            sync_reference()
            return self._record(rec, bank, scenario, seed, run_key, duration, meta)

        def flush(rows=None) -> None:
            sync_reference()
            series, labels = rec.take(rows)
            reference = series.pop("reference")
            reference = _stack_references(reference)
            columns, units = self._layout(reference.shape[1] if reference.ndim == 2 else 0)
            names = {"state": "truth/state", "u_applied": "truth/u_applied"}
            out = {names.get(k, k if k == "time" else f"signals/{k}"): v for k, v in series.items()}
            out["signals/reference"] = reference
            if not traces:
                traces.update(bank.traces())
            writer.append(out, columns, units, {k: (a, v, label_units[k]) for k, (a, v) in labels.items()},
                          bank.take(), traces)

        # the hot loop: bound methods and the columns' own appenders, looked up once (the same calls and rows as
        # ``rec.append(...)`` every tick; the rows are converted a chunk at a time by ``rec.settle``)
        (add_time, add_state, add_ref, add_u_cmd, add_u, add_u_diag, add_y_true, add_y_meas,
         add_u_applied) = (rec.rows[k].appender if k in rec.rows else None for k in (
            "time", "state", "reference", "u_cmd", "u", "u_diag", "y_true", "y_meas", "u_applied"))
        add_labels = rec.label_appenders()
        sense, actuate, emulate, push = inj.sense, inj.actuate, inj.emulate, bank.push
        sensing, actuating = inj.has_sensor_faults, inj.has_actuator_faults   # else y and u pass through as they are
        diagnosing = bool(bank.runners)
        control, step, reference_at = self.controller.update, sim.step, self.reference
        try:
            y = sim.reset(initial_state, seed=stream(seed, run_key, "sensors"))
            u_prev_diag = np.zeros(len(sim.actuators))
            for j in range(steps + 1):
                t = j * dt
                if sample is not None:
                    k = j % chunk
                    if k == 0:
                        sync_reference()
                        ahead = sample([i * dt for i in range(j, min(j + chunk, steps + 1))])
                        ahead_whole, ahead_kept = _ahead_blockable(ahead), 0
                        ahead_q, ahead_v, ahead_a = ahead
                    ref = (ahead_q[k], ahead_v[k], ahead_a[k])
                else:
                    ref = reference_at(t)
                y_faulty = sense(t, y) if sensing else y
                if diagnosing:
                    push(j, t, y_faulty, u_prev_diag)
                if oracle:
                    health = Health(t, tuple(fault_by_name[n].target for n, (a, _) in inj.labels.items() if a),
                                    {fault_by_name[n].target: v for n, (a, v) in inj.labels.items() if a}, ORACLE)
                else:
                    health = bank.health
                u_cmd = control(y_faulty if online else y, ref)
                u = accommodation.update(u_cmd, health) if accommodation is not None else u_cmd
                if online:
                    u_plant, u_diag = actuate(t, u) if actuating else u, u
                    if components:
                        for kind, target, value in inj.components(t):
                            sim.apply_component_fault(kind, target, value)
                else:
                    u_plant, u_diag = u, emulate(t, u) if actuating else u
                state = sim.state
                y_true = state if output_is_state else sim.true_output
                add_time(t)
                add_state(state)
                if not ahead_whole:
                    add_ref(ref)
                add_u_cmd(u_cmd)
                if add_u is not None:
                    add_u(u)
                if add_u_diag is not None:
                    add_u_diag(u_diag)
                if add_y_true is not None:
                    add_y_true(y_true)
                add_y_meas(y_faulty)
                if add_labels:
                    labels = inj.labels
                    for name, add_active, add_value in add_labels:
                        active, value = labels[name]
                        add_active(bool(active))
                        add_value(float(value))
                u_prev_diag = u_diag
                if j < steps:
                    y = step(u_plant)
                    add_u_applied(sim.u_applied.copy())
                else:
                    add_u_applied(sim.saturate(u_plant))
                if (j + 1) % chunk == 0:
                    if writer is not None:
                        flush()
                    else:
                        sync_reference()
                        rec.settle()
                if progress is not None:
                    progress(1)
            if writer is not None:
                flush()
                return writer.close()
        except KeyboardInterrupt as exc:         # SIGINT or SIGTERM (robofdi.interrupts): stop, keep the record
            sync_reference()
            signum = signal_of(exc)
            message = f"run interrupted by {signal.Signals(signum).name} at t = {rec.last('time', 0.0):.3f} s"
            if writer is not None:
                err = RunInterrupted(message, None, signum)
                err.partial_path = self._abort_stream(writer, flush, rec)
                raise err from None
            raise RunInterrupted(message, _trim(record()), signum) from None
        except Exception as exc:
            sync_reference()
            message = f"run failed at t = {rec.last('time', 0.0):.3f} s: {exc}"
            if writer is not None:
                err = RunAborted(message, None)
                err.partial_path = self._abort_stream(writer, flush, rec)
                raise err from exc
            raise RunAborted(message, _trim(record())) from exc
        return record()

    @staticmethod
    def _abort_stream(writer, flush, rec: Recorder):
        """Write the rows every series reached, close the file as partial; its path (None if that failed too)."""
        try:
            flush(len(rec))
        except (Exception, KeyboardInterrupt):
            pass
        try:
            return writer.close(aborted=True)
        except (Exception, KeyboardInterrupt):
            return None

    def _meta(self, duration, run_key, meta) -> dict:
        return {"injection": self.injection, "duration": duration, "faults": [f.to_dict() for f in self.faults],
                "accommodation": type(self.accommodation).__name__ if self.accommodation is not None else None,
                "health_source": self.health_source, "run_key": run_key, **(meta or {})}

    def _layout(self, width: int) -> tuple[dict, dict]:
        """Columns and units of every control-rate dataset; ``width`` of the flattened reference."""
        sim = self.simulator
        u_cols, u_units = list(sim.actuators), list(sim.units.get("u", [""] * len(sim.actuators)))
        y_cols, y_units = list(sim.sensor_channels), list(sim.units.get("y", [""] * len(sim.sensor_channels)))
        ref_cols = list(self.reference_columns) if self.reference_columns else [f"reference[{i}]" for i in range(width)]
        columns = {"truth/state": list(sim.state_names), "truth/u_applied": u_cols, "signals/reference": ref_cols}
        units = {"truth/state": list(sim.units.get("state", [])), "truth/u_applied": u_units,
                 "signals/reference": list(self.reference_units or [""] * len(ref_cols))}
        for key in ("u_cmd", "u", "u_diag"):
            columns[f"signals/{key}"], units[f"signals/{key}"] = u_cols, u_units
        for key in ("y_true", "y_meas"):
            columns[f"signals/{key}"], units[f"signals/{key}"] = y_cols, y_units
        return columns, units

    def _record(self, rec: Recorder, bank: DiagnosisBank, scenario, seed, run_key, duration, meta) -> Record:
        sim = self.simulator
        column = rec.rows["reference"]
        try:
            reference = _stack_references(column.rows if column.is_list else column.array())
        except ValueError:                       # ragged rows (tuples of vectors of different lengths)
            reference = _stack_references(list(column))
        columns, units = self._layout(reference.shape[1])
        faults = {f.name: f for f in self.faults}
        n_u, n_y, n_x = len(sim.actuators), len(sim.sensor_channels), len(sim.state_names)
        return Record(
            system=sim.system,
            scenario=scenario,
            seed=seed,
            rates=self.rates.as_dict(sim.physics_dt),
            time=rec.array("time"),
            truth_state=rec.array("state", n_x),
            u_applied=rec.array("u_applied", n_u),
            faults=rec.fault_labels({k: _label_unit(faults[k], sim) for k in rec.labels}),
            signals={"reference": reference, "u_cmd": rec.array("u_cmd", n_u), "u": rec.array("u", n_u),
                     "u_diag": rec.array("u_diag", n_u), "y_true": rec.array("y_true", n_y),
                     "y_meas": rec.array("y_meas", n_y)},
            diagnosers=bank.traces(),
            meta=self._meta(duration, run_key, meta),
            columns=columns,
            units=units,
        )


def _trim(rec: Record) -> Record:
    """Cut every series of a partial record to the length that all of them reached."""
    n = min([len(rec.time), len(rec.truth_state), len(rec.u_applied)] + [len(v) for v in rec.signals.values()]
            + [len(lab.active) for lab in rec.faults.values()] + [len(lab.value) for lab in rec.faults.values()])
    rec.time, rec.truth_state, rec.u_applied = rec.time[:n], rec.truth_state[:n], rec.u_applied[:n]
    rec.signals = {k: v[:n] for k, v in rec.signals.items()}
    rec.faults = {k: FaultLabels(lab.active[:n], lab.value[:n], lab.unit) for k, lab in rec.faults.items()}
    rec.meta["aborted"] = True
    return rec
