"""Release: let a gripper commanded open finish opening before a planned motion starts.

A place skill ends with the open command, but the replay may end before the fingers are open.
The fast planned retreat would then drag the released object (a NutAssembly nut off its peg).
So the attempt first holds the pose while the fingers open (settle).

The Panda's fingers are coupled, so a released object wedged between them stops both: in
NutAssembly a nut handle twisted against the finger pads self-locks (edge contacts, friction
1.5) and hangs from the open-commanded hand. Holding still does not free it, and small moves only
carry the nut along. So the hand slides in its own plane, along the finger axis (EE y) and then
along the palm (EE x), to each side in turn, up to 4 cm: far enough that the nut's ring meets the
peg, which holds the nut while the fingers come free (unjam). Then the open hand goes back to the
release pose, centred on the handle, so the retreat does not drag the nut up by one finger.

The moves need only the measured gripper width, so the same code runs in-process and over the
graph. `release_targets` is a generator: it yields EE targets and is sent the width after each.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Generator

import numpy as np

OPEN_WIDTH = 0.075  # m between the fingers that counts as open: the Panda hand opens to 0.08


@dataclass(frozen=True)
class ReleaseConfig:
    settle_steps: int = 10  # periods to hold still while the fingers open
    stall_eps: float = 5e-4  # m of width change per period below which the fingers have stopped
    unjam_step: float = 0.008  # m of hand slide per period
    unjam_max: float = 0.04  # m of slide per direction at most
    progress: float = 0.002  # m of width gained that shows a move freed the fingers
    recentre_steps: int = 4  # periods back at the release pose once the fingers are free


def _hold(target: np.ndarray, width: float, cfg: ReleaseConfig) -> Generator[np.ndarray, float, tuple[float, bool]]:
    """Hold `target` while the fingers open; returns (width, stalled short of open)."""
    for _ in range(cfg.settle_steps):
        before, width = width, (yield target)
        if width >= OPEN_WIDTH:
            return width, False
        if abs(width - before) < cfg.stall_eps:
            return width, True
    return width, False


def release_targets(hold: np.ndarray, width: float, cfg: ReleaseConfig = ReleaseConfig()
                    ) -> Generator[np.ndarray, float, None]:
    """Yield 4x4 EE targets; send() each the gripper width after the step. Ends when open.

    settle: hold `hold` while the width grows (at most settle_steps periods).
    unjam: if the fingers stopped short of OPEN_WIDTH, slide along hold's -y, +y, -x, +x axes in
    turn (back to `hold` between them); once a move frees them, hold there while they open, then
    return to `hold`.
    """
    if width >= OPEN_WIDTH or cfg.settle_steps == 0:
        return
    width, stalled = yield from _hold(hold, width, cfg)
    if not stalled or cfg.unjam_max <= 0:
        return  # open, still opening (the motion may start), or unjamming is off
    stuck = width
    n = max(1, int(round(cfg.unjam_max / cfg.unjam_step)))
    moves = [hold[:3, 3] + k * cfg.unjam_step * axis for axis in (-hold[:3, 1], hold[:3, 1], -hold[:3, 0], hold[:3, 0])
             for k in [*range(1, n + 1), 0]]  # k = 0: back to where the release happened
    for position in moves:
        target = hold.copy()
        target[:3, 3] = position
        width = yield target
        if width - stuck >= cfg.progress:  # free: let them finish opening here, then centre the
            yield from _hold(target, width, cfg)  # open hand on the object again, clear of it,
            for _ in range(cfg.recentre_steps):  # so the retreat does not drag it by a finger
                yield hold
            return
