"""viewer node (`skillgen view`): the running graph's topics over the Foxglove WebSocket protocol.

foxglove_bridge is not on PyPI; foxglove-sdk is, and its server speaks the same protocol, so a
Foxglove client opens ws://127.0.0.1:8765 and sees the graph. Every topic the graph poll finds
is subscribed raw (CDR, no deserialization) and logged on a channel with its ros2msg schema
(core/bag/schemas, as the recorder writes it), plus the synthesized scene (/tf, /tf_static,
/robot_description, /scene/object_markers: nodes/scene_feed.py). The robot's meshes are served to
the client as assets (package://franka_panda/..., core/viz/description.py). Loopback only
unless `host` names another address. Latched topics are logged again every `latched_period`
seconds: the protocol has no transient local, and a client that connects later must still get
the robot model and the static frames.
"""
from __future__ import annotations

import sys
import threading
import time

import foxglove
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy

from skillgen_ros.core import validation as V
from skillgen_ros.core.bag.reader import message_class
from skillgen_ros.core.bag.schemas import schema_text
from skillgen_ros.core.errors import BagError, ParameterError, SkillGenError
from skillgen_ros.core.viz.description import resolve_package_uri
from skillgen_ros.core.viz.scene import SCENE_TOPICS, VizMessage
from skillgen_ros.nodes.bag_qos import subscription_qos
from skillgen_ros.nodes.runtime import run_node
from skillgen_ros.nodes.scene_feed import SceneFeed

LOOPBACK = "127.0.0.1"


def serve_asset(uri: str) -> bytes | None:
    """fetchAsset: the Panda's meshes by package:// URI; nothing else on this machine."""
    path = resolve_package_uri(uri)
    return path.read_bytes() if path is not None else None


class Viewer(Node):
    def __init__(self):
        super().__init__("viewer")
        d = ParameterDescriptor
        self.declare_parameter("host", LOOPBACK, d(description="bind address; anything but loopback exposes the "
                                                               "graph to the network (`skillgen view --host`)"))
        self.declare_parameter("port", 8765, d(description="WebSocket port (0: any free port, logged)"))
        self.declare_parameter("exclude", ["/rosout", "/parameter_events"], d(description="never served"))
        self.declare_parameter("discovery_period", 0.5, d(description="s between graph polls"))
        self.declare_parameter("latched_period", 1.0, d(description="s between re-sends of latched topics"))
        self.declare_parameter("scene", True, d(description="serve /tf, /robot_description, object markers"))
        host, port = str(self.get_parameter("host").value), int(self.get_parameter("port").value)
        try:
            V.finite("discovery_period", self.get_parameter("discovery_period").value, 0.0, 3600.0, lo_open=True)
            V.finite("latched_period", self.get_parameter("latched_period").value, 0.0, 3600.0, lo_open=True)
        except SkillGenError as e:
            raise ParameterError(str(e.args[0])) from None
        if not 0 <= port <= 65535 or not host:
            raise ParameterError(f"port must be 0..65535 and host non-empty, got {host!r}:{port}")
        self._exclude = set(self.get_parameter("exclude").value)
        self._lock = threading.Lock()
        self._channels: dict[str, foxglove.Channel] = {}
        self._latched: dict[str, tuple[bytes, int]] = {}
        self._latched_topics: set[str] = set()
        self._subs: dict[str, object] = {}
        self._skipped: set[str] = set()
        try:
            self.server = foxglove.start_server(name="skillgen_ros", host=host, port=port,
                                                supported_encodings=["cdr"], asset_handler=serve_asset)
        except Exception as e:  # noqa: BLE001 -- the SDK raises its own error types (address in use, ...)
            raise ParameterError(f"cannot serve on {host}:{port}: {e}") from None
        self.get_logger().info(f"Foxglove live view on ws://{host}:{self.server.port}"
                               + ("" if host in (LOOPBACK, "localhost", "::1") else " (NOT loopback: reachable "
                                                                                   "from the network)"))
        try:  # from here a failure must stop the server's thread too
            if self.get_parameter("scene").value:
                for topic, (type_name, latched) in SCENE_TOPICS.items():
                    self._channel(topic, type_name, latched)
                self._exclude |= set(SCENE_TOPICS)
                self.feed = SceneFeed(self, self._on_scene)
            group = MutuallyExclusiveCallbackGroup()
            self.create_timer(float(self.get_parameter("discovery_period").value), self._discover,
                              callback_group=group)
            self.create_timer(float(self.get_parameter("latched_period").value), self._resend_latched,
                              callback_group=group)
        except BaseException:
            self.server.stop()
            raise

    def _channel(self, topic: str, type_name: str, latched: bool) -> foxglove.Channel:
        schema = foxglove.Schema(name=type_name, encoding="ros2msg", data=schema_text(type_name).encode())
        ch = foxglove.Channel(topic, schema=schema, message_encoding="cdr")
        with self._lock:
            self._channels[topic] = ch
            if latched:
                self._latched_topics.add(topic)
        return ch

    def _log(self, topic: str, data: bytes, log_ns: int) -> None:
        ch = self._channels.get(topic)
        if ch is None:
            return
        if topic in self._latched_topics:
            self._latched[topic] = (data, log_ns)
        ch.log(data, log_time=log_ns)

    def _on_scene(self, msg: VizMessage, log_ns: int) -> None:
        self._log(msg.topic, msg.data, log_ns)

    def _resend_latched(self) -> None:
        now = time.time_ns()
        for topic, (data, _) in list(self._latched.items()):
            self._channels[topic].log(data, log_time=now)

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._subs or topic in self._exclude or not types:
                continue
            if any(part.startswith("_") for part in topic.split("/")):
                continue  # hidden (action internals)
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            try:
                cls = message_class(types[0])
                qos = subscription_qos([i.qos_profile for i in infos], 10)
                self._channel(topic, types[0], qos.durability == DurabilityPolicy.TRANSIENT_LOCAL)
            except BagError as e:
                if topic not in self._skipped:
                    self._skipped.add(topic)
                    self.get_logger().warn(f"not serving {topic}: {e}")
                continue
            self._subs[topic] = self.create_subscription(
                cls, topic, lambda data, t=topic: self._log(t, data, time.time_ns()), qos, raw=True)
            self.get_logger().info(f"serving {topic} [{types[0]}]")

    def destroy_node(self):
        try:
            self.server.stop()
        finally:
            return super().destroy_node()


def main(args=None) -> int:
    return run_node(Viewer, args)


if __name__ == "__main__":
    sys.exit(main())
