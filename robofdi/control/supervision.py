"""Mission supervision for underwater vehicles — Antonelli's survey (book ch. 4), §3 and §3.4.

    PhaseFaultManager   the Theseus fault manager [17, 18]: a mission of phases, a phase that does not complete
                        within its time switches to the phase's safe behaviour (§3.4; the digest's [HARNESS]: a
                        phase/behaviour state machine with timeouts)
    Watchdog            the HW/SW failure of the failure catalogue (§3: "crash"): a task whose output stays the same
                        for longer than a timeout has stopped (the digest's emulation: outputs held)

    SupervisedController  the accommodation of both alarms (the safe manoeuvre): a failed phase makes the vehicle
                        fly the phase's safe behaviour ("stop under the ice and wait": hold the pose it has); a
                        stopped controller task is replaced by its redundant backup (§3, "redundancy [6]"), which
                        flies the watchdog's safe behaviour (surface, or stop and wait)

All are small stepping classes with one ``update``; they read only what the vehicle's software sees (events,
its own tasks' outputs, the navigation measurements), never the simulator's truth.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError

#: times within this of a timeout do not exceed it (tick times are sums of floats) [s]
TIME_TOLERANCE = 1e-9

__all__ = ["MissionPhase", "PhaseFaultManager", "Watchdog", "SupervisedController", "SAFE_BEHAVIOURS"]

#: The safe manoeuvres :class:`SupervisedController` can fly: hold the pose measured at the switch ("stop under the
#: ice and wait", Theseus §3.4), rise to the surface depth keeping x, y and yaw, or command zero thrust.
SAFE_BEHAVIOURS = ("stop_and_wait", "surface", "stop_thrusters")


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


class SupervisedController:
    """The safe manoeuvre on the supervision alarms (book ch. 4 §3 and §3.4), at the controller's place in the
    loop (``update(y, reference)`` → thrust command).

    ``primary``: the mission controller task, whose output the ``watchdog`` watches; ``backup``: the redundant
    task (a second controller on the same nominal model, §3's "redundancy [6]") that takes over when the watchdog
    alarms and flies ``on_watchdog``; ``phases`` with ``phase_complete(phase, t, y) → bool`` (the vehicle's own
    completion events, from the measurements): when a phase fails, the primary flies the phase's safe behaviour
    instead of the mission. Behaviours (:data:`SAFE_BEHAVIOURS`): "stop_and_wait" holds the pose measured at the
    switch (roll = pitch = 0, zero velocity); "surface" rises at ``ascent_speed`` [m/s] to ``surface_depth`` [m]
    keeping x, y and yaw, then holds; "stop_thrusters" commands zero. ``dt`` [s]: the control period (the task
    counts its ticks). ``mode`` is "mission" or the behaviour flown; ``log`` lists (t [s], event).
    """

    def __init__(self, primary, dt: float, backup=None, watchdog: Watchdog | None = None,
                 phases: PhaseFaultManager | None = None,
                 phase_complete: Callable[[str, float, np.ndarray], bool] | None = None,
                 on_watchdog: str = "surface", surface_depth: float = 1.0, ascent_speed: float = 0.2):
        where = "SupervisedController"
        if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (np.isfinite(dt) and dt > 0):
            raise RobofdiError(f"{where}: field 'dt' must be a time > 0 s, got {dt!r}")
        if on_watchdog not in SAFE_BEHAVIOURS:
            raise RobofdiError(f"{where}: field 'on_watchdog' must be one of {SAFE_BEHAVIOURS}, got {on_watchdog!r}")
        if watchdog is not None and backup is None and on_watchdog != "stop_thrusters":
            raise RobofdiError(f"{where}: a watchdog needs a 'backup' controller to fly {on_watchdog!r} (the primary "
                               "task has stopped), or on_watchdog='stop_thrusters'")
        if (phases is None) != (phase_complete is None):
            raise RobofdiError(f"{where}: fields 'phases' and 'phase_complete' go together")
        if phases is not None:
            bad = [p.safe_behaviour for p in phases.phases if p.safe_behaviour not in SAFE_BEHAVIOURS]
            if bad:
                raise RobofdiError(f"{where}: phase safe behaviour {bad[0]!r} is not one of {SAFE_BEHAVIOURS}")
        for name, v in (("surface_depth", surface_depth), ("ascent_speed", ascent_speed)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"{where}: field {name!r} must be > 0, got {v!r}")
        self.primary, self.backup, self.dt = primary, backup, float(dt)
        self.watchdog, self.phases, self.phase_complete = watchdog, phases, phase_complete
        self.on_watchdog, self.surface_depth, self.ascent_speed = on_watchdog, float(surface_depth), float(ascent_speed)
        self.reset()

    def reset(self) -> None:
        for part in (self.primary, self.backup, self.watchdog, self.phases):
            if part is not None and hasattr(part, "reset"):
                part.reset()
        self._k, self.mode, self._hold, self._since, self._backup_active = 0, "mission", None, None, False
        self.log: list[tuple[float, str]] = []

    def _switch(self, t: float, behaviour: str, y: np.ndarray, why: str) -> None:
        from robofdi.control.auv import navigation_pose

        eta, _ = navigation_pose(y)
        self._hold = np.array([eta[0], eta[1], eta[2], 0.0, 0.0, eta[5]])
        self.mode, self._since = behaviour, t
        self.log.append((t, f"{why} -> {behaviour}"))

    def _safe_reference(self, t: float):
        eta = self._hold.copy()
        deta = np.zeros(6)
        if self.mode == "surface":
            top = -self.surface_depth
            rise = self.ascent_speed * (t - self._since)
            if eta[2] + rise < top:
                eta[2] += rise
                deta[2] = self.ascent_speed
            else:
                eta[2] = max(eta[2], top)
        return eta, deta, np.zeros(6)

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        """One tick: the primary runs every tick (on the mission, or on the safe reference once a phase failed);
        an alarm raised at this tick takes effect from the next one."""
        t = self._k * self.dt
        self._k += 1
        safe = self.mode not in ("mission", "stop_thrusters")
        u_primary = np.asarray(self.primary.update(y, self._safe_reference(t) if safe and not self._backup_active
                                                   else reference), dtype=float)
        out = u_primary
        if self._backup_active:
            out = np.asarray(self.backup.update(y, self._safe_reference(t)), dtype=float) if safe else out
        if self.mode == "stop_thrusters":
            out = np.zeros_like(u_primary)
        if self.watchdog is not None and not self._backup_active and self.watchdog.update(t, u_primary):
            self._backup_active = True
            self._switch(t, self.on_watchdog, y, "watchdog: controller task stopped")
        if self.phases is not None and self.mode == "mission":
            behaviour = self.phases.update(t, bool(self.phase_complete(self.phases.behaviour, t, y)))
            if self.phases.failed is not None:
                self._switch(t, behaviour, y, f"phase {self.phases.failed.name!r} failed")
        return out
