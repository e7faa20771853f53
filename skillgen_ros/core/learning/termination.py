"""Termination labels and the deployment filter for the termination classifier T.

Labels (Appendix "Termination Classifier"): a step is "terminate" (1) if the motion planner
ran it, "running" (0) if the skill did; then the last 50% of every motion-planner segment is
flipped to "running", so T does not fire at the start of a skill. At deployment, termination
is accepted only after 5 consecutive positive predictions.

Our option "settled" (not the paper's): a skill that ends by holding still (our scripted demos
close the gripper, then wait about 10 steps before the motion planner lifts) has its last steps
and the motion's first steps at the same state, labelled "running" and "terminate" in a ratio of
about 9 to 2, so the paper's rule teaches T to fire only once the arm has moved away, which pi
never does. "settled" also labels "terminate" the skill's tail that stays within a few mm, degrees
and a mm of gripper travel of the skill's last step (the paper's "termination state", the last pose
of the skill), for every skill that a motion follows.
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError

RUNNING, TERMINATE = 0, 1
CONSECUTIVE = 5  # the paper's rule
# "settled": how close to the skill's last step a tail step must stay (the still hold in our demos moves
# the hand a median 3.4 mm, 90% under 5.8 mm, and turns it < 3 deg, so 5 mm keeps a median 9 of its
# ~10 steps (docs/hsp.md); the motion planner's lift leaves 5 mm within 2-3 steps)
SETTLED_POS_M = 0.005
SETTLED_ROT_RAD = np.radians(5.0)
SETTLED_GRIPPER_M = 0.001


def segments(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of each maximal run of True in a 1-D boolean array."""
    m = np.asarray(mask, bool).astype(np.int8)
    d = np.diff(np.concatenate([[0], m, [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def termination_labels(mp_step: np.ndarray, settled: np.ndarray | None = None) -> np.ndarray:
    """(T,) mp_step (1 motion planner, 0 skill) -> (T,) int64 labels.

    A motion segment of L steps keeps its first ceil(L/2) steps at TERMINATE and flips the last
    floor(L/2) to RUNNING (L = 1: nothing flips). `settled` (T,) bool (`settled_tail`) marks skill
    steps that are also TERMINATE (the "settled" rule; None: the paper's).
    """
    mp = np.asarray(mp_step)
    if mp.ndim != 1:
        raise InvalidInputError(f"mp_step must be 1-D, got shape {mp.shape}")
    labels = (mp != 0).astype(np.int64)
    for a, b in segments(mp != 0):
        labels[a + (b - a + 1) // 2:b] = RUNNING
    if settled is not None:
        settled = np.asarray(settled, bool)
        if settled.shape != mp.shape:
            raise InvalidInputError(f"settled has shape {settled.shape}, mp_step {mp.shape}")
        labels[settled & (mp == 0)] = TERMINATE
    return labels


def settled_tail(mp_step: np.ndarray, pos: np.ndarray, quat: np.ndarray, gripper: np.ndarray) -> np.ndarray:
    """(T,) bool: the steps at the end of each skill segment that a motion follows whose hand
    position, orientation (x y z w) and finger positions all stay within SETTLED_* of that
    segment's last step (which is always included), counted back until the first that does not."""
    from scipy.spatial.transform import Rotation

    mp = np.asarray(mp_step) != 0
    pos, gripper = np.asarray(pos, float), np.asarray(gripper, float).reshape(len(mp), -1)
    rot = Rotation.from_quat(np.asarray(quat, float))
    out = np.zeros(len(mp), bool)
    for a, b in segments(~mp):
        if b == len(mp):  # the demo's last skill: no motion follows, the task ends
            continue
        e = b - 1
        near = ((np.linalg.norm(pos[a:b] - pos[e], axis=1) <= SETTLED_POS_M)
                & ((rot[a:b].inv() * rot[e]).magnitude() <= SETTLED_ROT_RAD)
                & (np.abs(gripper[a:b] - gripper[e]).max(axis=1) <= SETTLED_GRIPPER_M))
        k = len(near) - int(np.argmin(near[::-1])) if not near.all() else 0  # first index of the tail run
        out[a + k:b] = True
    return out


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
