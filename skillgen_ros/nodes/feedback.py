"""Action feedback rate limit shared by the driver and skill_replay.

Feedback goes out at most `hz` times per wall-clock second, plus always the final step. On the
real-time robot (20 Hz control) that is every step, as joint_trajectory_controller's
`action_monitor_rate` does; in lockstep, where periods come many times faster than real time,
the clients are not woken hundreds of times a second for progress nobody can read.
"""
from __future__ import annotations

import time


class FeedbackThrottle:
    def __init__(self, hz: float, clock=time.monotonic):
        self.min_interval = 1.0 / hz if hz > 0 else 0.0
        self._last = -float("inf")
        self._clock = clock  # injectable: tests step a fake clock instead of sleeping

    def due(self, final: bool = False) -> bool:
        now = self._clock()
        if final or now - self._last >= self.min_interval:
            self._last = now
            return True
        return False
