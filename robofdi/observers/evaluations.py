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


def _immutable(a) -> bool:
    """``a`` is a read-only array that owns its memory (:func:`~robofdi.observers.residual.shared_measurement`'s
    copies, this memo's results): taken as unchanging, so the very same object again is the same arguments."""
    return type(a) is np.ndarray and a.base is None and not a.flags.writeable


class Evaluations:
    """Memo of the last call of each of :class:`~robofdi.models.ManipulatorModel`'s ``mass_matrix``,
    ``gravity``, ``coriolis`` and ``acceleration``; results are read-only arrays (shared).

    Each memo is keyed by its arguments' bytes. The ``…_at(x)`` forms take the state x = [q; q̇] whole; when x
    (and τ) is a read-only array that owns its memory — the measurement every diagnoser of a sample is handed —
    the same object again is a hit without reading its bytes."""

    __slots__ = ("model", "_mass", "_gravity", "_coriolis", "_acceleration", "__weakref__")

    # The four memos are written out one by one: a shared helper taking the memo's name and a closure cost
    # ≈ 0.3 µs a call, ≈ 3 % of a tick with the seven arm schemes (benchmarks/arm_loop.py, measured).

    def __init__(self, model: ManipulatorModel):
        self.model = model
        # (the arguments' bytes, the read-only result, the argument objects when unchanging) of the last call of each
        self._mass = self._gravity = self._coriolis = self._acceleration = (None, None, None)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M̂(q) [kg·m²]."""
        return self._mass_matrix(q, None)

    def mass_matrix_at(self, x: np.ndarray) -> np.ndarray:
        """M̂ at the positions of the state x = [q; q̇]."""
        last = self._mass
        if last[2] is x:
            return last[1]
        return self._mass_matrix(x[:x.shape[0] // 2], x if _immutable(x) else None)

    def _mass_matrix(self, q, same) -> np.ndarray:
        key = _bytes(q)
        last = self._mass
        value = last[1] if last[0] == key else _frozen(self.model.mass_matrix(q))
        self._mass = (key, value, same)
        return value

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """ĝ(q) [N·m]."""
        return self._gravity_of(q, None)

    def gravity_at(self, x: np.ndarray) -> np.ndarray:
        """ĝ at the positions of the state x = [q; q̇]."""
        last = self._gravity
        if last[2] is x:
            return last[1]
        return self._gravity_of(x[:x.shape[0] // 2], x if _immutable(x) else None)

    def _gravity_of(self, q, same) -> np.ndarray:
        key = _bytes(q)
        last = self._gravity
        value = last[1] if last[0] == key else _frozen(self.model.gravity(q))
        self._gravity = (key, value, same)
        return value

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Ĉ(q, q̇) (Pinocchio's factorisation)."""
        return self._coriolis_of(q, v, _bytes(q) + _bytes(v), None)

    def coriolis_at(self, x: np.ndarray) -> np.ndarray:
        """Ĉ at the state x = [q; q̇] (the same memo: q and q̇'s bytes are x's)."""
        last = self._coriolis
        if last[2] is x:
            return last[1]
        n = x.shape[0] // 2
        return self._coriolis_of(x[:n], x[n:], _bytes(x), x if _immutable(x) else None)

    def _coriolis_of(self, q, v, key, same) -> np.ndarray:
        last = self._coriolis
        value = last[1] if last[0] == key else _frozen(self.model.coriolis(q, v))
        self._coriolis = (key, value, same)
        return value

    def acceleration_at(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """:meth:`acceleration` at the state x = [q; q̇] (the same memo: q and q̇'s bytes are x's)."""
        last = self._acceleration
        if last[2] is not None and last[2][0] is x and last[2][1] is tau:
            return last[1]
        n = x.shape[0] // 2
        same = (x, tau) if _immutable(x) and _immutable(tau) else None
        return self._acceleration_of(x[:n], x[n:], tau, _bytes(x) + _bytes(tau), same)

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q̈ = M̂⁻¹(τ − n̂) [rad/s²]."""
        return self._acceleration_of(q, v, tau, _bytes(q) + _bytes(v) + _bytes(tau), None)

    def _acceleration_of(self, q, v, tau, key, same) -> np.ndarray:
        last = self._acceleration
        value = last[1] if last[0] == key else _frozen(self.model.acceleration(q, v, tau))
        self._acceleration = (key, value, same)
        return value


_SHARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def evaluations(model: ManipulatorModel) -> Evaluations:
    """The one :class:`Evaluations` of ``model`` (made at the first call, forgotten with the model)."""
    ev = _SHARED.get(model)
    if ev is None:
        ev = _SHARED[model] = Evaluations(model)
    return ev
