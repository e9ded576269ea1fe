"""Fault identification after isolation — Caccavale & Villani Sec. 6: before a fault is declared f̂ = 0; after,
the isolated components carry the diagnoser's estimate."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi import RobofdiError

__all__ = ["Identification"]


class Identification:
    """Gates a diagnoser's fault-magnitude candidates by the isolation result.

    components: names of the estimate entries (fault targets); modes: per entry "level" (the candidate is the
    magnitude itself) or "increment" (the candidate is the per-sample change of the fault, summed from the
    sample at which the fault was isolated, that sample included).
    """

    def __init__(self, components: Sequence[str], modes: Sequence[str]):
        if len(components) != len(modes):
            raise RobofdiError("Identification: 'components' and 'modes' must have the same length")
        bad = [m for m in modes if m not in ("level", "increment")]
        if bad:
            raise RobofdiError(f"Identification: field 'modes' entries must be 'level' or 'increment', got {bad}")
        self.components = list(components)
        self._increment = np.array([m == "increment" for m in modes])
        self._index = {c: i for i, c in enumerate(self.components)}
        self.reset()

    def reset(self) -> None:
        self._sum = np.zeros(len(self.components))
        self._on = np.zeros(len(self.components), dtype=bool)

    def update(self, candidates: np.ndarray, isolated: Sequence[str]) -> np.ndarray:
        for name in isolated:
            i = self._index.get(name)
            if i is not None:
                self._on[i] = True
        if not self._on.any():
            return np.zeros(len(self.components))
        self._sum = np.where(self._on & self._increment, self._sum + candidates, 0.0)
        return np.where(self._on, np.where(self._increment, self._sum, candidates), 0.0)

    def magnitudes(self, estimate: np.ndarray, isolated: Sequence[str]) -> dict[str, float]:
        """The identified magnitude of every isolated target (what a :class:`~robofdi.protocols.Health` carries)."""
        return {c: float(estimate[i]) for i, c in enumerate(self.components) if c in isolated}
