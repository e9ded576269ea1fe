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


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class Evaluations:
    """Memo of the last call of each of :class:`~robofdi.models.ManipulatorModel`'s ``mass_matrix``,
    ``gravity``, ``coriolis`` and ``acceleration``; results are read-only arrays (shared)."""

    __slots__ = ("model", "_last", "__weakref__")

    def __init__(self, model: ManipulatorModel):
        self.model = model
        self._last: dict[str, tuple[bytes, np.ndarray]] = {}

    def _get(self, what: str, compute, *args: np.ndarray) -> np.ndarray:
        key = b"".join([np.asarray(a, dtype=float).tobytes() for a in args])
        hit = self._last.get(what)
        if hit is not None and hit[0] == key:
            return hit[1]
        value = _frozen(np.array(compute(*args), dtype=float))
        self._last[what] = (key, value)
        return value

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M̂(q) [kg·m²]."""
        return self._get("mass_matrix", self.model.mass_matrix, q)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """ĝ(q) [N·m]."""
        return self._get("gravity", self.model.gravity, q)

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Ĉ(q, q̇) (Pinocchio's factorisation)."""
        return self._get("coriolis", self.model.coriolis, q, v)

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q̈ = M̂⁻¹(τ − n̂) [rad/s²]."""
        return self._get("acceleration", self.model.acceleration, q, v, tau)


_SHARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def evaluations(model: ManipulatorModel) -> Evaluations:
    """The one :class:`Evaluations` of ``model`` (made at the first call, forgotten with the model)."""
    ev = _SHARED.get(model)
    if ev is None:
        ev = _SHARED[model] = Evaluations(model)
    return ev
