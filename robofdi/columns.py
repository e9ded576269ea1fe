"""Columns: the series of a run, appended row by row into preallocated blocks.

A run appends one row per tick to every series it records. Kept as a Python list of small arrays, a row of six
floats costs ≈ 130 bytes (the array object) instead of 48, and memory grows with every tick; a :class:`Column`
copies each row into a preallocated block of ``chunk`` rows, so a row costs its bytes and nothing else, and
:meth:`Column.take` hands the rows out chunk by chunk (for a record streamed to disk,
:class:`robofdi.record.RecordWriter`) so that memory stays bounded whatever the run length.

Rows of float64 or bool of one shape are blocked; anything else (strings, integers, ragged rows, tuples of
vectors of different lengths) is kept as a list, as before — the values and their order are what was appended,
so :meth:`Column.array` is bit-identical to ``np.asarray`` of the list of rows.
"""
from __future__ import annotations

import numpy as np

__all__ = ["Column", "CHUNK"]

#: Rows per block (and per chunk of a streamed record): 4096 ticks ≈ 4 s of a 1 kHz loop.
CHUNK = 4096

_FLOATS = (float, np.float64)
_BOOLS = (bool, np.bool_)


class Column:
    """One recorded series: :meth:`append` a row, :meth:`array` all rows, :meth:`take` the rows since the last take."""

    __slots__ = ("chunk", "_blocks", "_block", "_n", "_count", "_shape", "_kind", "_items")

    def __init__(self, chunk: int = CHUNK):
        self.chunk = int(chunk)
        self._blocks: list[np.ndarray] = []       # full blocks not yet taken
        self._block: np.ndarray | None = None     # the block being filled
        self._n = 0                               # rows in _block
        self._count = 0                           # rows in _blocks
        self._shape: tuple = ()
        self._kind = ""
        self._items: list | None = None           # the list fallback

    def __len__(self) -> int:
        return len(self._items) if self._items is not None else self._count + self._n

    @property
    def rows(self) -> list | None:
        """The rows of a list column (None for a blocked one)."""
        return self._items

    @property
    def is_list(self) -> bool:
        """True when the rows are kept as a list (not float64/bool rows of one shape)."""
        return self._items is not None

    def _start(self, value) -> bool:
        """Choose blocks (True) or the list (False) from the first row."""
        if isinstance(value, _BOOLS):
            self._kind, self._shape = "b", ()
        elif isinstance(value, _FLOATS):
            self._kind, self._shape = "f", ()
        else:
            try:
                a = np.asarray(value)
            except ValueError:                    # ragged
                a = None
            if a is None or a.dtype not in (np.float64, np.bool_):
                self._items = []
                return False
            self._kind, self._shape = a.dtype.kind, a.shape
        self._block = np.empty((self.chunk, *self._shape), dtype=bool if self._kind == "b" else float)
        return True

    def _fits(self, value) -> bool:
        if type(value) is np.ndarray:
            return value.shape == self._shape and value.dtype.kind == self._kind
        if self._shape == ():
            return isinstance(value, _BOOLS) if self._kind == "b" else isinstance(value, _FLOATS)
        try:
            a = np.asarray(value)
        except ValueError:
            return False
        return a.shape == self._shape and a.dtype.kind == self._kind

    def _to_list(self) -> None:
        rows = self.array()
        self._items = list(rows)
        self._blocks, self._block, self._n, self._count = [], None, 0, 0

    def append(self, value) -> None:
        """One row (copied: the caller may reuse its array)."""
        if self._items is not None:
            self._items.append(value)
            return
        block = self._block
        if block is None:
            if not self._start(value):
                self._items.append(value)
                return
            block = self._block
        if not self._fits(value):
            self._to_list()
            self._items.append(value)
            return
        if self._n == self.chunk:
            self._blocks.append(block)
            self._count += self._n
            block = self._block = np.empty_like(block)
            self._n = 0
        block[self._n] = value
        self._n += 1

    def __getitem__(self, i: int):
        if self._items is not None:
            return self._items[i]
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError("column index out of range")
        if i >= self._count:
            return self._block[i - self._count].copy()
        return self._blocks[i // self.chunk][i % self.chunk].copy()

    def array(self, dtype=None) -> np.ndarray:
        """Every row not yet taken, stacked: (N, *row shape); a list column as ``np.asarray(rows, dtype)``."""
        if self._items is not None:
            return np.asarray(self._items, dtype=dtype)
        if self._block is None:
            return np.asarray([], dtype=dtype if dtype is not None else float)
        parts = self._blocks + [self._block[: self._n]]
        out = np.concatenate(parts) if len(parts) > 1 else parts[0].copy()
        return out if dtype is None or out.dtype == dtype else out.astype(dtype)

    def __array__(self, dtype=None, copy=None):
        return self.array(dtype)

    def take(self):
        """The rows appended since the last take (an array; a list for a list column), and forget them. The array
        may be a view of a block that the next :meth:`append` overwrites: use it before appending again."""
        if self._items is not None:
            items, self._items = self._items, []
            return items
        if self._block is None:
            return np.zeros((0,), dtype=float)
        if self._blocks:
            out = np.concatenate(self._blocks + [self._block[: self._n]])
            self._blocks, self._count = [], 0
        else:
            out = self._block[: self._n]
        self._n = 0
        return out
