"""Reading MCAP files defensively: bounded reads, so a damaged length field cannot allocate.

mcap's readers trust record length fields; one flipped bit there asked Python for exabytes
(MemoryError, issue 19). Every file BagReader opens goes through `open_bounded`.
"""
from __future__ import annotations

import os
from pathlib import Path


class _BoundedFile:
    """A read-only file whose reads never ask for more than the bytes left: an absurd length field
    (a flipped bit in a record header) becomes a short read that mcap reports, instead of a
    multi-gigabyte allocation (issue 19: MemoryError before this)."""

    def __init__(self, f):
        self._f = f
        self._size = os.fstat(f.fileno()).st_size

    def read(self, n: int = -1) -> bytes:
        left = max(0, self._size - self._f.tell())
        return self._f.read(left if n is None or n < 0 else min(n, left))

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._f.seek(offset, whence)

    def tell(self) -> int:
        return self._f.tell()

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True


def open_bounded(path: Path):
    """(raw file, bounded view) for mcap's readers."""
    f = open(path, "rb")
    return f, _BoundedFile(f)


def reader_pos(f) -> int:
    try:
        return int(f.tell())
    except (OSError, ValueError):
        return -1
