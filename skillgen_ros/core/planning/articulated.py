"""Articulated objects as planner obstacles: each link's parts as boxes posed by its joint values.

A coffee machine's lid is an obstacle where it is now: closed over the pod holder it blocks the
hand's way in, open (120 deg) it stands behind the hinge. The values come from the scene (the sim's
joint state, the driver's `object_joint_states`), keyed as core/tasks/articulation.joint_key; a joint
without a value is at its spec's reset value. Boxes carry the object's id, so the allowed contacts
of a skill on the object (AllowedContacts.hand_object) cover its links too.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..geometry import Pose
from ..tasks.articulation import joint_key, link_frames
from .collision import Box


def part_box(part) -> tuple[np.ndarray, np.ndarray]:
    """(T_frame_part, half extents) of one primitive, a cylinder by its bounding box."""
    h = part.size if part.kind == "box" else (part.size[0], part.size[0], part.size[1])
    return Pose(part.position, part.quaternion).matrix(), np.asarray(h, float)


def link_boxes(obj, pose: Pose, joints: Mapping[str, float] | None = None) -> list[Box]:
    """Boxes of every link of `obj` at object pose `pose` and the scene's joint values."""
    if not obj.joints:
        return []
    joints = joints or {}
    values = {j.name: float(joints.get(joint_key(obj.id, j.name), j.initial)) for j in obj.joints}
    frames = link_frames(obj, pose, values)
    out = []
    for link in obj.links:
        for part in link.parts:
            Tp, h = part_box(part)
            out.append(Box(obj.id, frames[link.name] @ Tp, h))
    return out
