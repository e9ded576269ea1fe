"""The nominal models' evaluations at one lockstep sample, shared by every batch diagnoser of the same runs.

The batch form of :mod:`robofdi.observers.evaluations`: N runs of one arm system, each with its own nominal model
(the robot instances differ), diagnosed together. At a sample every batch diagnoser is handed the same measurement
array Y (a, 2n) and input array U (a, n) of the a active runs, so they ask for M̂, ĝ, Ĉ and the forward dynamics at
the same array objects: a :class:`BatchEvaluations` remembers the last call of each by the identity of its
arguments and hands the same read-only (a, …) result to every batch diagnoser that asks again. Row i is run i's
model evaluated by the very Pinocchio call :class:`~robofdi.observers.evaluations.Evaluations` makes, so the same
bits as the run diagnosed alone.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.models.manipulator import ManipulatorModel

__all__ = ["BatchEvaluations", "batch_evaluations"]


def _unchanging(a: np.ndarray) -> np.ndarray | None:
    """``a`` when it is read-only (the engine's Y and U, views of them, this module's results): kept for the
    identity test; None for a writeable array, which is never a hit."""
    return None if a.flags.writeable else a


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class BatchEvaluations:
    """Memo of the last call of each of ``mass_matrix_at``, ``gravity_at``, ``coriolis_at`` and
    ``acceleration_at`` over the first a runs: X is the (a, 2n) states [q; q̇], U the (a, n) joint torques, and
    row i is ``models[i]``'s ``mass_matrix(q)``, ``gravity(q)``, ``coriolis(q, q̇)`` or ``acceleration(q, q̇, τ)``.

    A call with the same read-only argument objects as the last call of its method returns the same read-only
    result (arguments taken as unchanging: the engine hands fresh read-only arrays each sample)."""

    __slots__ = ("models", "_mass", "_gravity", "_coriolis", "_acceleration")

    # The four memos are written out one by one, as in Evaluations (a shared helper costs a closure a call).

    def __init__(self, models: Sequence[ManipulatorModel]):
        self.models = tuple(models)
        # (the argument objects when unchanging, the read-only result) of the last call of each
        self._mass = self._gravity = self._coriolis = self._acceleration = (None, None)

    def mass_matrix_at(self, X: np.ndarray) -> np.ndarray:
        """M̂ at the positions of each state, (a, n, n) [kg·m²]."""
        last = self._mass
        if last[0] is X:
            return last[1]
        n = X.shape[1] // 2
        M = np.empty((X.shape[0], n, n))
        for model, x, out in zip(self.models, X, M):
            out[:] = model.mass_matrix(x[:n])
        self._mass = (_unchanging(X), _frozen(M))
        return M

    def gravity_at(self, X: np.ndarray) -> np.ndarray:
        """ĝ at the positions of each state, (a, n) [N·m]."""
        last = self._gravity
        if last[0] is X:
            return last[1]
        n = X.shape[1] // 2
        g = np.empty((X.shape[0], n))
        for model, x, out in zip(self.models, X, g):
            out[:] = model.gravity(x[:n])
        self._gravity = (_unchanging(X), _frozen(g))
        return g

    def coriolis_at(self, X: np.ndarray) -> np.ndarray:
        """Ĉ at each state (Pinocchio's factorisation), (a, n, n)."""
        last = self._coriolis
        if last[0] is X:
            return last[1]
        n = X.shape[1] // 2
        C = np.empty((X.shape[0], n, n))
        for model, x, out in zip(self.models, X, C):
            out[:] = model.coriolis(x[:n], x[n:])
        self._coriolis = (_unchanging(X), _frozen(C))
        return C

    def acceleration_at(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """q̈ = M̂⁻¹(τ − n̂) at each state and torque, (a, n) [rad/s²]."""
        last = self._acceleration
        if last[0] is not None and last[0][0] is X and last[0][1] is U:
            return last[1]
        n = X.shape[1] // 2
        acc = np.empty((X.shape[0], n))
        for model, x, tau, out in zip(self.models, X, U, acc):
            out[:] = model.acceleration(x[:n], x[n:], tau)
        same = (X, U) if _unchanging(X) is not None and _unchanging(U) is not None else None
        self._acceleration = (same, _frozen(acc))
        return acc


_SHARED: dict[tuple[int, ...], BatchEvaluations] = {}     # ids of the models → their memo (which holds the models)
_KEEP = 4                                                  # memos kept: the batches of one lockstep engine and a few more


def batch_evaluations(models: Sequence[ManipulatorModel]) -> BatchEvaluations:
    """The one :class:`BatchEvaluations` of these model objects, in this order (made at the first call; only the
    last few are kept, the oldest forgotten)."""
    key = tuple(map(id, models))
    ev = _SHARED.get(key)
    if ev is None:
        while len(_SHARED) >= _KEEP:
            del _SHARED[next(iter(_SHARED))]
        ev = _SHARED[key] = BatchEvaluations(models)
    return ev
