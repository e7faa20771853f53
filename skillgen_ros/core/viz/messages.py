"""CDR encoding of the scene messages with rosbags' ROS 2 Jazzy typestore.

rclpy cannot build a tf2_msgs/msg/TFMessage here (tf2_msgs is not on PyPI), but rosbags ships
the Jazzy definitions of tf2_msgs, visualization_msgs and std_msgs: encoding with them gives the
bytes a ROS 2 publisher would send, under the standard type names, and the schema written into
the bag is the same store's `generate_msgdef` (core/bag/schemas.py falls back to it).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from rosbags.typesys import Stores, get_typestore

TF_TYPE = "tf2_msgs/msg/TFMessage"
STRING_TYPE = "std_msgs/msg/String"
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"


@functools.lru_cache(maxsize=1)
def store():
    """The rosbags typestore of ROS 2 Jazzy's standard messages."""
    return get_typestore(Stores.ROS2_JAZZY)


def _t(name: str):
    return store().types[name]


@dataclass(frozen=True)
class Transform:
    """One edge of the TF tree: `child` in `parent` at `stamp_ns` (position xyz, quaternion xyzw)."""

    parent: str
    child: str
    position: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]
    stamp_ns: int = 0


def _time(ns: int):
    ns = max(0, int(ns))
    return _t("builtin_interfaces/msg/Time")(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _header(frame: str, ns: int):
    return _t("std_msgs/msg/Header")(stamp=_time(ns), frame_id=frame)


def _vec(v, name="geometry_msgs/msg/Vector3"):
    return _t(name)(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _quat(q):
    return _t("geometry_msgs/msg/Quaternion")(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _pose(position, quaternion):
    return _t("geometry_msgs/msg/Pose")(position=_vec(position, "geometry_msgs/msg/Point"),
                                        orientation=_quat(quaternion))


def encode_tf(transforms: Sequence[Transform]) -> bytes:
    """tf2_msgs/msg/TFMessage (CDR) holding `transforms`."""
    ts = [_t("geometry_msgs/msg/TransformStamped")(
        header=_header(t.parent, t.stamp_ns), child_frame_id=t.child,
        transform=_t("geometry_msgs/msg/Transform")(translation=_vec(t.position), rotation=_quat(t.quaternion)))
        for t in transforms]
    return bytes(store().serialize_cdr(_t(TF_TYPE)(transforms=ts), TF_TYPE))


def encode_string(text: str) -> bytes:
    return bytes(store().serialize_cdr(_t(STRING_TYPE)(data=text), STRING_TYPE))


@dataclass(frozen=True)
class MarkerSpec:
    """One visualization_msgs/Marker: a primitive (kind CUBE/CYLINDER/SPHERE/LINE_STRIP/...) in `frame`."""

    ns: str
    id: int
    kind: str
    frame: str
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quaternion: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)
    points: tuple[tuple[float, float, float], ...] = ()
    text: str = ""


def encode_markers(markers: Sequence[MarkerSpec], stamp_ns: int = 0, delete_all_first: bool = True) -> bytes:
    """visualization_msgs/msg/MarkerArray (CDR); frame_locked, so a marker moves with its TF frame."""
    M = _t("visualization_msgs/msg/Marker")
    color = _t("std_msgs/msg/ColorRGBA")
    empty = dict(lifetime=_t("builtin_interfaces/msg/Duration")(sec=0, nanosec=0), colors=[],
                 texture_resource="", texture=_t("sensor_msgs/msg/CompressedImage")(
                     header=_header("", 0), format="", data=np.zeros(0, np.uint8)),
                 uv_coordinates=[], mesh_resource="",
                 mesh_file=_t("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, np.uint8)),
                 mesh_use_embedded_materials=False)
    out = []
    if delete_all_first:
        out.append(M(header=_header("", stamp_ns), ns="", id=0, type=0, action=M.DELETEALL,
                     pose=_pose((0, 0, 0), (0, 0, 0, 1)), scale=_vec((1, 1, 1)), color=color(r=0., g=0., b=0., a=0.),
                     frame_locked=False, points=[], text="", **empty))
    for m in markers:
        out.append(M(header=_header(m.frame, stamp_ns), ns=m.ns, id=int(m.id), type=int(getattr(M, m.kind)),
                     action=M.ADD, pose=_pose(m.position, m.quaternion), scale=_vec(m.scale),
                     color=color(r=float(m.color[0]), g=float(m.color[1]), b=float(m.color[2]), a=float(m.color[3])),
                     frame_locked=True, points=[_vec(p, "geometry_msgs/msg/Point") for p in m.points],
                     text=m.text, **empty))
    return bytes(store().serialize_cdr(_t(MARKERS_TYPE)(markers=out), MARKERS_TYPE))


def decode(data: bytes, type_name: str):
    """rosbags message object from CDR (tests and the live view use it to read back)."""
    return store().deserialize_cdr(bytes(data), type_name)
