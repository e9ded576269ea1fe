"""Fault identification after isolation — Caccavale & Villani Sec. 6: before a fault is declared f̂ = 0; after,
the isolated components carry the diagnoser's estimate."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi import RobofdiError
from robofdi.jit import kernel

__all__ = ["Identification"]


@kernel
def _gate(on, increment, total, candidates, out):
    """One sample of :meth:`Identification.update` for the entries that are on: ``total`` (the running sums of
    the increment entries, 0 elsewhere) in place, the gated estimate into ``out``."""
    for i in range(out.shape[0]):
        if on[i] and increment[i]:
            total[i] = total[i] + candidates[i]
        else:
            total[i] = 0.0
        if not on[i]:
            out[i] = 0.0
        elif increment[i]:
            out[i] = total[i]
        else:
            out[i] = candidates[i]


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
        self._any = False           # some entry is on (a Python flag: no array reduction per sample)

    @property
    def active(self) -> bool:
        """Some entry is on (an isolated fault named one): before that, :meth:`update` gives zeros."""
        return self._any

    def update(self, candidates: np.ndarray, isolated: Sequence[str]) -> np.ndarray:
        for name in isolated:
            i = self._index.get(name)
            if i is not None:
                self._on[i] = True
                self._any = True
        if not self._any:
            return np.zeros(len(self.components))
        candidates = np.asarray(candidates, dtype=float)
        if candidates.shape != self._sum.shape:
            raise RobofdiError(f"Identification: field 'candidates' must be {self._sum.size} values, got shape "
                               f"{candidates.shape}")
        out = np.empty(self._sum.size)
        _gate(self._on, self._increment, self._sum, candidates, out)
        return out

    def magnitudes(self, estimate: np.ndarray, isolated: Sequence[str]) -> dict[str, float]:
        """The identified magnitude of every isolated target (what a :class:`~robofdi.protocols.Health` carries)."""
        return {c: float(estimate[i]) for i, c in enumerate(self.components) if c in isolated}
