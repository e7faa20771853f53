"""An rclpy ActionClient whose futures always complete when it is used from another thread.

rclpy 7.1.6 (Jazzy, our pin) sends a goal, cancel or result request and only then records its
sequence number. An executor thread that takes the response in between finds no record, logs
"Ignoring unexpected goal response. There may be more than one action server" and the future never
completes: ros2/rclpy#1123, fixed upstream by rclpy#1308 (backported in #1517/#1519, not in our
wheel). Our clients send from a user thread while another thread spins (SkillGenClient, the deploy
CLI, datagen's graph env, the planner), and on a loaded 2-core machine a `generate` goal was lost
this way. This subclass does what the upstream fix does: one lock around taking responses and
around sending + recording a request, so a response is taken only after its request is recorded.
"""
from __future__ import annotations

import threading

from skillgen_ros import rosenv  # noqa: F401  (the ROS environment before rclpy loads)

from rclpy.action import ActionClient  # noqa: E402


class SafeActionClient(ActionClient):
    """ActionClient with rclpy#1308's lock; a drop-in replacement."""

    def __init__(self, *args, **kwargs):
        self._request_lock = threading.RLock()
        super().__init__(*args, **kwargs)

    def take_data(self):
        with self._request_lock:
            return super().take_data()

    def send_goal_async(self, goal, feedback_callback=None, goal_uuid=None):
        with self._request_lock:
            return super().send_goal_async(goal, feedback_callback=feedback_callback, goal_uuid=goal_uuid)

    def _cancel_goal_async(self, goal_handle):
        with self._request_lock:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle):
        with self._request_lock:
            return super()._get_result_async(goal_handle)
