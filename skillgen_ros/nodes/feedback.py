"""Action server settings shared by the driver and skill_replay: the feedback rate limit, and how
long a finished goal's result is kept.

Feedback goes out at most `hz` times per wall-clock second, plus always the final step. On the
real-time robot (20 Hz control) that is every step, as joint_trajectory_controller's
`action_monitor_rate` does; in lockstep, where periods come many times faster than real time,
the clients are not woken hundreds of times a second for progress nobody can read.
"""
from __future__ import annotations

import time

# Seconds an action server keeps a finished goal's result for a client to fetch. rclpy keeps it
# 900 s by default: with a skill's arrays in every ReplaySkill result and a goal every second or
# so, the container held a quarter of an hour of them (issue 19's soak: +0.3 MiB per attempt).
# Clients ask for the result as soon as the goal is accepted (and resend within 5 s, answered.py).
RESULT_TIMEOUT_S = 30



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
