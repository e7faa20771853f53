"""Release: leave the object just put down free of the hand before a planned motion starts.

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

An open finger can also press the object against its fixture (the nut's ring against the peg).
The compliant OSC then lets the hand drift away from its last target, and the retreat would lift
the object by friction. If the hand has drifted more than 8 mm, it moves on 1.5 cm further along
the drift, which unloads the finger (follow).

An open finger can also stay against the object with too little force to make the hand drift:
the nut's handle leaning on a finger as the ring sticks on the peg. Friction from that sideways
push lifts the nut on the retreat. So while the driver reports a sideways (horizontal) force on
the hand, the hand steps along it, away from what pushes, up to 3 cm, and a little past the point
where the force vanishes (clear). A force straight down (the object's weight on a finger) gives
no direction and is left to the retreat. The 0.05 N threshold suits the simulated wrench, which
is exact; a real arm's estimate needs its noise floor (1-2 N for a Panda's O_F_ext_hat_K).

The moves need only the measured gripper width, EE position and, for the clear, the external
wrench the driver reports (a Panda's O_F_ext_hat_K), so the same code runs in-process and over
the graph. `release_targets` is a generator: it yields EE targets and is
sent a `Feedback` after each.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Generator, NamedTuple

import numpy as np

from ..errors import InvalidInputError

OPEN_WIDTH = 0.075  # m between the fingers that counts as open: the Panda hand opens to 0.08


class Feedback(NamedTuple):
    width: float  # m between the fingers
    position: np.ndarray  # EE position (m, world)
    wrench: np.ndarray | None = None  # (6,) external force/torque on the hand (world); None: unknown


@dataclass(frozen=True)
class ReleaseConfig:
    settle_steps: int = 10  # periods to hold still while the fingers open
    stall_eps: float = 5e-4  # m of width change per period below which the fingers have stopped
    unjam_step: float = 0.008  # m of hand slide per period
    unjam_max: float = 0.04  # m of slide per direction at most (0 = no unjam)
    progress: float = 0.002  # m of width gained that shows a move may have freed the fingers
    recentre_steps: int = 4  # periods back at the release pose once the fingers are free
    drift_max: float = 0.008  # m off the last target beyond which an open finger is pressing
    follow: float = 0.015  # m to move on along the drift (0 = no follow)
    follow_steps: int = 6
    contact_force: float = 0.05  # N of sideways force on the hand that means a finger still touches
    clear_step: float = 0.004  # m per period along that force
    clear_max: float = 0.03  # m of clearing at most (0 = no clear)
    clear_margin: float = 0.004  # m further once the force is gone

    def __post_init__(self):
        positive = ("stall_eps", "unjam_step", "progress", "clear_step")
        bad = [f"{f}={getattr(self, f)}" for f in self.__dataclass_fields__
               if not np.isfinite(getattr(self, f)) or getattr(self, f) < 0 or (f in positive and getattr(self, f) == 0)]
        if bad:
            raise InvalidInputError(f"invalid release setting {', '.join(bad)}: each must be finite and >= 0, and "
                                    f"{', '.join(positive)} > 0", reason="INVALID_PARAMETER")

    def without_moves(self) -> "ReleaseConfig":
        """Only the settle: no unjam, follow or clear (MimicGen-style baselines, or `release.moves: false`)."""
        return replace(self, unjam_max=0.0, follow=0.0, clear_max=0.0)


Releaser = Generator[np.ndarray, Feedback, None]


def _hold(target: np.ndarray, fb: Feedback, cfg: ReleaseConfig) -> Generator[np.ndarray, Feedback, tuple[Feedback, bool]]:
    """Hold `target` while the fingers open; returns (feedback, stalled short of open)."""
    for _ in range(cfg.settle_steps):
        before, fb = fb, (yield target)
        if fb.width >= OPEN_WIDTH:
            return fb, False
        if abs(fb.width - before.width) < cfg.stall_eps:
            return fb, True
    return fb, False


def _unjam(hold: np.ndarray, fb: Feedback, cfg: ReleaseConfig) -> Generator[np.ndarray, Feedback, Feedback]:
    """Slide along hold's -y, +y, -x, +x (back to `hold` between them) until the fingers open."""
    stuck = fb.width
    n = max(1, int(round(cfg.unjam_max / cfg.unjam_step)))
    moves = [hold[:3, 3] + k * cfg.unjam_step * axis for axis in (-hold[:3, 1], hold[:3, 1], -hold[:3, 0], hold[:3, 0])
             for k in [*range(1, n + 1), 0]]  # k = 0: back to where the release happened
    for position in moves:
        target = hold.copy()
        target[:3, 3] = position
        fb = yield target
        if fb.width - stuck >= cfg.progress:  # looks free: let them finish opening here
            fb, stalled = yield from _hold(target, fb, cfg)
            if stalled and fb.width < OPEN_WIDTH:
                stuck = fb.width  # wedged again: carry on with the next move
                continue
            for _ in range(cfg.recentre_steps):  # then centre the open hand on the object again
                fb = yield hold
            return fb
    return fb


def _sideways(fb: Feedback) -> np.ndarray:
    """The horizontal part of the external force on the hand (zero when it is not reported)."""
    if fb.wrench is None:
        return np.zeros(3)
    return np.array([fb.wrench[0], fb.wrench[1], 0.0])


def _clear(start: np.ndarray, fb: Feedback, cfg: ReleaseConfig) -> Generator[np.ndarray, Feedback, Feedback]:
    """Step along the sideways force until it is gone (or clear_max), then clear_margin further."""
    target, moved = start.copy(), 0.0
    while moved < cfg.clear_max - 1e-9:
        force = _sideways(fb)
        size = float(np.linalg.norm(force))
        if size <= cfg.contact_force:
            break
        target = target.copy()
        target[:3, 3] += cfg.clear_step * force / size
        moved += cfg.clear_step
        fb = yield target
    if moved > 0 and cfg.clear_margin > 0:
        away = target[:3, 3] - start[:3, 3]
        target = target.copy()
        target[:3, 3] += cfg.clear_margin * away / np.linalg.norm(away)
        for _ in range(3):
            fb = yield target
    return fb


def release_targets(hold: np.ndarray, width: float, cfg: ReleaseConfig = ReleaseConfig(),
                    reference: np.ndarray | None = None, wrench: np.ndarray | None = None) -> Releaser:
    """Yield 4x4 EE targets; send() each the Feedback after the step. Ends when the hand is free.

    hold: the EE pose now (held while settling); reference: where the hand was last sent (the
    skill's last target), for the drift check and the clear; None skips both. wrench: the
    external wrench on the hand now (None: the driver reports none, no clear).
    """
    fb = Feedback(float(width), hold[:3, 3].copy(), wrench)
    last = hold
    if fb.width < OPEN_WIDTH and cfg.settle_steps > 0:
        fb, stalled = yield from _hold(hold, fb, cfg)
        if stalled and cfg.unjam_max > 0:
            fb = yield from _unjam(hold, fb, cfg)
    if reference is None:
        return
    drift = np.asarray(fb.position, float) - reference[:3, 3]
    size = float(np.linalg.norm(drift))
    if cfg.follow > 0 and size > cfg.drift_max:
        last = reference.copy()
        last[:3, 3] += drift / size * (size + cfg.follow)
        for _ in range(cfg.follow_steps):
            fb = yield last
    if cfg.clear_max > 0:
        yield from _clear(last, fb, cfg)
