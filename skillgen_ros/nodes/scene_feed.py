"""Feed a core SceneSynthesizer from the graph's topics (shared by the recorder and `skillgen view`).

Subscribes, decoded, to joint_states, the sim's true object poses, perception's estimates, each
camera's pose and the planner's path markers (relative names: the node's namespace), turns each
message into plain values and hands the synthesizer's CDR output to `emit(msg, log_ns)`.
"""
from __future__ import annotations

import time
from typing import Callable, Sequence

from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from visualization_msgs.msg import MarkerArray

from skillgen_interfaces.msg import ObjectPoseArray
from skillgen_ros.core.viz.scene import ObjectPoseValue, SceneSynthesizer, VizMessage

RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
TRUTH_TOPIC = "sim/ground_truth/object_poses"
ESTIMATE_TOPIC = "perception/object_poses"
PATH_TOPIC = "planner/path_markers"


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _objects(msg: ObjectPoseArray) -> list[ObjectPoseValue]:
    return [ObjectPoseValue(o.id, o.type, (o.pose.position.x, o.pose.position.y, o.pose.position.z),
                            (o.pose.orientation.x, o.pose.orientation.y, o.pose.orientation.z, o.pose.orientation.w))
            for o in msg.objects]


class SceneFeed:
    """Subscriptions on `node` that drive `synth`; `active()` False drops input (a paused recorder)."""

    def __init__(self, node: Node, emit: Callable[[VizMessage, int], None], cameras: Sequence[str] = ("front", "wrist"),
                 synth: SceneSynthesizer | None = None, active: Callable[[], bool] = lambda: True):
        self.synth = synth or SceneSynthesizer()
        self._emit, self._active = emit, active
        node.create_subscription(JointState, "joint_states", self._on_joints, RELIABLE)
        node.create_subscription(ObjectPoseArray, TRUTH_TOPIC, lambda m: self._on_objects(m, False), LATCHED)
        node.create_subscription(ObjectPoseArray, ESTIMATE_TOPIC, lambda m: self._on_objects(m, True), LATCHED)
        node.create_subscription(MarkerArray, PATH_TOPIC, self._on_path, LATCHED)
        for cam in cameras:
            node.create_subscription(PoseStamped, f"camera/{cam}/pose", lambda m, c=cam: self._on_camera(c, m),
                                     qos_profile_sensor_data)

    def _out(self, msgs: list[VizMessage]) -> None:
        now = time.time_ns()
        for m in msgs:
            self._emit(m, now)

    def _on_joints(self, m: JointState) -> None:
        if self._active():
            self._out(self.synth.on_joints(list(m.name), list(m.position), _ns(m.header.stamp)))

    def _on_objects(self, m: ObjectPoseArray, estimate: bool) -> None:
        if self._active():
            self._out(self.synth.on_objects(_objects(m), _ns(m.header.stamp), estimate=estimate))

    def _on_camera(self, name: str, m: PoseStamped) -> None:
        if self._active():
            p, q = m.pose.position, m.pose.orientation
            self._out(self.synth.on_camera(name, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), _ns(m.header.stamp)))

    def _on_path(self, m: MarkerArray) -> None:
        if not self._active():
            return
        goals = [((mk.pose.position.x, mk.pose.position.y, mk.pose.position.z),
                  (mk.pose.orientation.x, mk.pose.orientation.y, mk.pose.orientation.z, mk.pose.orientation.w))
                 for mk in sorted(m.markers, key=lambda mk: mk.id) if mk.ns == "planner_goal"]
        stamp = next((_ns(mk.header.stamp) for mk in m.markers if mk.ns == "planner_goal"), 0)
        self._out(self.synth.on_path(goals, stamp))
