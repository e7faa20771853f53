"""The robot driver's cameras as ROS topics (image, depth, camera_info, pose, points per camera).

A render costs more than a control period's physics, so a camera renders only when one of its
topics has a reader, and periodically only every `camera_hz` of (sim) time; frames also come on
demand (reset_scene, capture_cameras). The driver (driver_base.py) owns the world and the clock
and calls `publish(...)` with the stamp to use.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from skillgen_ros.core.errors import ParameterError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.sim.camera import CameraConfig
from skillgen_ros.nodes import convert


class DriverCameras:
    def __init__(self, names: list[str], frame: str, control_hz: float, camera_hz, make_pub: Callable):
        """make_pub(type, topic, qos) creates a publisher on the driver node."""
        self.names, self.frame, self.control_hz = list(names), frame, float(control_hz)
        self.every = self.periods_per_frame(camera_hz)
        qos = qos_profile_sensor_data
        self.pubs = {n: {"points": make_pub(convert.PointCloud2, f"camera/{n}/points", qos),
                         "image": make_pub(Image, f"camera/{n}/image", qos),
                         "depth": make_pub(Image, f"camera/{n}/depth", qos),
                         "camera_info": make_pub(CameraInfo, f"camera/{n}/camera_info", qos),
                         "pose": make_pub(PoseStamped, f"camera/{n}/pose", qos)}
                     for n in self.names}

    def periods_per_frame(self, camera_hz) -> int:
        """Control periods per periodic frame (0: none); ParameterError if camera_hz is bad."""
        hz = float(camera_hz)
        if not hz >= 0 or hz == float("inf"):
            raise ParameterError(f"camera_hz must be a finite value >= 0, got {camera_hz}")
        return max(1, int(round(self.control_hz / hz))) if hz > 0 else 0

    def due(self, period: int) -> bool:
        """Whether control period `period` gets a periodic frame."""
        return bool(self.every) and period % self.every == 0

    def publish(self, world, stamp, points: bool, only_read: bool = True) -> None:
        """Render and publish every camera (with `only_read`, those with a reader) at `stamp`."""
        for n in self.names:
            if not only_read or any(p.get_subscription_count() for p in self.pubs[n].values()):
                self._publish_one(world, n, stamp, points)

    def _publish_one(self, world, name: str, stamp, points: bool) -> None:
        f = world.render(name)
        pubs, h, wd = self.pubs[name], f.depth.shape[0], f.depth.shape[1]
        optical = Header(frame_id=f"camera_{name}_optical", stamp=stamp)
        pubs["image"].publish(Image(header=optical, height=h, width=wd, encoding="rgb8", step=3 * wd,
                                    data=np.ascontiguousarray(f.rgb, np.uint8).tobytes()))
        pubs["depth"].publish(Image(header=optical, height=h, width=wd, encoding="32FC1", step=4 * wd,
                                    data=np.ascontiguousarray(f.depth, np.float32).tobytes()))
        K = f.K
        P = np.hstack([K, np.zeros((3, 1))])
        pubs["camera_info"].publish(CameraInfo(header=optical, height=h, width=wd, distortion_model="plumb_bob",
                                               d=[0.0] * 5, k=K.reshape(-1).tolist(), r=np.eye(3).reshape(-1).tolist(),
                                               p=P.reshape(-1).tolist()))
        pubs["pose"].publish(convert.pose_stamped(Pose.from_matrix(f.T_world_camera), self.frame, stamp))
        if points:
            pts = f.points_world
            organized = pts.shape[:2] if pts.ndim == 3 else None
            rgb = f.rgb.reshape(-1, 3) if organized else None
            pubs["points"].publish(convert.points_to_cloud(pts.reshape(-1, 3), self.frame, stamp, rgb=rgb,
                                                           organized_shape=organized))


def camera_configs(param) -> tuple[CameraConfig, ...]:
    """CameraConfig per name in the `cameras` parameter, from the <name>_* parameters."""
    out = []
    for n in param("cameras"):
        if not n:
            continue
        if n not in ("front", "wrist"):
            raise ParameterError(f"unknown camera {n!r} (front, wrist)")
        out.append(CameraConfig(n, int(param(f"{n}_width")), int(param(f"{n}_height")), float(param(f"{n}_fov_deg")),
                                noise_base=float(param("depth_noise_base")),
                                noise_quadratic=float(param("depth_noise_quadratic")),
                                dropout=float(param("depth_dropout"))))
    return tuple(out)
