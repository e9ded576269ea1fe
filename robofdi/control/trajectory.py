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

    def _profile(self, t: float) -> tuple[float, float, float]:
        """(p, ṗ, p̈) of the normalised quintic at time t (scalars: the one formula of __call__ and sample)."""
        s = min(max((t - self.start) / self.duration, 0.0), 1.0)
        d = self.duration
        p = 10 * s**3 - 15 * s**4 + 6 * s**5
        dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / d
        ddp = (60 * s - 180 * s**2 + 120 * s**3) / d**2
        return p, dp, ddp

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q_d, q̇_d, q̈_d) at time t."""
        p, dp, ddp = self._profile(t)
        dq = self._dq
        return self._q0 + p * dq, dp * dq, ddp * dq

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q_d, q̇_d, q̈_d) at every time of ``times``, each (len(times), n): row k equals ``self(times[k])`` bit
        for bit (the same scalar profile, the same elementwise products) — a loop reads its reference ahead."""
        return _sample([self] * len(times), times)


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

    def _segment(self, t: float) -> Quintic:
        # the first segment with t < its end (a bisection: a motion of thousands of segments costs no more a tick)
        k = bisect.bisect_right(self._ends, t)
        return self.segments[min(k, len(self.segments) - 1)]

    def __call__(self, t: float):
        return self._segment(t)(t)

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q_d, q̇_d, q̈_d) at every time of ``times`` (:meth:`Quintic.sample`; row k equals ``self(times[k])``)."""
        return _sample([self._segment(t) for t in times], times)


def _sample(segments, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows q0 + p Δq, ṗ Δq, p̈ Δq of each time's segment: the scalar profile per time, the products vectorised
    (elementwise, so each row is what the segment's __call__ returns)."""
    times = [float(t) for t in times]
    profile = np.array([seg._profile(t) for seg, t in zip(segments, times)], dtype=float).reshape(len(times), 3)
    q0 = np.array([seg._q0 for seg in segments], dtype=float).reshape(len(times), -1)
    dq = np.array([seg._dq for seg in segments], dtype=float).reshape(len(times), -1)
    return q0 + profile[:, :1] * dq, profile[:, 1:2] * dq, profile[:, 2:] * dq
