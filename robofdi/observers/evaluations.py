"""The nominal model's evaluations at one diagnosis sample, shared by every diagnoser built on the same model.

The arm's diagnosers see the same measurement and input at a sample, so they evaluate the same M̂(q_k), ĝ(q_{k−1}),
Ĉ(q_{k−1}, q̇_{k−1}) and forward dynamics at x̄(k−1), ū(k−1): seven crba calls a sample for seven diagnosers. An
:class:`Evaluations` remembers the last arguments and result of each (keyed by the arguments' bytes, so a hit is
the same result bit for bit) and hands the same read-only array to every diagnoser that asks again.
"""
from __future__ import annotations

import weakref

import numpy as np

from robofdi.models.manipulator import ManipulatorModel

__all__ = ["Evaluations", "evaluations"]


def _frozen(a) -> np.ndarray:
    """``a`` as a read-only float array of its own: ``a`` itself when it is a float array that owns its memory (a
    fresh result: Pinocchio's are, checked), else a copy."""
    if not (type(a) is np.ndarray and a.dtype is _FLOAT and a.base is None and a.flags.owndata):
        a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


_FLOAT = np.dtype(float)


def _bytes(a) -> bytes:
    """The bytes of ``a`` as a float array (a float array's own bytes, without a conversion)."""
    return a.tobytes() if type(a) is np.ndarray and a.dtype is _FLOAT else np.asarray(a, dtype=float).tobytes()


class Evaluations:
    """Memo of the last call of each of :class:`~robofdi.models.ManipulatorModel`'s ``mass_matrix``,
    ``gravity``, ``coriolis`` and ``acceleration``; results are read-only arrays (shared)."""

    __slots__ = ("model", "_mass", "_gravity", "_coriolis", "_acceleration", "__weakref__")

    def __init__(self, model: ManipulatorModel):
        self.model = model
        # (the arguments' bytes, the read-only result) of the last call of each
        self._mass = self._gravity = self._coriolis = self._acceleration = (None, None)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M̂(q) [kg·m²]."""
        key = _bytes(q)
        last = self._mass
        if last[0] == key:
            return last[1]
        value = _frozen(self.model.mass_matrix(q))
        self._mass = (key, value)
        return value

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """ĝ(q) [N·m]."""
        key = _bytes(q)
        last = self._gravity
        if last[0] == key:
            return last[1]
        value = _frozen(self.model.gravity(q))
        self._gravity = (key, value)
        return value

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Ĉ(q, q̇) (Pinocchio's factorisation)."""
        key = _bytes(q) + _bytes(v)
        last = self._coriolis
        if last[0] == key:
            return last[1]
        value = _frozen(self.model.coriolis(q, v))
        self._coriolis = (key, value)
        return value

    def acceleration_at(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """:meth:`acceleration` at the state x = [q; q̇] (the same memo: q and q̇'s bytes are x's)."""
        key = _bytes(x) + _bytes(tau)
        last = self._acceleration
        if last[0] == key:
            return last[1]
        n = x.shape[0] // 2
        value = _frozen(self.model.acceleration(x[:n], x[n:], tau))
        self._acceleration = (key, value)
        return value

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q̈ = M̂⁻¹(τ − n̂) [rad/s²]."""
        key = _bytes(q) + _bytes(v) + _bytes(tau)
        last = self._acceleration
        if last[0] == key:
            return last[1]
        value = _frozen(self.model.acceleration(q, v, tau))
        self._acceleration = (key, value)
        return value


_SHARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def evaluations(model: ManipulatorModel) -> Evaluations:
    """The one :class:`Evaluations` of ``model`` (made at the first call, forgotten with the model)."""
    ev = _SHARED.get(model)
    if ev is None:
        ev = _SHARED[model] = Evaluations(model)
    return ev
