"""Dynamic index-range scheduling with exactly-once bookkeeping.

Attempts depend only on (seed, index), so any worker can run any index. The scheduler hands out
contiguous ranges of the lowest pending indices, sized by guided self-scheduling (a share of what
is left, shrinking towards the end, so the last ranges finish together), takes back the unfinished
part of a range whose worker died, and records each index once. With target_successes, the run
ends at the same index a serial run would: the first k where indices first..k are all done and hold
target successes; indices above k are dropped, so the result is deterministic.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class IndexRange:
    first: int
    end: int  # exclusive

    def __len__(self) -> int:
        return self.end - self.first

    def __iter__(self):
        return iter(range(self.first, self.end))


class DuplicateIndexError(RuntimeError):
    """An index reported twice: a scheduler bug, never silently merged."""


class IndexScheduler:
    def __init__(self, first_index: int, attempts: int, workers: int, target_successes: int = 0,
                 done: dict[int, bool] | None = None, max_chunk: int = 8):
        self.first, self.end = first_index, first_index + attempts
        self.workers, self.target, self.max_chunk = max(1, workers), target_successes, max(1, max_chunk)
        self.done: dict[int, bool] = {i: s for i, s in (done or {}).items() if self.first <= i < self.end}
        self.pending = sorted(set(range(self.first, self.end)) - set(self.done))
        self.in_flight: dict[IndexRange, None] = {}

    # -- handing out work
    def bound(self) -> int:
        """No index at or above this is needed: the target-th success among finished indices."""
        if not self.target:
            return self.end
        succ = sorted(i for i, s in self.done.items() if s)
        return succ[self.target - 1] + 1 if len(succ) >= self.target else self.end

    def take(self) -> IndexRange | None:
        """The next range of contiguous pending indices below bound(), or None."""
        b = self.bound()
        todo = [i for i in self.pending if i < b]
        if not todo:
            return None
        size = max(1, min(self.max_chunk, math.ceil(len(todo) / (2 * self.workers))))
        first = todo[0]
        n = 1
        while n < size and n < len(todo) and todo[n] == first + n:
            n += 1
        r = IndexRange(first, first + n)
        self.pending = [i for i in self.pending if not first <= i < r.end]
        self.in_flight[r] = None
        return r

    # -- results
    def finish(self, r: IndexRange, results: dict[int, bool]) -> list[int]:
        """Record a range's finished indices (a stopped worker may finish only a prefix); the rest
        go back to pending. Returns the indices newly recorded."""
        self.in_flight.pop(r, None)
        new = []
        for i, ok in sorted(results.items()):
            if not r.first <= i < r.end:
                raise DuplicateIndexError(f"index {i} reported for range {r}")
            if i in self.done:
                raise DuplicateIndexError(f"index {i} reported twice")
            self.done[i] = bool(ok)
            new.append(i)
        self._requeue(i for i in r if i not in self.done)
        return new

    def release(self, r: IndexRange) -> None:
        """The range's worker died: every index of it runs again elsewhere."""
        self.in_flight.pop(r, None)
        self._requeue(i for i in r if i not in self.done)

    def _requeue(self, indices) -> None:
        self.pending = sorted(set(self.pending) | set(indices))

    # -- where the run stands
    def cutoff(self) -> int | None:
        """The last index of the run's result once it is known (all below done), else None."""
        succ = 0
        for i in range(self.first, self.end):
            if i not in self.done:
                return None
            succ += self.done[i]
            if self.target and succ >= self.target:
                return i
        return self.end - 1

    @property
    def complete(self) -> bool:
        return self.cutoff() is not None

    def kept(self) -> list[int]:
        """The indices of the result: the done ones up to the cutoff (a stopped run: below bound())."""
        c = self.cutoff()
        lim = c + 1 if c is not None else self.bound()
        return sorted(i for i in self.done if i < lim)
