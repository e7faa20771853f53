"""Message <-> core conversions, in one place, tested as round trips (test/test_convert.py).

Nodes call these; the core never sees a message type. PointCloud2 packing is written here with
numpy structured arrays because sensor_msgs_py is not available from PyPI.
"""
from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Pose as PoseMsg, PoseStamped, Quaternion, Vector3, Wrench, WrenchStamped
from sensor_msgs.msg import JointState, PointCloud2, PointField
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from skillgen_ros.core.geometry import Pose


def pose_to_msg(p: Pose) -> PoseMsg:
    x, y, z = (float(v) for v in p.position)
    qx, qy, qz, qw = (float(v) for v in p.quaternion)
    return PoseMsg(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def pose_from_msg(m: PoseMsg) -> Pose:
    """No validation here: callers that accept user input use core.geometry.validate_pose."""
    return Pose(np.array([m.position.x, m.position.y, m.position.z]),
                np.array([m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w]))


def pose_arrays_from_msg(m: PoseMsg) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([m.position.x, m.position.y, m.position.z]),
            np.array([m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w]))


def pose_stamped(p: Pose, frame_id: str, stamp) -> PoseStamped:
    return PoseStamped(header=Header(frame_id=frame_id, stamp=stamp), pose=pose_to_msg(p))


def wrench_stamped(w: np.ndarray, frame_id: str, stamp) -> WrenchStamped:
    """(6,) force, torque -> WrenchStamped."""
    f, t = (Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2])) for v in (w[:3], w[3:]))
    return WrenchStamped(header=Header(frame_id=frame_id, stamp=stamp), wrench=Wrench(force=f, torque=t))


def wrench_from_msg(m: WrenchStamped) -> np.ndarray:
    f, t = m.wrench.force, m.wrench.torque
    return np.array([f.x, f.y, f.z, t.x, t.y, t.z], float)


def joint_state(names, positions, velocities=None, efforts=None, frame_id: str = "", stamp=None) -> JointState:
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.name = list(names)
    msg.position = [float(v) for v in positions]
    msg.velocity = [float(v) for v in velocities] if velocities is not None else []
    msg.effort = [float(v) for v in efforts] if efforts is not None else []
    return msg


def seconds_to_duration(t: float) -> Duration:
    ns = int(round(t * 1e9))  # rounded once: 1.9999999999 s is 2 s (not 1 s + a nanosec field wrapped to 0)
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def duration_to_seconds(d: Duration) -> float:
    return d.sec + d.nanosec * 1e-9


def trajectory_to_msg(joint_names, times, positions, velocities=None, accelerations=None,
                      frame_id: str = "") -> JointTrajectory:
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    msg.joint_names = list(joint_names)
    for i, t in enumerate(times):
        pt = JointTrajectoryPoint()
        pt.positions = [float(v) for v in positions[i]]
        if velocities is not None:
            pt.velocities = [float(v) for v in velocities[i]]
        if accelerations is not None:
            pt.accelerations = [float(v) for v in accelerations[i]]
        pt.time_from_start = seconds_to_duration(float(t))
        msg.points.append(pt)
    return msg


def trajectory_from_msg(msg: JointTrajectory):
    """-> (joint_names, times (N,), positions (N,J), velocities (N,J) or None)."""
    times = np.array([duration_to_seconds(p.time_from_start) for p in msg.points])
    pos = np.array([list(p.positions) for p in msg.points], dtype=float).reshape(len(msg.points), -1)
    vel = None
    if msg.points and all(len(p.velocities) == len(msg.joint_names) for p in msg.points):
        vel = np.array([list(p.velocities) for p in msg.points], dtype=float)
    return list(msg.joint_names), times, pos, vel


_XYZ_FIELDS = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate("xyz")]
_RGB_FIELD = PointField(name="rgb", offset=12, datatype=PointField.FLOAT32, count=1)


def points_to_cloud(points: np.ndarray, frame_id: str, stamp=None, rgb: np.ndarray | None = None,
                    organized_shape: tuple[int, int] | None = None) -> PointCloud2:
    """(N,3) float points (NaN allowed for organized clouds) [+ (N,3) uint8 colours] -> PointCloud2."""
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    n = len(pts)
    if rgb is None:
        data = pts
        fields, step = _XYZ_FIELDS, 12
    else:
        c = np.asarray(rgb, dtype=np.uint8).reshape(-1, 3).astype(np.uint32)
        packed = ((c[:, 0] << 16) | (c[:, 1] << 8) | c[:, 2]).view(np.float32)
        data = np.concatenate([pts, packed[:, None]], axis=1)
        fields, step = _XYZ_FIELDS + [_RGB_FIELD], 16
    msg = PointCloud2()
    msg.header.frame_id = frame_id
    if stamp is not None:
        msg.header.stamp = stamp
    if organized_shape is not None:
        msg.height, msg.width = organized_shape
    else:
        msg.height, msg.width = 1, n
    msg.fields = fields
    msg.is_bigendian = False
    msg.point_step = step
    msg.row_step = step * msg.width
    msg.is_dense = bool(np.all(np.isfinite(pts)))
    msg.data = np.ascontiguousarray(data, dtype=np.float32).tobytes()
    return msg


def cloud_to_points(msg: PointCloud2) -> np.ndarray:
    """PointCloud2 with float32 x, y, z fields (any extra fields, any point_step) -> (N,3) float64."""
    offs = {f.name: f.offset for f in msg.fields}
    if not {"x", "y", "z"} <= offs.keys():
        raise ValueError(f"PointCloud2 lacks x/y/z fields (has {sorted(offs)})")
    n = msg.width * msg.height
    if n == 0:
        return np.zeros((0, 3))
    dtype = np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3,
                      "offsets": [offs["x"], offs["y"], offs["z"]], "itemsize": msg.point_step})
    buf = np.frombuffer(bytes(msg.data), dtype=dtype, count=n)
    return np.stack([buf["x"], buf["y"], buf["z"]], axis=1).astype(np.float64)
