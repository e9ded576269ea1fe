"""Named, independent random streams from one seed.

Every stochastic source of a run (the plant's ripple phases, the nominal-model errors, each sensor's noise,
each fault, each calibration run) draws from its own stream. A stream is a :class:`numpy.random.SeedSequence`
whose ``spawn_key`` is derived from the source's name path, exactly as ``SeedSequence.spawn`` derives child
keys from an index — but keyed by name, so adding a source never shifts the streams of the others::

    stream(7, "plant", "ripple")        # the robot's ripple phases for seed 7
    stream(7, "run", "sensor", "joint3_vel")
    rng(7, "calibration", "low_velocity", "sensor")

The same (seed, names) always gives the same stream; different names give statistically independent streams.
"""
from __future__ import annotations

import zlib

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["stream", "rng", "MAX_SEED", "check_seed"]

#: The largest seed: a record stores its seed as a signed 64-bit HDF5 attribute.
MAX_SEED = 2**63 - 1


def check_seed(where: str, seed) -> int:
    """``seed`` as an int, or a RobofdiError naming ``where``: an integer in [0, MAX_SEED]."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
        raise RobofdiError(f"{where} must be an integer in [0, 2^63 - 1] (a record stores it as a 64-bit integer), "
                           f"got {seed!r}")
    return int(seed)


def _key(name: str) -> int:
    if not isinstance(name, str) or not name:
        raise RobofdiError(f"seed stream: names must be non-empty strings, got {name!r}")
    return zlib.crc32(name.encode("utf-8"))


def _root(seed) -> np.random.SeedSequence:
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if seed is None:
        return np.random.SeedSequence()
    return np.random.SeedSequence(check_seed("seed", seed))


def stream(seed, *names: str) -> np.random.SeedSequence:
    """The stream of the source ``names`` under ``seed`` (an int, a SeedSequence, or None for fresh entropy)."""
    root = _root(seed)
    return np.random.SeedSequence(root.entropy, spawn_key=tuple(root.spawn_key) + tuple(_key(n) for n in names),
                                  pool_size=root.pool_size)


def rng(seed, *names: str) -> np.random.Generator:
    """A generator on :func:`stream` ``(seed, *names)``."""
    return np.random.default_rng(stream(seed, *names))
