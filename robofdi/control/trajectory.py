"""Reference trajectories."""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from robofdi import RobofdiError
from robofdi.jit import kernel

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
        return _sample(self._q0[None], self._dq[None], np.array([self.start]), np.array([self.duration]),
                       np.zeros(len(times), dtype=np.int64), times)


@dataclass(frozen=True)
class Sequence:
    """Quintic segments one after the other (each starts where the previous ended)."""

    segments: tuple

    def __post_init__(self):
        if not self.segments:
            raise RobofdiError("Sequence: field 'segments' must not be empty")
        object.__setattr__(self, "_ends", [seg.end for seg in self.segments])   # not a field: repr and == unchanged
        for name, values in (("_q0s", [seg._q0 for seg in self.segments]), ("_dqs", [seg._dq for seg in self.segments]),
                             ("_starts", [seg.start for seg in self.segments]),
                             ("_durations", [seg.duration for seg in self.segments])):
            object.__setattr__(self, name, np.array(values, dtype=float))          # the segments stacked (sample)

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
        times = np.asarray(times, dtype=float).reshape(-1)
        # _segment's bisection for every time at once (searchsorted "right" is bisect_right)
        index = np.minimum(np.searchsorted(self._ends, times, side="right"), len(self.segments) - 1)
        return _sample(self._q0s, self._dqs, self._starts, self._durations, index.astype(np.int64), times)


#: the exponents of the quintic profile, handed to the kernel as data: a literal 2.0 would be compiled into s·s,
#: while Python's ``s**2`` calls the C library's pow (the last bit differs for some s)
_POWERS = np.array([2.0, 3.0, 4.0, 5.0])


@kernel
def _profiles(times, index, starts, durations, powers, out):
    """(p, ṗ, p̈) of :meth:`Quintic._profile` at every time (segment ``index[k]``) into ``out`` (len, 3): the same
    operations in the same order, ``pow`` for ``**`` (bit for bit)."""
    for k in range(times.shape[0]):
        i = index[k]
        d = durations[i]
        x = (times[k] - starts[i]) / d
        x = 0.0 if 0.0 > x else x              # max(x, 0.0)
        s = 1.0 if 1.0 < x else x              # min(x, 1.0)
        s2, s3 = math.pow(s, powers[0]), math.pow(s, powers[1])
        s4, s5 = math.pow(s, powers[2]), math.pow(s, powers[3])
        out[k, 0] = 10.0 * s3 - 15.0 * s4 + 6.0 * s5
        out[k, 1] = (30.0 * s2 - 60.0 * s3 + 30.0 * s4) / d
        out[k, 2] = (60.0 * s - 180.0 * s2 + 120.0 * s3) / math.pow(d, powers[0])


def _sample(q0s, dqs, starts, durations, index, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows q0 + p Δq, ṗ Δq, p̈ Δq of each time's segment (``index`` into the stacked segments): the scalar
    profile per time (a kernel), the products vectorised (elementwise, so each row is what the segment's
    __call__ returns)."""
    times = np.asarray(times, dtype=float).reshape(-1)
    profile = np.empty((times.size, 3))
    _profiles(times, index, starts, durations, _POWERS, profile)
    q0, dq = q0s[index], dqs[index]
    return q0 + profile[:, :1] * dq, profile[:, 1:2] * dq, profile[:, 2:] * dq
