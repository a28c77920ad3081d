"""A ring of rows: the last ``capacity`` rows of fixed width in one preallocated float array.

The analysis keeps the newest samples of a segment for its sliding-window fits. A Python
list of tuples trimmed from the front cost a memmove of the whole list per sample and about
400 bytes per row, and turning it into an array for every result cost 13 to 20 ms at 20 000
rows. The ring costs one row assignment per sample, a fixed 8 bytes per value, and one copy
per :meth:`RowRing.array`. Pure numpy.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ['RowRing']


class RowRing:
    """The last ``capacity`` rows appended, oldest first (see module doc).

    The width is fixed by the first row; a row of another width is refused.

    Parameters
    ----------
    capacity : int
        Rows kept (older ones are overwritten).
    empty_width : int
        Width reported by :meth:`array` before the first row.
    """

    def __init__(self, capacity: int, empty_width: int = 5):
        if int(capacity) < 1:
            raise ValueError(f'capacity must be >= 1 row, got {capacity!r}')
        self.capacity = int(capacity)
        self.empty_width = int(empty_width)
        self._buf: np.ndarray | None = None
        self.appended = 0

    def __len__(self) -> int:
        return min(self.appended, self.capacity)

    def append(self, row: Sequence[float]) -> None:
        """Store one row (overwrites the oldest once full)."""
        if self._buf is None:
            self._buf = np.empty((self.capacity, len(row)), dtype=float)
        elif len(row) != self._buf.shape[1]:
            raise ValueError(f'row of {len(row)} values in a ring of width '
                             f'{self._buf.shape[1]}')
        self._buf[self.appended % self.capacity] = row
        self.appended += 1

    def array(self) -> np.ndarray:
        """Return a copy of the rows, oldest first (shape ``(len(self), width)``)."""
        if self._buf is None:
            return np.empty((0, self.empty_width))
        n, i = len(self), self.appended % self.capacity
        if n < self.capacity:
            return self._buf[:n].copy()
        return np.concatenate((self._buf[i:], self._buf[:i]))

    @property
    def nbytes(self) -> int:
        """Bytes held by the ring's array (fixed once the first row came)."""
        return 0 if self._buf is None else int(self._buf.nbytes)
