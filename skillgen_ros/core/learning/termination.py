"""Termination labels and the deployment filter for the termination classifier T.

Labels (Appendix "Termination Classifier"): a step is "terminate" (1) if the motion planner
ran it, "running" (0) if the skill did; then the last 50% of every motion-planner segment is
flipped to "running", so T does not fire at the start of a skill. At deployment, termination
is accepted only after 5 consecutive positive predictions.
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError

RUNNING, TERMINATE = 0, 1
CONSECUTIVE = 5  # the paper's rule


def segments(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of each maximal run of True in a 1-D boolean array."""
    m = np.asarray(mask, bool).astype(np.int8)
    d = np.diff(np.concatenate([[0], m, [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def termination_labels(mp_step: np.ndarray) -> np.ndarray:
    """(T,) mp_step (1 motion planner, 0 skill) -> (T,) int64 labels.

    A motion segment of L steps keeps its first ceil(L/2) steps at TERMINATE and flips the last
    floor(L/2) to RUNNING (L = 1: nothing flips).
    """
    mp = np.asarray(mp_step)
    if mp.ndim != 1:
        raise InvalidInputError(f"mp_step must be 1-D, got shape {mp.shape}")
    labels = (mp != 0).astype(np.int64)
    for a, b in segments(mp != 0):
        labels[a + (b - a + 1) // 2:b] = RUNNING
    return labels


class TerminationFilter:
    """Accepts termination only after `consecutive` positive predictions in a row."""

    def __init__(self, consecutive: int = CONSECUTIVE):
        if consecutive < 1:
            raise InvalidInputError(f"consecutive must be >= 1, got {consecutive}")
        self.consecutive = int(consecutive)
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def update(self, positive: bool) -> bool:
        """Feed one prediction; True once the last `consecutive` were all positive."""
        self.count = self.count + 1 if positive else 0
        return self.count >= self.consecutive
