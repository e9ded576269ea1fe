"""The :class:`FaultInjector`: applies a list of faults to actuator commands, sensor readings and plant components."""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from robofdi.errors import RobofdiError, all_finite
from robofdi.faults.effects import Effect, make_effect
from robofdi.faults.fault import FAULT_KINDS, Fault, check_sampling
from robofdi.seeding import stream

__all__ = ["FaultInjector", "check_faults"]


def _channel_names(field_name: str, names: Sequence[str]) -> tuple[str, ...]:
    names = tuple(names)
    for n in names:
        if not isinstance(n, str) or not n:
            raise RobofdiError(f"FaultInjector: field '{field_name}' must hold non-empty strings, got {n!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise RobofdiError(f"FaultInjector: field '{field_name}' has duplicate name(s) {', '.join(dup)}")
    return names


class FaultInjector:
    """Turns nominal actuator commands ``u`` and sensor readings ``y`` into faulty ones, gives the component
    changes of the plant, and labels the truth.

    Faults on the same channel are applied in list order, each on the output of the previous one.
    After every :meth:`actuate` / :meth:`emulate` / :meth:`sense` / :meth:`components` call, :attr:`labels` maps each
    fault name to ``(active, value)``: ``value`` is the change the fault made to its target (0.0 when inactive).
    For actuator faults it is measured after the actuator saturation ``saturate`` (the simulator's), so a fault
    that a saturated motor cannot deliver is labelled with what the plant really received.

    Randomness: a fault with its own ``seed`` uses it; the others draw from ``stream(seed, "fault", name)``
    (:mod:`robofdi.seeding`), so each fault has an independent stream and the same seed replays the same run.
    """

    def __init__(self, faults: Sequence[Fault], actuators: Sequence[str], sensors: Sequence[str],
                 seed: int | np.random.SeedSequence | None = 0, *,
                 component_kinds: Mapping[str, Sequence[str]] | None = None,
                 saturate: Callable[[np.ndarray], np.ndarray] | None = None):
        self.actuators = _channel_names("actuators", actuators)
        self.sensors = _channel_names("sensors", sensors)
        self.component_kinds = {k: tuple(v) for k, v in (component_kinds or {}).items()}
        self.saturate = saturate
        if isinstance(seed, bool) or not (seed is None or isinstance(seed, np.random.SeedSequence)
                                          or (isinstance(seed, (int, np.integer)) and seed >= 0)):
            raise RobofdiError(f"FaultInjector: field 'seed' must be None, an integer >= 0 or a SeedSequence, got {seed!r}")
        # seed None: fresh entropy, drawn once so reset() still replays the same randomness
        root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.faults: tuple[Fault, ...] = tuple(faults)
        seen: set[str] = set()
        for f in self.faults:
            if not isinstance(f, Fault):
                raise RobofdiError(f"FaultInjector: field 'faults' must hold Fault objects, got {f!r}")
            if f.name in seen:
                raise RobofdiError(f"FaultInjector: duplicate fault name {f.name!r}")
            seen.add(f.name)
            allowed = self._targets(f)
            if f.target not in allowed:
                what = f"{f.family}s" if f.family != "component" else f"targets of {f.kind} on this plant"
                raise RobofdiError(
                    f"Fault {f.name!r}: unknown target {f.target!r}; expected one of {', '.join(allowed) or '(none)'} ({what})"
                )
        self._effects: list[tuple[Effect, int]] = []
        for f in self.faults:
            ss = np.random.SeedSequence(f.seed) if f.seed is not None else stream(root, "fault", f.name)
            index = self._targets(f).index(f.target)
            self._effects.append((make_effect(f, ss), index))
        self._by_family = {fam: [(e, ch) for e, ch in self._effects if e.fault.family == fam]
                           for fam in ("actuator", "sensor", "component")}
        self.labels: dict[str, tuple[bool, float]] = {}
        self.reset()

    def _targets(self, f: Fault) -> tuple[str, ...]:
        if f.family == "actuator":
            return self.actuators
        if f.family == "sensor":
            return self.sensors
        return self.component_kinds.get(f.kind, ())

    @property
    def label_names(self) -> list[str]:
        """All fault names, in the order the faults were given."""
        return [f.name for f in self.faults]

    def check_offline(self) -> None:
        """Raise unless every fault can be emulated exactly on a fault-free run (sensor faults, and actuator
        faults whose effect is invertible: additive, drift, partial loss of effectiveness)."""
        for f in self.faults:
            if f.family == "component" or (f.family == "actuator" and not FAULT_KINDS[f.kind].offline):
                exact = [k for k, v in FAULT_KINDS.items() if v.offline]
                raise RobofdiError(
                    f"Fault {f.name!r}: kind {f.kind!r} cannot be emulated offline exactly; offline injection takes "
                    f"sensor faults and {', '.join(exact)} (use injection='online')"
                )

    def reset(self) -> None:
        """Clear held values and histories, re-seed random generators, zero the labels."""
        for effect, _ in self._effects:
            effect.reset()
        self.labels = {f.name: (False, 0.0) for f in self.faults}

    def actuate(self, t: float, u: np.ndarray) -> np.ndarray:
        """Faulty copy of the actuator command ``u`` at time ``t`` (input is never modified; with no actuator
        fault, ``u`` itself is returned)."""
        if not self._by_family["actuator"]:
            return u
        out = self._vector(t, u, "u", len(self.actuators))
        sat = self.saturate
        for effect, ch in self._by_family["actuator"]:
            f = effect.fault
            before = float(out[ch])
            effect.observe(t, before)
            if not f.active(t):
                self.labels[f.name] = (False, 0.0)
                continue
            after = out[ch] = effect.apply(t, before)
            if sat is None:
                self.labels[f.name] = (True, after - before)
            else:
                applied = sat(out)[ch]
                out[ch] = before
                self.labels[f.name] = (True, float(applied - sat(out)[ch]))
                out[ch] = after
        return out

    def emulate(self, t: float, u: np.ndarray) -> np.ndarray:
        """Offline emulation (Caccavale & Villani Sec. 7): the input ū the diagnosers are told while the plant
        receives the fault-free u, chosen so that the actuator faults turn ū into u exactly. Labels: u − ū."""
        if not self._by_family["actuator"]:
            return u
        out = self._vector(t, u, "u", len(self.actuators))
        for effect, ch in reversed(self._by_family["actuator"]):
            f = effect.fault
            if f.active(t):
                after = float(out[ch])
                out[ch] = effect.inverse(t, after)
                self.labels[f.name] = (True, after - float(out[ch]))
            else:
                self.labels[f.name] = (False, 0.0)
        return out

    def sense(self, t: float, y: np.ndarray) -> np.ndarray:
        """Faulty copy of the sensor reading ``y`` at time ``t`` (input is never modified; with no sensor fault,
        ``y`` itself is returned)."""
        if not self._by_family["sensor"]:
            return y
        out = self._vector(t, y, "y", len(self.sensors))
        for effect, ch in self._by_family["sensor"]:
            f = effect.fault
            before = float(out[ch])
            effect.observe(t, before)
            if f.active(t):
                out[ch] = effect.apply(t, before)
                self.labels[f.name] = (True, float(out[ch]) - before)
            else:
                self.labels[f.name] = (False, 0.0)
        return out

    @property
    def has_component_faults(self) -> bool:
        return bool(self._by_family["component"])

    @property
    def has_actuator_faults(self) -> bool:
        """False when :meth:`actuate` and :meth:`emulate` return ``u`` itself (no actuator fault)."""
        return bool(self._by_family["actuator"])

    @property
    def has_sensor_faults(self) -> bool:
        """False when :meth:`sense` returns ``y`` itself (no sensor fault)."""
        return bool(self._by_family["sensor"])

    def components(self, t: float) -> list[tuple[str, str, float]]:
        """(kind, target, change from nominal) of every component fault at time t (0.0 while inactive)."""
        changes = []
        for effect, _ in self._by_family["component"]:
            f = effect.fault
            value = effect.apply(t, 0.0) if f.active(t) else 0.0
            self.labels[f.name] = (f.active(t), value)
            changes.append((f.kind, f.target, value))
        return changes

    @staticmethod
    def _vector(t, x, field_name: str, n: int) -> np.ndarray:
        if isinstance(t, bool) or not isinstance(t, (int, float, np.number)) or not math.isfinite(t):
            raise RobofdiError(f"FaultInjector: field 't' must be a finite number, got {t!r}")
        try:
            out = np.array(x, dtype=float)  # copy
        except (TypeError, ValueError):
            raise RobofdiError(f"FaultInjector: field '{field_name}' must be a numeric 1-D array, got {x!r}") from None
        if out.ndim != 1 or out.shape[0] != n:
            raise RobofdiError(
                f"FaultInjector: field '{field_name}' must be a 1-D array of length {n}, got shape {out.shape}"
            )
        if not all_finite(out):
            raise RobofdiError(f"FaultInjector: field '{field_name}' must be finite, got {out.tolist()}")
        return out


def check_faults(faults: Sequence[Fault], simulator=None, duration: float | None = None, injection: str = "online",
                 label: str = "Fault", control_hz: float | None = None) -> None:
    """Refuse, before anything runs, faults a run cannot carry — the one check every scenario, the loop and the
    command line use: an onset outside a run of ``duration`` s; faults the sampling at ``control_hz`` cannot
    represent or that contradict each other (:func:`robofdi.faults.fault.check_sampling`; ``control_hz`` defaults
    to the simulator's); with a ``simulator`` (its ``actuators``, ``sensor_channels`` and ``component_kinds``), an
    unknown target or a kind it cannot take (the injector's own checks); with ``injection`` "offline", a fault
    that needs the closed loop. ``label`` starts the onset message (e.g. "--fault" at the command line)."""
    faults = tuple(faults)
    for f in faults:
        if not isinstance(f, Fault):
            raise RobofdiError(f"{label}: expected Fault objects, got {f!r}")
        if duration is not None and f.onset >= duration:
            raise RobofdiError(f"{label} {f.name!r}: onset {f.onset:g} s is not inside the run (duration "
                               f"{duration:g} s)")
    if control_hz is None and simulator is not None and getattr(simulator, "control_dt", None):
        control_hz = 1.0 / simulator.control_dt
    if control_hz is not None:
        check_sampling(faults, control_hz)
    if simulator is not None:
        injector = FaultInjector(faults, simulator.actuators, simulator.sensor_channels, 0,
                                 component_kinds=simulator.component_kinds)
        if injection == "offline":
            injector.check_offline()
