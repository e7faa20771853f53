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
from .collision import AttachedObject, Box


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


def part_boxes(obj) -> list[tuple[np.ndarray, np.ndarray]]:
    """(T_object_part, half extents) per primitive part, cylinders by their bounding box; the
    object's bounding box when it has no parts."""
    if not obj.parts:
        return [(np.eye(4), np.asarray(obj.half_extents, float))]
    return [part_box(part) for part in obj.parts]


def object_boxes(obj, pose: Pose, joints: Mapping[str, float] | None = None) -> list[Box]:
    """Boxes of an object at `pose`: one per primitive part, and an articulated object's links at the
    scene's joint values ({joint_key: value}): the planner's obstacles, and what perception cuts out
    of the cloud around a fixture (perception/fixtures.py)."""
    T = pose.matrix()
    return [Box(obj.id, T @ Tp, h) for Tp, h in part_boxes(obj)] + link_boxes(obj, pose, joints)


def attached_from_parts(obj, T_ee_obj: np.ndarray, spacing: float = 0.01) -> AttachedObject:
    """A held object as spheres filling each primitive part (a nut's ring and handle, not its
    bounding box, so the hole and the space around the handle stay free for planning). A 1 cm grid
    overshoots a nut wall's faces by at most 4 mm (2 cm: 8 mm, which refused NutAssembly transfers
    starting with the held round nut a few mm from the placed square nut)."""
    spheres = [AttachedObject.from_box(obj.id, h, np.asarray(T_ee_obj) @ Tp, spacing).spheres
               for Tp, h in part_boxes(obj)]
    return AttachedObject(obj.id, np.vstack(spheres))


def box_points(boxes, spacing: float = 0.01) -> np.ndarray:
    """Points on the faces of `boxes` at most `spacing` apart: links as a cloud obstacle (a planner whose
    cloud lost them, e.g. perception's obstacle cloud, which drops a recognized object's points)."""
    out = []
    for b in boxes:
        h = np.asarray(b.half_extents, float)
        axes = [np.linspace(-x, x, max(2, int(np.ceil(2 * x / spacing)) + 1)) for x in h]
        g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        g = g[np.any(np.isclose(np.abs(g), h), axis=1)]   # the faces only
        out.append(g @ b.pose[:3, :3].T + b.pose[:3, 3])
    return np.vstack(out) if out else np.empty((0, 3))


def scene_link_boxes(articulated: Mapping[str, object], boxes: Mapping[str, Box],
                     joints: Mapping[str, float] | None, skip: str | None = None) -> list[Box]:
    """Link boxes of the articulated objects ({id: ObjectSpec}) placed at their scene boxes' poses (the
    object frame) and the joint values; `skip` (the held object) and objects without a box get none."""
    return [b for oid, obj in articulated.items() if oid in boxes and oid != skip
            for b in link_boxes(obj, Pose.from_matrix(boxes[oid].pose), joints)]


def support_below(boxes, centre, depth: float = 0.15) -> str | None:
    """The name of the box right below `centre` (within `depth`): what an object there rests on (a peg, a bin,
    a drawer's tray; the table is not a box). The highest such top wins."""
    best, best_top = None, -np.inf
    c = np.asarray(centre, float)
    for b in boxes:
        local = (c - b.pose[:3, 3]) @ b.pose[:3, :3]
        top = b.pose[2, 3] + np.abs(b.pose[2, :3]) @ b.half_extents
        if np.all(np.abs(local[:2]) <= b.half_extents[:2] + 0.01) and c[2] - depth < top < c[2] + 0.01 and top > best_top:
            best, best_top = b.name, top
    return best
