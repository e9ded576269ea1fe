"""Mission supervision for underwater vehicles — Antonelli's survey (book ch. 4), §3 and §3.4.

    PhaseFaultManager   the Theseus fault manager [17, 18]: a mission of phases, a phase that does not complete
                        within its time switches to the phase's safe behaviour (§3.4; the digest's [HARNESS]: a
                        phase/behaviour state machine with timeouts)
    Watchdog            the HW/SW failure of the failure catalogue (§3: "crash"): a task whose output stays the same
                        for longer than a timeout has stopped (the digest's emulation: outputs held)

Both are small stepping classes with one ``update``; they read only what the vehicle's software sees (events,
its own tasks' outputs), never the simulator's truth.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError

#: times within this of a timeout do not exceed it (tick times are sums of floats) [s]
TIME_TOLERANCE = 1e-9

__all__ = ["MissionPhase", "PhaseFaultManager", "Watchdog"]


@dataclass(frozen=True)
class MissionPhase:
    """One phase of a mission (a manoeuvre between waypoints): ``name``, the time it may take [s] and the behaviour
    to switch to when it does not complete in time (Theseus' homing phase: "stop under the ice and wait")."""

    name: str
    timeout: float
    safe_behaviour: str = "stop_and_wait"

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise RobofdiError(f"MissionPhase: field 'name' must be a non-empty string, got {self.name!r}")
        if isinstance(self.timeout, bool) or not isinstance(self.timeout, (int, float)) or not (
                np.isfinite(self.timeout) and self.timeout > 0):
            raise RobofdiError(f"MissionPhase {self.name!r}: field 'timeout' must be a time > 0 s, got {self.timeout!r}")
        if not isinstance(self.safe_behaviour, str) or not self.safe_behaviour:
            raise RobofdiError(f"MissionPhase {self.name!r}: field 'safe_behaviour' must be a non-empty string")


class PhaseFaultManager:
    """The Theseus fault manager (§3.4): phases run in order; ``update(t, complete)`` is told at each tick whether
    the current phase reported completion. A phase still incomplete ``timeout`` s after it began has failed: the
    manager switches to its safe behaviour and stays there (the vehicle waits to be recovered). Returns the active
    behaviour: the current phase's name, "mission_complete", or the failed phase's safe behaviour."""

    def __init__(self, phases: Sequence[MissionPhase]):
        self.phases = list(phases)
        if not self.phases or not all(isinstance(p, MissionPhase) for p in self.phases):
            raise RobofdiError("PhaseFaultManager: field 'phases' must be a non-empty list of MissionPhase")
        names = [p.name for p in self.phases]
        if len(set(names)) != len(names):
            raise RobofdiError(f"PhaseFaultManager: phase names must be unique, got {names}")
        self.reset()

    def reset(self) -> None:
        self.index, self.started, self.failed, self.failed_at = 0, None, None, None
        self.log: list[tuple[float, str]] = []

    @property
    def behaviour(self) -> str:
        if self.failed is not None:
            return self.failed.safe_behaviour
        return "mission_complete" if self.index >= len(self.phases) else self.phases[self.index].name

    def update(self, t: float, complete: bool) -> str:
        if self.failed is not None or self.index >= len(self.phases):
            return self.behaviour
        if self.started is None:
            self.started = float(t)
            self.log.append((self.started, self.phases[self.index].name))
        phase = self.phases[self.index]
        if complete:
            self.index += 1
            self.started = None if self.index >= len(self.phases) else float(t)
            if self.started is not None:
                self.log.append((self.started, self.phases[self.index].name))
        elif t - self.started > phase.timeout + TIME_TOLERANCE:
            self.failed, self.failed_at = phase, float(t)
            self.log.append((self.failed_at, phase.safe_behaviour))
        return self.behaviour


class Watchdog:
    """HW/SW failure detection (§3): ``update(t, output)`` with a task's latest output (e.g. the controller's thrust
    command, or a heartbeat counter); when it has not changed (bit for bit) for more than ``timeout`` s the task is
    declared stopped and the alarm latches until ``reset``. Returns the alarm. A healthy feedback task's output
    changes every tick with the measurement noise, so ``timeout`` can be a few ticks."""

    def __init__(self, timeout: float):
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not (np.isfinite(timeout) and timeout > 0):
            raise RobofdiError(f"Watchdog: field 'timeout' must be a time > 0 s, got {timeout!r}")
        self.timeout = float(timeout)
        self.reset()

    def reset(self) -> None:
        self._last, self._since, self.alarm, self.alarm_at = None, None, False, None

    def update(self, t: float, output) -> bool:
        if self.alarm:
            return True
        value = np.array(output, dtype=float, copy=True)
        if self._last is None or value.shape != self._last.shape or not np.array_equal(value, self._last):
            self._last, self._since = value, float(t)
        elif t - self._since > self.timeout + TIME_TOLERANCE:
            self.alarm, self.alarm_at = True, float(t)
        return self.alarm
