"""The few interfaces everything plugs into (ARCHITECTURE.md, "The small set of interfaces").

Truth and belief never mix: a :class:`Simulator` is the truth; a :class:`Diagnoser` is built from the
simulator's ``nominal_model()`` (the belief) and sees only commands and measurements. :class:`robofdi.loop.ClosedLoop`
is the only place where the two meet::

    reference ─► Controller ─► u_cmd ─► Accommodation ─► u ─► actuator faults ─► Simulator.step (saturates,
         ▲                                   ▲                                    reports u_applied)
         │                                   └── Health (one diagnosis sample late, or the named oracle)
         └──── y_meas ◄── sensor faults ◄── Simulator measurement
                  └──► Diagnoser.update(y, u) ─► Residual ─► Decision.update ─► Alarms (+ identification)

Every name a simulator exposes (actuators, sensor channels, components, state columns) is a fault target or a
record column, and ``units`` gives the physical unit of each column, so the record and summary carry units.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["Simulator", "Controller", "Reference", "Accommodation", "Diagnoser", "Decision", "Identifier", "Health",
           "System", "TargetLimit", "Mission", "Parts", "returns_state", "output_is_state"]


def returns_state(getter):
    """Mark a simulator's ``true_output`` getter that returns ``self.state`` (the same numbers, nothing else done):
    a loop may then read the state once a tick and record y_true as its copy (:func:`output_is_state`)."""
    getter.returns_state = True
    return getter


def output_is_state(simulator) -> bool:
    """True when ``type(simulator).true_output`` is a property whose getter is marked by :func:`returns_state` (a
    subclass that overrides ``true_output`` is not, unless it marks its own getter)."""
    prop = getattr(type(simulator), "true_output", None)
    return isinstance(prop, property) and getattr(prop.fget, "returns_state", False) is True


@runtime_checkable
class Simulator(Protocol):
    """The plant (truth). One ``step`` advances one control period ``control_dt`` with u held (zero-order hold)."""

    system: str                          # label of the plant, e.g. the MJCF model name
    actuators: list[str]                 # names of the entries of u (actuator-fault targets)
    sensor_channels: list[str]           # names of the entries of y (sensor-fault targets)
    components: list[str]                # component-fault targets (e.g. "joint3", "payload")
    component_kinds: Mapping[str, Sequence[str]]   # component fault kind -> the targets it may act on
    state_names: list[str]               # names of the entries of ``state``
    units: Mapping[str, Sequence[str]]   # "state", "u", "y" -> unit of each entry
    control_dt: float                    # [s]
    physics_dt: float                    # [s], from the model file
    u_applied: np.ndarray                # what the plant really received in the last step (after saturation)
    state: np.ndarray                    # the true state now
    true_output: np.ndarray              # what the sensors would read now without noise (and without faults)

    def reset(self, initial_state: Any = None, seed: np.random.SeedSequence | int | None = None) -> np.ndarray:
        """Start a run (``initial_state`` None: the plant's own default); ``seed`` drives this run's sensor
        noise. Returns the first measurement y."""

    def step(self, u: np.ndarray) -> np.ndarray:
        """Apply u (saturated to the actuator limits) for one control period; return the measurement y."""

    def saturate(self, u: np.ndarray) -> np.ndarray:
        """What the actuators can deliver of the command u (the static part of ``step``'s saturation)."""

    def apply_component_fault(self, kind: str, target: str, value: float) -> None:
        """Change component ``target`` by ``value`` (in the kind's unit) from its nominal value; 0 restores it."""

    def nominal_model(self, mismatch: Any = None) -> Any:
        """The belief a diagnoser gets: built from the model file, never from this simulator's state."""


class Reference(Protocol):
    """A reference signal: ``reference(t)`` is an array or a tuple of arrays (e.g. q_d, q̇_d, q̈_d)."""

    def __call__(self, t: float) -> np.ndarray | tuple[np.ndarray, ...]: ...


class Controller(Protocol):
    """The nominal controller: measurement y and reference in, commanded input u_cmd out."""

    def update(self, y: np.ndarray, reference: Any) -> np.ndarray: ...


@dataclass(frozen=True)
class Health:
    """What the diagnosis believes about the plant at one diagnosis sample (or, for the oracle, the truth).

    ``isolated``: the fault hypotheses isolated so far (actuator / sensor / component names);
    ``estimate``: identified fault magnitude per isolated target, in the fault's own unit.
    """

    time: float = 0.0
    isolated: tuple[str, ...] = ()
    estimate: Mapping[str, float] = field(default_factory=dict)
    source: str = ""


HEALTHY = Health()


class Accommodation(Protocol):
    """Between controller and actuators: allocation, compensation, reconfiguration (identity when none)."""

    def reset(self) -> None: ...

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray: ...


@runtime_checkable
class Diagnoser(Protocol):
    """A residual generator stepped sample by sample: ``update(y, u)`` with y = x̄(k) measured now and u = ū(k−1),
    the input held over the interval that ended at sample k (no look-ahead).

    The contract (checked by :func:`robofdi.testing.check_diagnoser`): the output at sample k depends on samples
    0..k only; ``reset()`` then the same inputs give the same outputs; ``components`` / ``estimate_components``
    name the entries of ``Residual.r`` / ``Residual.estimate`` and ``units`` gives one unit string per entry;
    non-finite or mis-shaped ``y`` / ``u`` raise :class:`~robofdi.errors.RobofdiError` naming the field
    (:func:`robofdi.observers.check_measurement`); it holds nominal models only, never a simulator. The decision
    and the health are not the diagnoser's: :class:`robofdi.loop.DiagnosisRunner` produces them."""

    inputs: list[str]                    # names of the entries of u it expects (the simulator's actuators)
    measurements: list[str]              # names of the entries of y it expects (the simulator's sensor channels)
    components: list[str]                # names of the residual entries
    estimate_components: list[str]       # names of the identification candidates (fault targets)
    estimate_modes: list[str]            # per estimate entry: "level" or "increment"
    units: Mapping[str, Sequence[str]]   # "residual", "estimate" -> unit of each entry

    def reset(self) -> None: ...

    def update(self, y: np.ndarray, u: np.ndarray) -> Any: ...          # -> robofdi.observers.Residual

    def signatures(self) -> Sequence[Any]: ...                          # -> robofdi.decision.Signature


@runtime_checkable
class Decision(Protocol):
    """Residual evaluation: alarms per component and the isolated hypothesis."""

    threshold: np.ndarray

    def reset(self) -> None: ...

    def update(self, residual: np.ndarray) -> Any: ...                  # -> robofdi.decision.Alarms


@runtime_checkable
class Identifier(Protocol):
    """Fault identification after isolation: the diagnoser's candidates gated by the isolated hypotheses
    (:class:`robofdi.decision.Identification`, Caccavale & Villani Sec. 6), and the magnitudes a
    :class:`Health` carries."""

    components: list[str]                # names of the estimate entries (fault targets)

    def reset(self) -> None: ...

    def update(self, candidates: np.ndarray, isolated: Sequence[str]) -> np.ndarray: ...

    def magnitudes(self, estimate: np.ndarray, isolated: Sequence[str]) -> Mapping[str, float]: ...


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


@dataclass
class Parts:
    """One run's parts, built once by :meth:`System.build`: ``loop`` wires them — the plant (truth), the controller,
    the diagnoses (each diagnoser, built on the nominal model, with its decision) and the accommodation
    (:class:`robofdi.loop.ClosedLoop`, or an adapter's loop with the same ``run`` signature) — and the rest says
    how this run goes: ``duration`` [s], ``initial_state`` (None: the plant's default), ``seed``, ``run_key``,
    ``scenario`` label and record ``meta``. ``run()`` closes the loop → Record; inspect or change the parts first
    (e.g. add a diagnosis of your own to ``diagnoses``)."""

    loop: Any
    duration: float
    initial_state: Any = None
    seed: int = 0
    run_key: str = "campaign"
    scenario: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def simulator(self) -> Any:
        return getattr(self.loop, "simulator", None)

    @property
    def controller(self) -> Any:
        return getattr(self.loop, "controller", None)

    @property
    def diagnoses(self) -> Mapping[str, Any]:
        return getattr(self.loop, "diagnoses", {})

    @property
    def accommodation(self) -> Any:
        return getattr(self.loop, "accommodation", None)

    def run(self, progress=None, diagnose: bool = True) -> Any:
        """Simulate the run → :class:`robofdi.record.Record` (``progress``: called with the ticks done;
        ``diagnose=False``: without stepping the diagnoses, :meth:`robofdi.loop.ClosedLoop.run`)."""
        return self.loop.run(self.duration, self.initial_state, seed=self.seed, run_key=self.run_key,
                             scenario=self.scenario, meta=dict(self.meta or {}), progress=progress,
                             **({} if diagnose else {"diagnose": False}))


@runtime_checkable
class System(Protocol):
    """A plant family as experiments, campaigns and the command line use it (:mod:`robofdi.systems`).

    ``options_type``: the system's configuration, a validated frozen dataclass (a campaign spec's ``[system]``
    table). Every function is deterministic in its arguments: a run's result depends only on (options,
    calibration, calibration key, mission, faults, run seed), so the same seed gives the same record wherever it
    runs. Truth stays inside the parts ``build`` wires: the diagnosers get nominal models, commands and
    measurements.
    """

    name: str
    options_type: type

    def diagnosers(self, options) -> Sequence[str]:
        """Every diagnoser this system can run, best (or the one driving the accommodation) first. A system may
        also define ``default_diagnosers(options)``, the subset a campaign runs when its spec names none (the
        others are opt-in: run only when named), and ``calibration_notes(calibration)``, what a calibration
        identified that a user reads ({name with its unit: number}; campaign.json's
        ``execution.calibration.per_key[key]["identified"]`` and report.md)."""

    def targets(self, options) -> dict[str, dict[str, TargetLimit]]:
        """Fault targets and their limits: {"actuator": {name: limit}, "sensor": {...}, "component_<kind>": {...}}."""

    def calibration_keys(self, options) -> list:
        """One calibration per key (a robot instance's seed); runs cycle through the keys."""

    def calibrate(self, options, key, diagnosers) -> tuple[Any, bool]:
        """(calibration of ``diagnosers`` for robot ``key``, True if it came from :mod:`robofdi.calibration`'s cache)."""

    def mission(self, options, key, generator: np.random.Generator) -> Mission:
        """A mission drawn from ``generator`` (the campaign face)."""

    def build(self, options, calibration, key, mission: Mission, faults, seed: int, diagnosers) -> Parts:
        """The parts of one closed-loop run of ``mission`` with ``faults`` and every named diagnoser online, each
        built once (:class:`Parts`); nothing is simulated yet."""

    def run(self, options, calibration, key, mission: Mission, faults, seed: int, diagnosers) -> Any:
        """One closed-loop run → a Record: ``build(...).run()`` (:class:`robofdi.systems.RobotInstances` says so
        once for every system that derives from it)."""
