"""Columns: the series of a run, appended row by row into preallocated blocks.

A run appends one row per tick to every series it records. Kept as a Python list of small arrays, a row of six
floats costs ≈ 130 bytes (the array object) instead of 48, and memory grows with every tick; a :class:`Column`
converts its rows into one array block every ``chunk`` rows, so a row costs its bytes and nothing else, and
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

class Column:
    """One recorded series: :meth:`append` a row, :meth:`array` all rows, :meth:`take` the rows since the last take.

    A row is appended to a list (as cheap as a list append); every ``chunk`` rows the list is converted at once
    (``np.asarray``, what stacking the whole list at the end would do) into a block when its rows are float64 or
    bool of one shape, and the small row objects are dropped. Other rows stay a list."""

    __slots__ = ("chunk", "_blocks", "_items", "_count", "_listed")

    def __init__(self, chunk: int = CHUNK):
        self.chunk = int(chunk)
        self._blocks: list[np.ndarray] = []       # converted chunks not yet taken
        self._items: list = []                    # rows since the last conversion
        self._count = 0                           # rows in _blocks
        self._listed = False                      # rows that do not convert: kept as a list for good

    def __len__(self) -> int:
        return self._count + len(self._items)

    @property
    def is_list(self) -> bool:
        """True when the rows are kept as a list (not float64/bool rows of one shape)."""
        return self._listed

    @property
    def rows(self) -> list | None:
        """The rows of a list column (None for a blocked one)."""
        return self._items if self._listed else None

    def append(self, value) -> None:
        """One row (kept as given until its chunk is converted, which copies it: do not change it in place)."""
        items = self._items
        items.append(value)
        if len(items) >= self.chunk and not self._listed:
            self._convert()

    @property
    def appender(self):
        """The pending rows' own ``list.append``, valid for the column's life (that list is only ever changed in
        place): a hot loop appends one row with it, without :meth:`append`'s call and test, and calls
        :meth:`settle` every ``chunk`` rows so that the rows are still converted chunk by chunk."""
        return self._items.append

    def settle(self) -> None:
        """Convert the pending rows into a block once there are ``chunk`` of them (what :meth:`append` does)."""
        if len(self._items) >= self.chunk and not self._listed:
            self._convert()

    def extend(self, block: np.ndarray) -> None:
        """Append the rows of ``block`` (one row per entry of its first axis): the same column as appending
        ``block[0]``, ``block[1]``, … one by one. A float64 or bool array is kept as one block when no rows are
        pending and its rows have the shape and dtype of the column's blocks; anything else is appended row by row.
        The block is kept, not copied: do not change it afterwards."""
        if (not self._items and not self._listed and isinstance(block, np.ndarray) and block.ndim >= 1
                and block.dtype in (np.float64, np.bool_)
                and (not self._blocks or (self._blocks[0].shape[1:] == block.shape[1:]
                                          and self._blocks[0].dtype == block.dtype))):
            if len(block):
                self._blocks.append(block)
                self._count += len(block)
            return
        for row in block:
            self.append(row)

    def _convert(self) -> None:
        items = self._items
        try:
            block = np.asarray(items)
        except ValueError:                        # ragged rows
            block = None
        ok = (block is not None and block.dtype in (np.float64, np.bool_)
              and (not self._blocks or self._blocks[0].shape[1:] == block.shape[1:]))
        if not ok:
            self._to_list()
            return
        self._blocks.append(block)
        self._count += len(items)
        items.clear()                             # in place: an :attr:`appender` stays valid

    def _to_list(self) -> None:
        rows = [row for block in self._blocks for row in block]
        self._items[:0] = rows
        self._blocks, self._count, self._listed = [], 0, True

    def __getitem__(self, i: int):
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError("column index out of range")
        if i >= self._count:
            return self._items[i - self._count]
        for block in self._blocks:                # blocks of ``chunk`` rows, or of any length (:meth:`extend`)
            if i < len(block):
                return block[i].copy()
            i -= len(block)
        raise IndexError("column index out of range")

    def array(self, dtype=None) -> np.ndarray:
        """Every row not yet taken, stacked (N rows of the row shape), as ``np.asarray(rows, dtype)`` of the rows."""
        if not self._blocks:
            return np.asarray(self._items, dtype=dtype)
        parts = list(self._blocks)
        if self._items:
            tail = np.asarray(self._items)
            if tail.shape[1:] != parts[0].shape[1:] or tail.dtype not in (np.float64, np.bool_):
                return np.asarray([row for block in self._blocks for row in block] + self._items, dtype=dtype)
            parts.append(tail)
        out = np.concatenate(parts) if len(parts) > 1 else parts[0]
        return out if dtype is None or out.dtype == dtype else out.astype(dtype)

    def __array__(self, dtype=None, copy=None):
        return self.array(dtype)

    def take(self):
        """The rows appended since the last take (an array; a list for a list column), and forget them."""
        if self._listed:
            items = self._items[:]
            self._items.clear()                   # in place: an :attr:`appender` stays valid
            return items
        if not (self._blocks or self._items):
            return np.zeros((0,), dtype=float)
        try:
            out = self.array()
        except ValueError:                        # ragged rows not yet converted: as a list
            out = list(self)
        self._blocks, self._count = [], 0
        self._items.clear()
        return out
