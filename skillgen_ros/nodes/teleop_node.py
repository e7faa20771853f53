"""The teleop node itself (rclpy): keys and a 3D mouse -> osc_target; see nodes/teleop.py for the
keys, the status line and the pure functions this class maps onto topics and parameters."""
from __future__ import annotations

import os
import select
import sys
import termios
import threading
import tty

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from skillgen_interfaces.msg import GripperState, ObjectPoseArray, OscTarget
from skillgen_ros.core.geometry import Pose
from skillgen_ros.nodes.teleop import (GRIPPER_KEY, HELP, QUIT_KEYS, Target, _ESCAPES, _EVENT, _StatusPrinter, apply_key, apply_twist, clamp_lead, find_spacemouse, parse_spacemouse_events, spacemouse_twist)


class Teleop(Node):
    """Keyboard (and 3D mouse) -> osc_target at a fixed rate, relative to the measured EE."""

    def __init__(self):
        super().__init__("teleop")
        p = {
            "rate_hz": (20.0, "osc_target publishing rate"),
            "linear_step": (0.01, "metres per key press"),
            "angular_step": (0.08, "radians per key press"),
            "max_lead": (0.08, "largest distance (m) the target may run ahead of the measured EE"),
            "frame_id": ("world", "frame of the published target"),
            "read_stdin": (True, "read keys from this process's terminal"),
            "spacemouse_device": ("", "3D mouse evdev path; empty = autodetect under /dev/input/by-id"),
            "spacemouse_max_linear": (0.15, "m/s at full 3D-mouse deflection"),
            "spacemouse_max_angular": (0.8, "rad/s at full 3D-mouse deflection"),
            "task": ("", "task being demonstrated: the status line shows the distance to its next object"),
            "object_poses_topic": ("sim/ground_truth/object_poses",
                                   "object poses for the status line (perception/object_poses on a real robot)"),
            "status_hz": (5.0, "status line rate on the terminal; 0 = no status line"),
            "min_subscribers": (0, "hold the robot until osc_target has this many subscribers (`demos record`: "
                                   "the driver and the recorder, so the bag has the demo from its first command)"),
        }
        for name, (default, desc) in p.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=desc))
        g = lambda n: self.get_parameter(n).value  # noqa: E731
        self._rate = float(g("rate_hz"))
        self._lin, self._ang = float(g("linear_step")), float(g("angular_step"))
        self._lead, self._frame = float(g("max_lead")), str(g("frame_id"))
        self._sm_lin, self._sm_ang = float(g("spacemouse_max_linear")), float(g("spacemouse_max_angular"))
        self._min_subs = int(g("min_subscribers"))
        self._lock = threading.Lock()
        self._target: Target | None = None
        self._ee: np.ndarray | None = None
        self._gripper_cmd: float | None = None
        self._keys: list[str] = []
        self._warned = ""  # the last reason keys were ignored for
        self._pub = self.create_publisher(OscTarget, "osc_target", 10)
        self.create_subscription(PoseStamped, "ee_pose", self._on_ee, 10)
        self.create_subscription(GripperState, "gripper_state", self._on_gripper, 10)
        self._status = _StatusPrinter(str(g("task")), float(g("status_hz")), self._rate)
        if self._status.enabled:
            latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self.create_subscription(ObjectPoseArray, str(g("object_poses_topic")), self._on_objects, latched)
        self._tty_state = None
        self._stop = threading.Event()
        if bool(g("read_stdin")):
            threading.Thread(target=self._read_keys, daemon=True).start()
        self._sm_fd, self._sm_axes = None, np.zeros(6)
        dev = find_spacemouse(str(g("spacemouse_device")))
        if dev:
            try:
                self._sm_fd = os.open(dev, os.O_RDONLY | os.O_NONBLOCK)
                self.get_logger().info(f"3D mouse: {dev}")
            except OSError as e:
                self.get_logger().warning(f"3D mouse {dev} not usable: {e}")
        self.create_timer(1.0 / self._rate, self._tick)
        self.get_logger().info("teleop keys:" + HELP)

    # -- inputs
    def _on_ee(self, msg):
        p, q = msg.pose.position, msg.pose.orientation
        with self._lock:
            self._ee = np.array([p.x, p.y, p.z, q.x, q.y, q.z, q.w])

    def _on_gripper(self, msg):
        with self._lock:
            self._gripper_cmd = float(msg.command)
            self._status.gripper(float(msg.width), bool(msg.grasping), float(msg.command))

    def _on_objects(self, msg):
        poses = {o.id: Pose(np.array([o.pose.position.x, o.pose.position.y, o.pose.position.z]),
                            np.array([o.pose.orientation.x, o.pose.orientation.y, o.pose.orientation.z,
                                      o.pose.orientation.w])) for o in msg.objects}
        with self._lock:
            self._status.objects = poses

    def _read_keys(self):
        try:
            fd = sys.stdin.fileno()
        except (OSError, ValueError):  # no stdin at all (e.g. started by a launcher)
            self.get_logger().warning("no terminal on stdin: keyboard input disabled")
            return
        if os.isatty(fd):
            self._tty_state = termios.tcgetattr(fd)
            tty.setcbreak(fd)  # one key at a time, no echo; Ctrl-C still raises SIGINT
        while not self._stop.is_set():
            r, _, _ = select.select([fd], [], [], 0.1)
            if not r:
                continue
            data = os.read(fd, 64)
            if not data:  # stdin closed
                return
            text = _ESCAPES.sub("", data.decode("utf-8", "ignore"))  # arrows etc. are not '[' presses
            with self._lock:
                self._keys.extend(text)

    # -- the control period
    def _tick(self):
        with self._lock:
            keys, self._keys = self._keys, []
            ee = None if self._ee is None else self._ee.copy()
            grip0 = self._gripper_cmd
        if self._target is None:
            subs = self._pub.get_subscription_count()
            if ee is None or subs < self._min_subs:  # no robot (or recorder) yet: honour quit, ignore motion keys
                if any(k in QUIT_KEYS for k in keys):
                    self._restore_tty()
                    rclpy.try_shutdown()
                elif keys:
                    why = ("no ee_pose yet (is the driver up?)" if ee is None else
                           f"osc_target has fewer than {self._min_subs} subscribers (is the recorder up?)")
                    if why != self._warned:  # each reason once
                        self._warned = why
                        self.get_logger().warning(f"{why}; keys ignored until it is")
                return
            self._target = Target(ee[:3], ee[3:], grip0 if grip0 is not None and grip0 > 0 else -1.0)
        t = self._target
        for k in keys:
            self._status.last_key = k
            if k in QUIT_KEYS:
                self._status.finish()
                self.get_logger().info("teleop: quit")
                self._restore_tty()
                rclpy.try_shutdown()
                return
            if k == "h":
                self._status.finish()
                print("teleop keys:" + HELP, file=sys.stderr, flush=True)
            elif k == "]":
                self._lin, self._ang = self._lin * 2, self._ang * 2
            elif k == "[":
                self._lin, self._ang = self._lin / 2, self._ang / 2
            elif k == "0" and ee is not None:
                t = Target(ee[:3], ee[3:], t.gripper)
            else:
                t = apply_key(t, k, self._lin, self._ang)
        t = self._spacemouse(t)
        if ee is not None:
            t = clamp_lead(t, ee[:3], self._lead)
        self._target = t
        msg = OscTarget()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self._frame
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in t.position)
        (msg.pose.orientation.x, msg.pose.orientation.y,
         msg.pose.orientation.z, msg.pose.orientation.w) = (float(v) for v in t.quaternion)
        msg.gripper = float(t.gripper)
        self._pub.publish(msg)
        with self._lock:
            self._status.tick(ee)

    def _spacemouse(self, t: Target) -> Target:
        if self._sm_fd is None:
            return t
        try:
            data = os.read(self._sm_fd, _EVENT.size * 64)
        except BlockingIOError:
            data = b""
        except OSError:
            self._sm_fd = None
            return t
        self._sm_axes, presses = parse_spacemouse_events(data, self._sm_axes)
        for _ in range(presses):
            t = apply_key(t, GRIPPER_KEY, 0, 0)
        lin, ang = spacemouse_twist(self._sm_axes, 1.0 / self._rate, self._sm_lin, self._sm_ang)
        return apply_twist(t, lin, ang) if np.any(self._sm_axes) else t

    def _restore_tty(self):
        if self._tty_state is not None:
            try:
                termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, self._tty_state)
            except termios.error:
                pass
            self._tty_state = None

    def destroy_node(self):
        self._stop.set()
        self._restore_tty()
        if self._sm_fd is not None:
            os.close(self._sm_fd)
        return super().destroy_node()
