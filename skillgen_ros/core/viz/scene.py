"""SceneSynthesizer: turn what the graph publishes into what Foxglove's 3D panel draws.

Inputs are plain values taken from the graph's own topics (joint states, object poses, camera
poses, the planner's path); outputs are CDR messages on the standard scene topics (SCENE_TOPICS).
The recorder writes them into the bag beside the recorded topics, and `skillgen view` serves
them live. Frames (docs/foxglove.md):
- world -> panda_link0 and the URDF's fixed joints on /tf_static; its moving joints on /tf;
- world -> <object id> (the sim's true pose) and world -> <object id>_estimate (perception's);
- world -> camera_<name>_optical (the frame of the camera's images);
- world -> planner_goal_<k>: the EE pose at the end of the k-th segment of the last planned path
  (the planner's `planner_goal` markers: retreat, transit/transfer, approach).
Not thread-safe: one thread feeds it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from .description import robot_description
from .messages import (MARKERS_TYPE, STRING_TYPE, TF_TYPE, Transform, encode_markers, encode_string,
                       encode_tf)
from .objects import object_markers
from .robot_tf import WORLD, PandaTf, joint_map, panda_tf

TF, TF_STATIC, ROBOT_DESCRIPTION, OBJECT_MARKERS = "/tf", "/tf_static", "/robot_description", "/scene/object_markers"
# topic -> (type, latched): latched topics are transient local (a late subscriber gets the last one)
SCENE_TOPICS = {TF: (TF_TYPE, False), TF_STATIC: (TF_TYPE, True), ROBOT_DESCRIPTION: (STRING_TYPE, True),
                OBJECT_MARKERS: (MARKERS_TYPE, True)}
ESTIMATE_SUFFIX = "_estimate"


@dataclass(frozen=True)
class ObjectPoseValue:
    id: str
    type: str
    position: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]


@dataclass(frozen=True)
class VizMessage:
    topic: str  # one of SCENE_TOPICS
    data: bytes  # CDR
    stamp_ns: int

    @property
    def type(self) -> str:
        return SCENE_TOPICS[self.topic][0]


def camera_frame(name: str) -> str:
    """The frame_id of a camera's images (nodes/driver_cameras.py)."""
    return f"camera_{name}_optical"


class SceneSynthesizer:
    def __init__(self, robot: PandaTf | None = None):
        self.robot = robot or panda_tf()
        self._static_sent = False
        self._objects: tuple[tuple[str, str], ...] = ()

    def reset(self) -> None:
        """A new recording: the latched topics are sent again with the next input."""
        self._static_sent, self._objects = False, ()

    def _static(self, stamp_ns: int) -> list[VizMessage]:
        if self._static_sent:
            return []
        self._static_sent = True
        return [VizMessage(ROBOT_DESCRIPTION, encode_string(robot_description()), stamp_ns),
                VizMessage(TF_STATIC, encode_tf(self.robot.transforms({}, stamp_ns, fixed=True)), stamp_ns)]

    def on_joints(self, names: Sequence[str], positions: Sequence[float], stamp_ns: int) -> list[VizMessage]:
        out = self._static(stamp_ns)
        out.append(VizMessage(TF, encode_tf(self.robot.transforms(joint_map(names, positions), stamp_ns)), stamp_ns))
        return out

    def on_objects(self, objects: Sequence[ObjectPoseValue], stamp_ns: int, estimate: bool = False) -> list[VizMessage]:
        """world -> each object; a new set of (id, type) (a reset to another task) resends the models."""
        out = self._static(stamp_ns)
        suffix = ESTIMATE_SUFFIX if estimate else ""
        if objects:
            out.append(VizMessage(TF, encode_tf([Transform(WORLD, o.id + suffix, o.position, o.quaternion, stamp_ns)
                                                 for o in objects]), stamp_ns))
        if not estimate:
            ids = tuple(sorted((o.id, o.type) for o in objects))
            if ids and ids != self._objects:
                self._objects = ids
                markers = [m for k, (oid, typ) in enumerate(ids) for m in object_markers(oid, typ, k)]
                out.append(VizMessage(OBJECT_MARKERS, encode_markers(markers, stamp_ns), stamp_ns))
        return out

    def on_camera(self, name: str, position, quaternion, stamp_ns: int) -> list[VizMessage]:
        return self._static(stamp_ns) + [VizMessage(TF, encode_tf(
            [Transform(WORLD, camera_frame(name), tuple(position), tuple(quaternion), stamp_ns)]), stamp_ns)]

    def on_path(self, goals: Sequence[tuple[Sequence[float], Sequence[float]]], stamp_ns: int) -> list[VizMessage]:
        """The planner's last path: one frame per segment goal, (position, quaternion xyzw) each."""
        if not goals:
            return []
        return self._static(stamp_ns) + [VizMessage(TF, encode_tf(
            [Transform(WORLD, f"planner_goal_{k}", tuple(p), tuple(q), stamp_ns)
             for k, (p, q) in enumerate(goals)]), stamp_ns)]
