"""The :class:`FaultInjector`: applies a list of faults to actuator commands and sensor readings."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from robofdi import RobofdiError
from robofdi.faults.effects import Effect, make_effect
from robofdi.faults.fault import Fault

__all__ = ["FaultInjector"]


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
    """Turns nominal actuator commands ``u`` and sensor readings ``y`` into faulty ones, and labels the truth.

    Faults on the same channel are applied in list order, each on the output of the previous one.
    After every :meth:`actuate` / :meth:`sense` call, :attr:`labels` maps each fault name to
    ``(active, value)`` where ``value`` is the change that fault made to its target channel
    (faulty minus the value it received; 0.0 when inactive). Faults without a seed draw from
    ``SeedSequence([seed, index])``, so the same injector seed reproduces the same run.
    """

    def __init__(self, faults: Sequence[Fault], actuators: Sequence[str], sensors: Sequence[str],
                 seed: int | None = 0):
        self.actuators = _channel_names("actuators", actuators)
        self.sensors = _channel_names("sensors", sensors)
        if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool) or seed < 0):
            raise RobofdiError(f"FaultInjector: field 'seed' must be None or an integer >= 0, got {seed!r}")
        # seed None: fresh entropy, drawn once so reset() still replays the same randomness
        self.seed = seed
        root = np.random.SeedSequence(seed).entropy
        self.faults: tuple[Fault, ...] = tuple(faults)
        seen: set[str] = set()
        for f in self.faults:
            if not isinstance(f, Fault):
                raise RobofdiError(f"FaultInjector: field 'faults' must hold Fault objects, got {f!r}")
            if f.name in seen:
                raise RobofdiError(f"FaultInjector: duplicate fault name {f.name!r}")
            seen.add(f.name)
            allowed = self.actuators if f.family == "actuator" else self.sensors
            if f.target not in allowed:
                raise RobofdiError(
                    f"Fault {f.name!r}: unknown target {f.target!r}; expected one of {', '.join(allowed)}"
                    f" ({f.family}s)"
                )
        self._effects: list[tuple[Effect, int]] = []
        for i, f in enumerate(self.faults):
            ss = np.random.SeedSequence(f.seed) if f.seed is not None else np.random.SeedSequence([root, i])
            channels = self.actuators if f.family == "actuator" else self.sensors
            self._effects.append((make_effect(f, ss), channels.index(f.target)))
        self._by_family = {fam: [(e, ch) for e, ch in self._effects if e.fault.family == fam] for fam in ("actuator", "sensor")}
        self.labels: dict[str, tuple[bool, float]] = {}
        self.reset()

    @property
    def label_names(self) -> list[str]:
        """All fault names, in the order the faults were given."""
        return [f.name for f in self.faults]

    def reset(self) -> None:
        """Clear held values and histories, re-seed random generators, zero the labels."""
        for effect, _ in self._effects:
            effect.reset()
        self.labels = {f.name: (False, 0.0) for f in self.faults}

    def actuate(self, t: float, u: np.ndarray) -> np.ndarray:
        """Faulty copy of the actuator command ``u`` at time ``t`` (input is never modified)."""
        return self._apply("actuator", t, u, "u", len(self.actuators))

    def sense(self, t: float, y: np.ndarray) -> np.ndarray:
        """Faulty copy of the sensor reading ``y`` at time ``t`` (input is never modified)."""
        return self._apply("sensor", t, y, "y", len(self.sensors))

    def _apply(self, family: str, t: float, x, field_name: str, n: int) -> np.ndarray:
        if isinstance(t, bool) or not isinstance(t, (int, float, np.number)) or not math.isfinite(t):
            raise RobofdiError(f"FaultInjector: field 't' must be a finite number, got {t!r}")
        t = float(t)
        try:
            out = np.array(x, dtype=float)  # copy
        except (TypeError, ValueError):
            raise RobofdiError(f"FaultInjector: field '{field_name}' must be a numeric 1-D array, got {x!r}") from None
        if out.ndim != 1 or out.shape[0] != n:
            raise RobofdiError(
                f"FaultInjector: field '{field_name}' must be a 1-D array of length {n}, got shape {out.shape}"
            )
        if not math.isfinite(out.sum()):  # NaN and inf propagate through the sum: one reduction per call
            raise RobofdiError(f"FaultInjector: field '{field_name}' must be finite, got {out.tolist()}")
        for effect, ch in self._by_family[family]:
            f = effect.fault
            before = float(out[ch])
            effect.observe(t, before)
            if f.active(t):
                out[ch] = effect.apply(t, before)
                self.labels[f.name] = (True, float(out[ch]) - before)
            else:
                self.labels[f.name] = (False, 0.0)
        return out
