"""Sensor noise draws shared by the plants: one independent, named stream per measurement channel."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.seeding import stream

__all__ = ["ChannelNoise"]


class ChannelNoise:
    """Standard normal draws, one independent stream per channel, buffered: each stream fills its column of a
    (block, channels) buffer, and :meth:`draw` hands out one contiguous row per measurement."""

    def __init__(self, run: np.random.SeedSequence, channels: Sequence[str], block: int = 512):
        self._gens = [np.random.default_rng(stream(run, "sensor", c)) for c in channels]
        self._block, self._k = block, block
        self._buffer = np.empty((block, len(channels)))

    def draw(self) -> np.ndarray:
        if self._k == self._block:
            for i, g in enumerate(self._gens):
                self._buffer[:, i] = g.standard_normal(self._block)
            self._k = 0
        self._k += 1
        return self._buffer[self._k - 1]
