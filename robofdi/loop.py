"""The closed-loop runner: where the simulator (truth) and the diagnosers (belief) meet.

One control tick j at time t_j = j / control_hz::

    y_j ─► sensor faults ─► ȳ_j ─► controller (online) ─► u_cmd_j ─► actuator faults ─► u_j ─► plant (ZOH)
                             └──► diagnosers every control_hz/diagnosis_hz ticks, with ū = the commands held
                                  over the diagnosis interval that just ended (mean, or first, of them)

``injection="online"``: faults act in the loop (the plant gets the faulty torque, the controller sees the
faulty measurement). ``injection="offline"``: the run is fault-free and only the diagnosers' view is
corrupted — the emulation of Caccavale & Villani Sec. 7 — with an actuator fault δu seen as
ū = u − δu, so that u = ū + δu as in eq. (14).

The same :class:`DiagnosisRunner` steps a diagnoser online here and offline over a record
(:func:`diagnose_record`), so both give the same residuals.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from robofdi import RobofdiError
from robofdi.decision import Identification, ThresholdDecision
from robofdi.faults import FaultInjector
from robofdi.record import DiagnoserTrace, FaultLabels, Record

__all__ = ["Rates", "Diagnosis", "DiagnosisRunner", "ClosedLoop", "RunAborted", "diagnose_record"]


@dataclass(frozen=True)
class Rates:
    """Control and diagnosis rates [Hz]; the physics rate is the simulator's. ``input_hold``: how ū of a
    diagnosis interval is formed from the control commands in it ("mean" or "first")."""

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
    """A diagnoser (anything with ``update(y, u) -> Residual``, ``components``, ``estimate_components``,
    ``estimate_modes``) and, optionally, its decision."""

    diagnoser: object
    decision: ThresholdDecision | None = None


class RunAborted(RuntimeError):
    """A run failed part-way; ``record`` holds everything recorded up to the failure."""

    def __init__(self, message: str, record: Record):
        super().__init__(message)
        self.record = record


class DiagnosisRunner:
    """Steps one diagnosis at the diagnosis rate from control-rate samples and keeps its trace."""

    def __init__(self, diagnosis: Diagnosis, rates: Rates):
        self.diagnosis, self.rates = diagnosis, rates
        d = diagnosis.diagnoser
        self.identification = Identification(d.estimate_components, d.estimate_modes)
        self.reset()

    def reset(self) -> None:
        d = self.diagnosis
        d.diagnoser.reset()
        if d.decision is not None:
            d.decision.reset()
        self.identification.reset()
        self._inputs: list[np.ndarray] = []
        self._rows: dict[str, list] = {k: [] for k in ("time", "residual", "alarm", "isolated", "estimate")}

    def push(self, j: int, t: float, y: np.ndarray, u_prev: np.ndarray) -> None:
        """Control tick j at time t: y measured now, u_prev the command held over the tick that just ended
        (zeros at the first tick, which only initialises the diagnoser)."""
        self._inputs.append(u_prev)
        if j % self.rates.ratio:
            return
        u = sum(self._inputs) / len(self._inputs) if self.rates.input_hold == "mean" else self._inputs[0]
        self._inputs = []
        res = self.diagnosis.diagnoser.update(y, u)
        decision = self.diagnosis.decision
        if decision is not None:
            alarms = decision.update(res.r)
            alarm, isolated = alarms.alarm, alarms.isolated
        else:
            alarm, isolated = np.zeros(res.r.size, dtype=bool), ()
        rows = self._rows
        rows["time"].append(t)
        rows["residual"].append(res.r)
        rows["alarm"].append(alarm)
        rows["isolated"].append("+".join(isolated))
        rows["estimate"].append(self.identification.update(res.estimate, isolated))

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
            estimate=np.asarray(rows["estimate"], dtype=float).reshape(-1, e),
            components=list(d.diagnoser.components),
            estimate_components=list(d.diagnoser.estimate_components),
        )


def diagnose_record(record: Record, diagnosis: Diagnosis, rates: Rates | None = None) -> DiagnoserTrace:
    """Run a diagnosis offline over a record's diagnoser view: signals ``y_meas`` (the measurement after
    sensor faults) and ``u_diag`` (the input the diagnosers are told)."""
    rates = rates or Rates(**{k: record.rates[k] for k in ("control_hz", "diagnosis_hz", "input_hold")})
    runner = DiagnosisRunner(diagnosis, rates)
    y, u = record.signals["y_meas"], record.signals["u_diag"]
    for j, t in enumerate(record.time):
        runner.push(j, float(t), y[j], u[j - 1] if j else np.zeros_like(u[0]))
    return runner.trace()


@dataclass
class ClosedLoop:
    """Wires simulator, reference, controller, fault injector and diagnoses for one scenario."""

    simulator: object
    controller: object
    reference: Callable[[float], tuple]
    injector: FaultInjector
    diagnoses: Mapping[str, Diagnosis] = field(default_factory=dict)
    rates: Rates = field(default_factory=Rates)
    injection: str = "online"

    def __post_init__(self):
        if self.injection not in ("online", "offline"):
            raise RobofdiError(f"ClosedLoop: field 'injection' must be 'online' or 'offline', got {self.injection!r}")
        joints = getattr(self.simulator, "joint_names", None)
        owners = [("controller", self.controller)] + [(f"diagnoser {k!r}", d.diagnoser) for k, d in self.diagnoses.items()]
        for owner, part in owners:
            model = getattr(part, "model", None)
            if joints is not None and hasattr(model, "check_joints"):
                try:
                    model.check_joints(joints)
                except RobofdiError as exc:
                    raise RobofdiError(f"ClosedLoop: {owner}: {exc}") from None
        sim_dt = getattr(self.simulator, "control_dt", None)
        if sim_dt is not None and abs(sim_dt * self.rates.control_hz - 1.0) > 1e-9:
            raise RobofdiError(
                f"ClosedLoop: rates.control_hz={self.rates.control_hz} does not match the simulator's control_dt={sim_dt}"
            )

    def run(
        self,
        duration: float,
        q0: np.ndarray,
        *,
        system: str = "",
        scenario: str = "",
        seed: int | None = None,
        meta: dict | None = None,
        progress: Callable[[int], None] | None = None,
    ) -> Record:
        """Simulate ``duration`` seconds from rest at q0; return the labelled record.

        If anything fails part-way, :class:`RunAborted` carries the record of what was done so far.
        """
        if not (np.isfinite(duration) and duration > 0):
            raise RobofdiError(f"run: field 'duration' must be > 0 s, got {duration}")
        dt = 1.0 / self.rates.control_hz
        steps = int(round(duration / dt))
        sim, inj = self.simulator, self.injector
        runners = {name: DiagnosisRunner(d, self.rates) for name, d in self.diagnoses.items()}
        inj.reset()
        rows: dict[str, list] = {k: [] for k in ("time", "state", "u_cmd", "u", "y_true", "y_meas", "u_diag", "q_ref")}
        labels: dict[str, tuple[list, list]] = {name: ([], []) for name in inj.label_names}

        def record() -> Record:
            return Record(
                system=system,
                scenario=scenario,
                seed=seed,
                rates=self.rates.as_dict(getattr(sim, "physics_dt", None)),
                time=np.asarray(rows["time"], dtype=float),
                truth_state=np.asarray(rows["state"], dtype=float),
                faults={k: FaultLabels(np.asarray(a, dtype=bool), np.asarray(v, dtype=float)) for k, (a, v) in labels.items()},
                signals={k: np.asarray(rows[k], dtype=float) for k in rows if k not in ("time", "state")},
                diagnosers={name: r.trace() for name, r in runners.items()},
                meta={"injection": self.injection, "duration": duration, **(meta or {})},
            )

        try:
            y = sim.reset(q0, seed=seed)
            u_prev_diag = np.zeros(len(sim.actuators))
            for j in range(steps + 1):
                t = j * dt
                y_faulty = inj.sense(t, y)
                y_ctrl = y_faulty if self.injection == "online" else y
                for runner in runners.values():
                    runner.push(j, t, y_faulty, u_prev_diag)
                ref = self.reference(t)
                u_cmd = self.controller.update(y_ctrl, ref)
                u_faulty = inj.actuate(t, u_cmd)
                if self.injection == "online":
                    u_plant, u_diag = u_faulty, u_cmd
                else:
                    u_plant, u_diag = u_cmd, 2.0 * u_cmd - u_faulty
                rows["time"].append(t)
                rows["state"].append(sim.state)
                rows["u_cmd"].append(u_cmd)
                rows["u"].append(u_plant)
                rows["y_true"].append(y)
                rows["y_meas"].append(y_faulty)
                rows["u_diag"].append(u_diag)
                rows["q_ref"].append(ref[0])
                for name, (active, value) in inj.labels.items():
                    labels[name][0].append(active)
                    labels[name][1].append(value)
                u_prev_diag = u_diag
                if j < steps:
                    y = sim.step(u_plant)
                if progress is not None:
                    progress(1)
        except KeyboardInterrupt:
            t_stop = rows["time"][-1] if rows["time"] else 0.0
            raise RunAborted(f"run interrupted at t = {t_stop:.3f} s", _trim(record())) from None
        except Exception as exc:
            t_fail = rows["time"][-1] if rows["time"] else 0.0
            raise RunAborted(f"run failed at t = {t_fail:.3f} s: {exc}", _trim(record())) from exc
        return record()


def _trim(rec: Record) -> Record:
    """Cut every series of a partial record to the length that all of them reached."""
    n = min([len(rec.time), len(rec.truth_state)] + [len(v) for v in rec.signals.values()]
            + [len(l.active) for l in rec.faults.values()] + [len(l.value) for l in rec.faults.values()])
    rec.time, rec.truth_state = rec.time[:n], rec.truth_state[:n]
    rec.signals = {k: v[:n] for k, v in rec.signals.items()}
    rec.faults = {k: FaultLabels(l.active[:n], l.value[:n]) for k, l in rec.faults.items()}
    rec.meta["aborted"] = True
    return rec
