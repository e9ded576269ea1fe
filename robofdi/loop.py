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
The same :class:`DiagnosisRunner` steps a diagnoser online here and offline over a record (:func:`diagnose_record`).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robofdi.decision import Identification, ThresholdDecision
from robofdi.errors import RobofdiError
from robofdi.faults import FAULT_KINDS, Fault, FaultInjector
from robofdi.protocols import HEALTHY, Accommodation, Controller, Health, Reference, Simulator
from robofdi.record import DiagnoserTrace, FaultLabels, Record
from robofdi.seeding import stream

__all__ = ["Rates", "Diagnosis", "DiagnosisRunner", "ClosedLoop", "RunAborted", "diagnose_record", "diagnoser_inputs",
           "ORACLE"]

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
    """A diagnoser (:class:`robofdi.protocols.Diagnoser`) and, optionally, its decision."""

    diagnoser: Any
    decision: ThresholdDecision | None = None


class RunAborted(RuntimeError):
    """A run failed part-way; ``record`` holds everything recorded up to the failure, ``partial_path`` where it
    was saved (set by :func:`robofdi.evaluate.run_folder.keep_partial`)."""

    def __init__(self, message: str, record: Record):
        super().__init__(message)
        self.record = record
        self.partial_path = None


class DiagnosisRunner:
    """Steps one diagnosis at the diagnosis rate from control-rate samples, keeps its trace and its health."""

    def __init__(self, diagnosis: Diagnosis, rates: Rates, name: str = ""):
        self.diagnosis, self.rates, self.name = diagnosis, rates, name
        d = diagnosis.diagnoser
        self.identification = Identification(d.estimate_components, d.estimate_modes)
        self.reset()

    def reset(self) -> None:
        d = self.diagnosis
        d.diagnoser.reset()
        if d.decision is not None:
            d.decision.reset()
        self.identification.reset()
        self.health = HEALTHY
        self._inputs: list[np.ndarray] = []
        self._rows: dict[str, list] = {k: [] for k in ("time", "residual", "alarm", "isolated", "estimate")}

    def push(self, j: int, t: float, y: np.ndarray, u_prev: np.ndarray) -> bool:
        """Control tick j at time t: y measured now, u_prev the input held over the tick that just ended
        (zeros at the first tick, which only initialises the diagnoser). True when a diagnosis sample was taken."""
        self._inputs.append(u_prev)
        if j % self.rates.ratio:
            return False
        u = sum(self._inputs) / len(self._inputs) if self.rates.input_hold == "mean" else self._inputs[0]
        self._inputs = []
        res = self.diagnosis.diagnoser.update(y, u)
        decision = self.diagnosis.decision
        if decision is not None:
            alarms = decision.update(res.r)
            alarm, isolated = alarms.alarm, alarms.isolated
        else:
            alarm, isolated = np.zeros(res.r.size, dtype=bool), ()
        estimate = self.identification.update(res.estimate, isolated)
        rows = self._rows
        rows["time"].append(t)
        rows["residual"].append(res.r)
        rows["alarm"].append(alarm)
        rows["isolated"].append("+".join(isolated))
        rows["estimate"].append(estimate)
        if isolated:
            components = self.identification.components
            self.health = Health(t, tuple(isolated), {c: float(estimate[i]) for i, c in enumerate(components)
                                                      if c in isolated}, self.name)
        return True

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
            units={k: list(v) for k, v in getattr(d.diagnoser, "units", {}).items()},
        )


def diagnose_record(record: Record, diagnosis: Diagnosis, rates: Rates | None = None, progress=None) -> DiagnoserTrace:
    """Run a diagnosis offline over a record's diagnoser view: signals ``y_meas`` (the measurement after
    sensor faults) and ``u_diag`` (the input the diagnosers are told). ``progress(k)`` is told every 1000 ticks."""
    rates = rates or Rates(**{k: record.rates[k] for k in ("control_hz", "diagnosis_hz", "input_hold")})
    runner = DiagnosisRunner(diagnosis, rates)
    y, u = record.signals["y_meas"], record.signals["u_diag"]
    for j, t in enumerate(record.time):
        runner.push(j, float(t), y[j], u[j - 1] if j else np.zeros_like(u[0]))
        if progress is not None and j % 1000 == 999:
            progress(1000)
    if progress is not None:
        progress(len(record.time) % 1000)
    return runner.trace()


def diagnoser_inputs(record: Record, rates: Rates | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The (y, u) pairs a diagnoser receives when :func:`diagnose_record` replays ``record``: (N, ny)
    measurements and (N, nu) inputs ū(k−1), one row per diagnosis sample — for designs that learn from
    fault-free runs sample by sample."""
    class _Tap:
        inputs, measurements, components, estimate_components, estimate_modes = [], [], ["tap"], ["tap"], ["level"]

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


def _stack_references(refs: list) -> np.ndarray:
    """(N, k) array of the references recorded as they came (arrays, or tuples of arrays such as (q, q̇, q̈))."""
    if not refs:
        return np.zeros((0, 0))
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
            for attr, names in (("inputs", sim.actuators), ("measurements", sim.sensor_channels)):
                expected = getattr(d.diagnoser, attr, None)
                if expected is not None and list(expected) != list(names):
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
    ) -> Record:
        """Simulate ``duration`` seconds from ``initial_state`` (None: the plant's default); return the record.

        ``seed`` drives everything random in this run through independent streams (:mod:`robofdi.seeding`):
        the sensors' noise (``stream(seed, run_key, "sensors")``) and each fault (``stream(seed, run_key,
        "faults")``). Runs with different ``run_key`` (e.g. calibration runs and test runs) never share noise.
        If anything fails part-way, :class:`RunAborted` carries the record of what was done so far.
        """
        if not (np.isfinite(duration) and duration > 0):
            raise RobofdiError(f"run: field 'duration' must be > 0 s, got {duration}")
        sim, rates = self.simulator, self.rates
        dt = 1.0 / rates.control_hz
        steps = int(round(duration / dt))
        inj = self._injector(stream(seed, run_key))
        runners = {name: DiagnosisRunner(d, rates, name) for name, d in self.diagnoses.items()}
        health_runner = runners.get(self.health_source)
        oracle = self.health_source == ORACLE
        accommodation = self.accommodation
        for part in (self.controller, accommodation):     # stateful parts start every run afresh
            if hasattr(part, "reset"):
                part.reset()
        online = self.injection == "online"
        components = inj.has_component_faults
        keys = ("time", "state", "u_applied", "reference", "u_cmd", "u", "u_diag", "y_true", "y_meas")
        rows: dict[str, list] = {k: [] for k in keys}
        labels: dict[str, tuple[list, list]] = {name: ([], []) for name in inj.label_names}
        fault_by_name = {f.name: f for f in self.faults}

        def record() -> Record:
            return self._record(rows, labels, runners, scenario, seed, run_key, duration, meta)

        health = pending = HEALTHY
        try:
            y = sim.reset(initial_state, seed=stream(seed, run_key, "sensors"))
            u_prev_diag = np.zeros(len(sim.actuators))
            for j in range(steps + 1):
                t = j * dt
                y_faulty = inj.sense(t, y)
                sampled = False
                for runner in runners.values():
                    sampled |= runner.push(j, t, y_faulty, u_prev_diag)
                if sampled:      # health moves on one diagnosis sample late: no algebraic loop
                    health = pending
                    if health_runner is not None:
                        pending = health_runner.health
                if oracle:
                    health = Health(t, tuple(fault_by_name[n].target for n, (a, _) in inj.labels.items() if a),
                                    {fault_by_name[n].target: v for n, (a, v) in inj.labels.items() if a}, ORACLE)
                ref = self.reference(t)
                u_cmd = self.controller.update(y_faulty if online else y, ref)
                u = accommodation.update(u_cmd, health) if accommodation is not None else u_cmd
                if online:
                    u_plant, u_diag = inj.actuate(t, u), u
                    if components:
                        for kind, target, value in inj.components(t):
                            sim.apply_component_fault(kind, target, value)
                else:
                    u_plant, u_diag = u, inj.emulate(t, u)
                rows["time"].append(t)
                rows["state"].append(sim.state)
                rows["reference"].append(ref)
                rows["u_cmd"].append(u_cmd)
                rows["u"].append(u)
                rows["u_diag"].append(u_diag)
                rows["y_true"].append(sim.true_output)
                rows["y_meas"].append(y_faulty)
                for name, (active, value) in inj.labels.items():
                    labels[name][0].append(active)
                    labels[name][1].append(value)
                u_prev_diag = u_diag
                if j < steps:
                    y = sim.step(u_plant)
                    rows["u_applied"].append(sim.u_applied.copy())
                else:
                    rows["u_applied"].append(sim.saturate(u_plant))
                if progress is not None:
                    progress(1)
        except KeyboardInterrupt:
            t_stop = rows["time"][-1] if rows["time"] else 0.0
            raise RunAborted(f"run interrupted at t = {t_stop:.3f} s", _trim(record())) from None
        except Exception as exc:
            t_fail = rows["time"][-1] if rows["time"] else 0.0
            raise RunAborted(f"run failed at t = {t_fail:.3f} s: {exc}", _trim(record())) from exc
        return record()

    def _record(self, rows, labels, runners, scenario, seed, run_key, duration, meta) -> Record:
        sim = self.simulator
        u_cols, u_units = list(sim.actuators), list(sim.units.get("u", [""] * len(sim.actuators)))
        y_cols, y_units = list(sim.sensor_channels), list(sim.units.get("y", [""] * len(sim.sensor_channels)))
        reference = _stack_references(rows["reference"])
        width = reference.shape[1]
        ref_cols = list(self.reference_columns) if self.reference_columns else [f"reference[{i}]" for i in range(width)]
        columns = {"truth/state": list(sim.state_names), "truth/u_applied": u_cols, "signals/reference": ref_cols}
        units = {"truth/state": list(sim.units.get("state", [])), "truth/u_applied": u_units,
                 "signals/reference": list(self.reference_units or [""] * len(ref_cols))}
        for key in ("u_cmd", "u", "u_diag"):
            columns[f"signals/{key}"], units[f"signals/{key}"] = u_cols, u_units
        for key in ("y_true", "y_meas"):
            columns[f"signals/{key}"], units[f"signals/{key}"] = y_cols, y_units
        faults = {f.name: f for f in self.faults}
        n_u, n_y, n_x = len(u_cols), len(y_cols), len(sim.state_names)

        def array(key, width):
            return np.asarray(rows[key], dtype=float).reshape(-1, width)

        return Record(
            system=sim.system,
            scenario=scenario,
            seed=seed,
            rates=self.rates.as_dict(sim.physics_dt),
            time=np.asarray(rows["time"], dtype=float),
            truth_state=array("state", n_x),
            u_applied=array("u_applied", n_u),
            faults={k: FaultLabels(np.asarray(a, dtype=bool), np.asarray(v, dtype=float), _label_unit(faults[k], sim))
                    for k, (a, v) in labels.items()},
            signals={"reference": reference, "u_cmd": array("u_cmd", n_u), "u": array("u", n_u),
                     "u_diag": array("u_diag", n_u), "y_true": array("y_true", n_y), "y_meas": array("y_meas", n_y)},
            diagnosers={name: r.trace() for name, r in runners.items()},
            meta={"injection": self.injection, "duration": duration, "faults": [f.to_dict() for f in self.faults],
                  "accommodation": type(self.accommodation).__name__ if self.accommodation is not None else None,
                  "health_source": self.health_source, "run_key": run_key, **(meta or {})},
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
