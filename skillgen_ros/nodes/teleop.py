"""teleop node: a person drives the end effector from a keyboard (and a 3D mouse when present).

Publishes `osc_target` (skillgen_interfaces/OscTarget) at `rate_hz` (20 Hz), an absolute EE target
that starts at the current `ee_pose` and is moved by key presses; the target is kept within
`max_lead` metres of the measured EE so that releasing the keys stops the arm quickly and the
same node works on a real robot after remapping `ee_pose` / `osc_target`.

Keys (terminal in raw mode; world / robot-base frame, x forward, y left, z up):
    w / s   +x / -x            u / o   roll  +/- (about world x)
    a / d   +y / -y            i / k   pitch +/- (about world y)
    r / f   +z / -z            j / l   yaw   +/- (about world z)
    space   toggle gripper (open <-> closed)
    ] / [   double / halve the step size     h   print this help
    0       reset the target to the measured EE pose
    q       quit (Ctrl-C works too)
Each key press moves the target by `linear_step` metres or `angular_step` radians; holding a
key repeats it at the terminal's auto-repeat rate.

Status line: `status_hz` times a second (5) the node prints one line to its terminal with the
measured EE pose, the gripper's width and grasp state, the distance from the hand to the next
skill's object point (`task` parameter; core/teleop.py, core/tasks/skill_points.py) and the last
key, rewritten in place on a terminal; to a pipe it prints a new line only when the key, the grasp
or the next skill changes.

3D mouse: if `spacemouse_device` (default: the first /dev/input/by-id/*3Dconnexion*-event-*
or *SpaceMouse*-event-* device) exists and is readable, its six axes add a velocity of up to
`spacemouse_max_linear` m/s and `spacemouse_max_angular` rad/s, and its first button toggles
the gripper. Without one the node runs keyboard-only.
"""
from __future__ import annotations

import glob
import os
import re
import shutil
import struct
import sys
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.teleop import SkillProgress, TeleopView, status_line
from skillgen_ros.nodes.runtime import run_node

# key -> (linear direction (3,), angular axis (3,)) in the world frame
KEY_MOTION: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "w": ((1, 0, 0), (0, 0, 0)), "s": ((-1, 0, 0), (0, 0, 0)),
    "a": ((0, 1, 0), (0, 0, 0)), "d": ((0, -1, 0), (0, 0, 0)),
    "r": ((0, 0, 1), (0, 0, 0)), "f": ((0, 0, -1), (0, 0, 0)),
    "u": ((0, 0, 0), (1, 0, 0)), "o": ((0, 0, 0), (-1, 0, 0)),
    "i": ((0, 0, 0), (0, 1, 0)), "k": ((0, 0, 0), (0, -1, 0)),
    "j": ((0, 0, 0), (0, 0, 1)), "l": ((0, 0, 0), (0, 0, -1)),
}
GRIPPER_KEY = " "
QUIT_KEYS = ("q", "\x03", "\x04")  # q, Ctrl-C, Ctrl-D
_ESCAPES = re.compile(r"\x1b(\[[0-9;]*[A-Za-z~]|O.)?")
HELP = __doc__.split("Keys", 1)[1].split("\n\n")[0]


@dataclass(frozen=True)
class Target:
    """The commanded EE pose (position (3,), xyzw quaternion (4,)) and gripper -1 open..+1 closed."""

    position: np.ndarray
    quaternion: np.ndarray
    gripper: float = -1.0


def apply_key(t: Target, key: str, linear_step: float, angular_step: float) -> Target:
    """The target after one key press (unknown keys leave it unchanged)."""
    if key == GRIPPER_KEY:
        return Target(t.position, t.quaternion, -1.0 if t.gripper > 0 else 1.0)
    if key not in KEY_MOTION:
        return t
    lin, ang = (np.asarray(v, float) for v in KEY_MOTION[key])
    return apply_twist(t, lin * linear_step, ang * angular_step)


def apply_twist(t: Target, dpos: np.ndarray, drot: np.ndarray) -> Target:
    """Move the target by a world-frame translation and a world-frame rotation vector."""
    q = (Rotation.from_rotvec(drot) * Rotation.from_quat(t.quaternion)).as_quat()
    return Target(np.asarray(t.position, float) + dpos, q, t.gripper)


def clamp_lead(t: Target, ee_position: np.ndarray, max_lead: float) -> Target:
    """Keep the target within max_lead of the measured EE so it never runs far ahead of the arm."""
    d = np.asarray(t.position) - np.asarray(ee_position)
    n = float(np.linalg.norm(d))
    if n <= max_lead or n == 0.0:
        return t
    return Target(np.asarray(ee_position) + d * (max_lead / n), t.quaternion, t.gripper)


# ---- 3D mouse (Linux evdev) ------------------------------------------------------------------
_EVENT = struct.Struct("llHHi")  # struct input_event: timeval, type, code, value
EV_KEY, EV_REL, EV_ABS = 0x01, 0x02, 0x03
SPACEMOUSE_FULL_SCALE = 350.0  # typical axis range of 3Dconnexion devices


def find_spacemouse(explicit: str = "") -> str | None:
    """The 3D-mouse event device to read, or None when there is none (the usual case)."""
    cands = [explicit] if explicit else sorted(
        glob.glob("/dev/input/by-id/*3Dconnexion*-event-*") + glob.glob("/dev/input/by-id/*SpaceMouse*-event-*")
        + glob.glob("/dev/input/by-id/*spacenav*-event-*"))
    for c in cands:
        if c and os.path.exists(c) and os.access(c, os.R_OK):
            return c
    return None


def parse_spacemouse_events(data: bytes, axes: np.ndarray) -> tuple[np.ndarray, int]:
    """Update the six axes (x y z rx ry rz, -1..1) from raw events; returns (axes, button presses)."""
    axes = axes.copy()
    presses = 0
    for off in range(0, len(data) - _EVENT.size + 1, _EVENT.size):
        _, _, typ, code, value = _EVENT.unpack_from(data, off)
        if typ in (EV_REL, EV_ABS) and code < 6:
            axes[code] = float(np.clip(value / SPACEMOUSE_FULL_SCALE, -1.0, 1.0))
        elif typ == EV_KEY and value == 1:
            presses += 1
    return axes, presses


def spacemouse_twist(axes: np.ndarray, dt: float, max_lin: float, max_ang: float) -> tuple[np.ndarray, np.ndarray]:
    """Device axes -> world translation and rotation for one period (device y/z flipped to z up)."""
    lin = np.array([axes[1], axes[0], -axes[2]]) * max_lin * dt
    ang = np.array([axes[4], axes[3], -axes[5]]) * max_ang * dt
    return lin, ang


# ---- the status line -------------------------------------------------------------------------
class _StatusPrinter:
    """Prints core/teleop.status_line at `hz` on a terminal (rewritten in place), or on a pipe a new
    line whenever the key, the grasp or the next skill changes (so logs stay short)."""

    def __init__(self, task: str, hz: float, control_hz: float, out=None):
        from skillgen_ros.core.tasks import get_task

        self.out = out or sys.stdout
        self.enabled = hz > 0
        self.task = get_task(task) if task else None
        self.progress = SkillProgress(self.task) if self.task else None
        self.every = max(1, int(round(control_hz / hz))) if hz > 0 else 0
        self.tty = bool(getattr(self.out, "isatty", lambda: False)())
        self.objects: dict | None = None
        self.last_key = ""
        self._width: float | None = None
        self._grasping = False
        self._command: float | None = None
        self._n = 0
        self._printed_key = None
        self._shown: tuple | None = None

    def gripper(self, width: float, grasping: bool, command: float) -> None:
        self._width, self._grasping, self._command = width, grasping, command
        if self.progress is not None:
            self.progress.update(grasping)

    def tick(self, ee) -> None:
        if not self.enabled:
            return
        self._n += 1
        view = TeleopView(None if ee is None else Pose(ee[:3], ee[3:]), self._width, self._grasping, self._command,
                          None if self.progress is None else self.progress.index, self.objects, self.last_key)
        if self.tty:
            if self._n % self.every == 0:  # cut to the terminal's width: a wrapped line cannot be rewritten
                cols = shutil.get_terminal_size((120, 24)).columns
                self.out.write("\r" + status_line(view, self.task)[:max(20, cols - 1)] + "\x1b[K")
                self.out.flush()
            return
        key = (self.last_key, self._grasping, view.next_skill, ee is not None)
        if key != self._shown and (self._n % self.every == 0 or self.last_key != self._printed_key):
            self._shown, self._printed_key = key, self.last_key
            self.out.write(status_line(view, self.task) + "\n")
            self.out.flush()

    def finish(self) -> None:
        """End the in-place line so what follows starts on a fresh one."""
        if self.enabled and self.tty:
            self.out.write("\n")
            self.out.flush()


def main(args=None) -> int:
    from skillgen_ros.nodes.teleop_node import Teleop  # rclpy: only the node needs it

    return run_node(Teleop, args, name="teleop")


if __name__ == "__main__":
    sys.exit(main())
