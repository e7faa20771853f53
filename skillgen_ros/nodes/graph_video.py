"""The front camera's frames of an attempt being filmed for the run's MP4 (graph mode).

Outside filmed attempts the driver renders nothing periodically (camera_hz 0 in the datagen
graph); while filming, this raises the driver's `camera_hz` parameter and collects the images,
then puts the rate back. The MP4 is an aid: a driver without the parameter gives a video of
whatever frames come.
"""
from __future__ import annotations

import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from skillgen_ros.nodes.latest import wait_future

MAX_FRAMES = 2000


class AttemptVideo:
    def __init__(self, node: Node, driver_node: str, camera_hz: float, callback_group=None):
        self.node = node
        self._params = AsyncParameterClient(node, driver_node, callback_group=callback_group) if driver_node else None
        self._hz = float(camera_hz)
        self._hz_before: float | None = None
        self._frames: list | None = None
        node.create_subscription(Image, "camera/front/image", self._on_image, qos_profile_sensor_data,
                                 callback_group=callback_group)

    def _on_image(self, m: Image):
        frames = self._frames
        if frames is not None and m.encoding in ("rgb8", "bgr8") and len(frames) < MAX_FRAMES:
            img = np.frombuffer(bytes(m.data), np.uint8).reshape(m.height, m.width, 3)
            frames.append(img[..., ::-1] if m.encoding == "bgr8" else img)

    def start(self) -> None:
        self._frames = []
        self._hz_before = self._set_camera_hz(self._hz)

    def stop(self) -> list:
        frames, self._frames = self._frames or [], None
        if self._hz_before is not None:
            self._set_camera_hz(self._hz_before)
            self._hz_before = None
        return frames

    def _set_camera_hz(self, hz: float) -> float | None:
        """Set the driver's camera_hz; returns the value it had, or None if that failed."""
        cli = self._params
        if cli is None or not cli.wait_for_services(timeout_sec=2.0):
            return None
        got = cli.get_parameters(["camera_hz"])
        if not wait_future(got, 2.0) or got.result() is None or not got.result().values:
            return None
        before = got.result().values[0].double_value
        done = cli.set_parameters([Parameter("camera_hz", value=float(hz))])
        if not wait_future(done, 2.0) or done.result() is None or not all(r.successful for r in done.result().results):
            self.node.get_logger().warning(f"could not set {cli.remote_node_name}.camera_hz for the video")
            return None
        return before
