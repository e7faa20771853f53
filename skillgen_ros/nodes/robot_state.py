"""The robot state the graph env acts from: the newest driver period it has seen.

Two sources feed it: `joint_states` (read on demand, nodes/latest.py) and, after a replayed skill, the
driver's `state_history`. The joint_states reader is not spun while skill_replay runs the driver, so it
can hold a period from early in the skill; taken as the state, it made the next observation and the next
plan's start stale, and the trajectory dragged the arm back there (Coffee Prep, 14 of 20 graph attempts).
So a period only replaces the held one if it is newer, by the driver's stamp.
"""
from __future__ import annotations

import threading

import numpy as np

from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS
from skillgen_ros.nodes.state_history import ns


class NewestRobotState:
    """Arm and finger positions of the newest driver period seen, with its stamp (ns; -1: none yet this scene)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._q, self._fingers, self._stamp = np.zeros(len(ARM_JOINTS)), np.zeros(len(FINGER_JOINTS)), -1

    def take_joint_state(self, m) -> bool:
        """Take a JointState message; False if there is none or it lacks an arm joint. A message older than
        the state held is accepted (True) but not taken."""
        if m is None:
            return False
        pos = dict(zip(m.name, m.position))
        if not all(j in pos for j in ARM_JOINTS):
            return False
        fingers = np.array([pos[j] for j in FINGER_JOINTS]) if all(j in pos for j in FINGER_JOINTS) else None
        stamp = ns(m.header.stamp)
        with self._lock:
            if stamp >= self._stamp:
                self._q, self._stamp = np.array([pos[j] for j in ARM_JOINTS]), stamp
                if fingers is not None:
                    self._fingers = fingers
        return True

    def take_period(self, q, fingers, stamp_ns: int) -> None:
        """A driver period (state_history's), taken if it is newer than the state held."""
        with self._lock:
            if stamp_ns > self._stamp:
                self._q, self._fingers, self._stamp = np.array(q, float), np.array(fingers, float), int(stamp_ns)

    def new_scene(self) -> None:
        """A reset: the new scene's clock may start over, so the next period is taken whatever its stamp."""
        with self._lock:
            self._stamp = -1

    def snapshot(self) -> tuple[np.ndarray, np.ndarray, int]:
        """(arm positions, finger positions, stamp ns), copies."""
        with self._lock:
            return self._q.copy(), self._fingers.copy(), self._stamp
