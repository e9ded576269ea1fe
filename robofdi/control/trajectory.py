"""Reference trajectories."""
from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from robofdi import RobofdiError

__all__ = ["Quintic", "Sequence"]


@dataclass(frozen=True)
class Quintic:
    """Fifth-order polynomial q0 → q0 + Δq in ``duration`` s with null initial/final velocity and acceleration;
    holds the final pose afterwards (the trajectory of Caccavale & Villani Sec. 7)."""

    q0: tuple
    dq: tuple
    duration: float
    start: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "q0", tuple(float(v) for v in self.q0))
        object.__setattr__(self, "dq", tuple(float(v) for v in self.dq))
        object.__setattr__(self, "_q0", np.array(self.q0))
        object.__setattr__(self, "_dq", np.array(self.dq))
        if len(self.q0) != len(self.dq):
            raise RobofdiError(f"Quintic: fields 'q0' and 'dq' must have the same length ({len(self.q0)} vs {len(self.dq)})")
        if not np.all(np.isfinite(self.q0 + self.dq)):
            raise RobofdiError("Quintic: fields 'q0' and 'dq' must be finite")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise RobofdiError(f"Quintic: field 'duration' must be > 0, got {self.duration}")

    @property
    def end(self) -> float:
        return self.start + self.duration

    @property
    def qf(self) -> np.ndarray:
        return np.add(self.q0, self.dq)

    @property
    def start_pose(self) -> np.ndarray:
        """q at the start [rad] (the pose to reset the arm to)."""
        return np.array(self.q0)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q_d, q̇_d, q̈_d) at time t."""
        s = min(max((t - self.start) / self.duration, 0.0), 1.0)
        d = self.duration
        p = 10 * s**3 - 15 * s**4 + 6 * s**5
        dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / d
        ddp = (60 * s - 180 * s**2 + 120 * s**3) / d**2
        dq = self._dq
        return self._q0 + p * dq, dp * dq, ddp * dq


@dataclass(frozen=True)
class Sequence:
    """Quintic segments one after the other (each starts where the previous ended)."""

    segments: tuple

    def __post_init__(self):
        if not self.segments:
            raise RobofdiError("Sequence: field 'segments' must not be empty")
        object.__setattr__(self, "_ends", [seg.end for seg in self.segments])   # not a field: repr and == unchanged

    @classmethod
    def through(cls, waypoints, durations, start: float = 0.0) -> Sequence:
        wps = [np.asarray(w, dtype=float) for w in waypoints]
        if len(durations) != len(wps) - 1:
            raise RobofdiError("Sequence.through: need one duration per segment (len(waypoints) - 1)")
        segs, t = [], start
        for a, b, d in zip(wps[:-1], wps[1:], durations):
            segs.append(Quintic(tuple(a), tuple(b - a), d, t))
            t += d
        return cls(tuple(segs))

    @property
    def end(self) -> float:
        return self.segments[-1].end

    @property
    def start(self) -> float:
        return self.segments[0].start

    @property
    def start_pose(self) -> np.ndarray:
        """q at the start [rad] (the pose to reset the arm to)."""
        return self.segments[0].start_pose

    @property
    def waypoints(self) -> np.ndarray:
        """(len(segments) + 1, n) poses [rad]: the start and the end of every segment."""
        return np.array([self.segments[0].q0] + [seg.qf for seg in self.segments])

    @property
    def durations(self) -> tuple:
        """Duration [s] of every segment."""
        return tuple(seg.duration for seg in self.segments)

    def __call__(self, t: float):
        # the first segment with t < its end (a bisection: a motion of thousands of segments costs no more a tick)
        k = bisect.bisect_right(self._ends, t)
        return self.segments[min(k, len(self.segments) - 1)](t)
