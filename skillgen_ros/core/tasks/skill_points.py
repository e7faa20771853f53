"""Where the hand works on each skill's object: one keypoint per (task, skill), in the object frame.

A nut is grasped by its handle, not its centre; a peg is approached at its top; the milk carton
at its top, the bin at its floor, the needle at its handle, the tripod at its ring, an assembly piece 2 cm under its top and
the piece below it at its top, the coffee pod 8 mm under its top and the machine at its pod holder's rim. One table,
read by auto-annotation (the point a skill's start is measured to, cli/annotate.py), by teleop's
status line (the distance from the hand to the next object of interest) and by the grasp
pictures in docs/teleop.md (scripts/teleop_grasps.py).
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose

# task -> keypoint name per skill index (the skill's object is the task's SkillSpec.object_id)
SKILL_POINTS: dict[str, tuple[str, ...]] = {
    "Square": ("handle", "top"),
    "NutAssembly": ("handle", "top", "handle", "top"),
    "PickPlace": ("top", "floor_center"),
    "Threading": ("handle", "ring_center"),
    "ThreePieceAssembly": ("grasp", "top", "grasp", "top"),
    "Coffee": ("grasp", "holder_top"),
    # the mug on its axis 1.2 cm under the rim (grasped across its body), then the machine's drip base; the
    # drawer at its handle (closed, as a reset leaves it), the pod 8 mm under its top, the machine at its pod
    # holder's rim
    "CoffeePreparation": ("grasp", "base_top", "handle", "grasp", "holder_top"),
}


def skill_point_name(task, index: int) -> str:
    """The keypoint of skill `index` of `task` (a TaskSpec)."""
    names = SKILL_POINTS.get(task.name)
    if names is None or not 0 <= index < len(names):
        raise InvalidInputError(f"no skill point for task {task.name!r} skill {index}", reason="UNKNOWN_SKILL")
    return names[index]


def skill_point_offset(task, index: int) -> np.ndarray:
    """Skill `index`'s point in its object's frame."""
    sk = task.skills[index]
    return task.object(sk.object_id).keypoint(skill_point_name(task, index))


def skill_point_world(task, index: int, object_pose: Pose) -> np.ndarray:
    """Skill `index`'s point in the world, given its object's pose."""
    return object_pose.matrix()[:3, :3] @ skill_point_offset(task, index) + np.asarray(object_pose.position, float)
