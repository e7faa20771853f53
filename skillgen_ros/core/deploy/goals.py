"""HSP-TAMP's privileged termination: each skill's goal checked on the sim's true state.

HSP-TAMP (paper Sec. 4, "HSP Variants") deploys only the learned policy pi inside HITL-TAMP
(Mandlekar et al., 2023), whose planner, not a learned classifier, decides when a skill's
effect holds and takes control back. It is the paper's privileged upper reference. We check the
effects HITL-TAMP's planner would, on ground-truth poses (never on perception):
- a skill whose motion is a transit (the hand arrives free: grasp_nut, grasp_milk, grasp_needle,
  ...): the object is grasped and lifted clear, i.e. the fingers are closed on it (commanded
  closed and stopped short of shut), it is within reach of the hand, and it rose LIFT_M above
  its resting height;
- a transfer skill (carrying the object to a fixture): the task's own placement predicate for
  that pair (core/tasks/suite.py: nut_on_peg, object_in_bin, needle_through_ring) holds, and the
  hand has been commanded open (the object is let go, so a following transit starts free).
"""
from __future__ import annotations

from typing import Callable, Mapping

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose
from ..robot import TABLE_Z
from ..tasks import suite
from ..tasks.spec import SceneState, SkillSpec, TaskSpec

LIFT_M = 0.03  # lifted clear of the table (m above the resting height)
REACH_M = 0.08  # object origin within this of the hand, beyond its own half extent
MIN_WIDTH_M = 0.002  # fingers closed on something, not on air


def _placement(task: TaskSpec, held: str, fixture: str) -> Callable[[SceneState], bool]:
    obj, fix = task.object(held), task.object(fixture)
    if "peg" in fix.type:
        return lambda p: suite.nut_on_peg(obj, fix, p)
    if fix.type == "bin":
        return lambda p: suite.object_in_bin(obj, fix, p)
    if fix.type == "tripod":
        return lambda p: suite.needle_through_ring(obj, fix, p)
    return lambda p: task.is_success(p)


def skill_goal_reached(task: TaskSpec, skill: SkillSpec, true_poses: Mapping[str, Pose], ee_pose: np.ndarray,
                       gripper_width: float, gripper_command: float,
                       joints: Mapping[str, float] | None = None) -> bool:
    """The skill's effect on the true state (see the module docstring); `joints`: articulated objects'
    joint values (Coffee's lid). Without the values a rule needs, the goal is not known to be reached: the
    skill runs on to its termination or budget, and the task's own success check decides."""
    if skill.mode == "transfer" and skill.attached_object:
        state = SceneState(dict(true_poses), np.asarray(ee_pose[:3], float), float(gripper_command), dict(joints or {}))
        try:
            return gripper_command < 0 and _placement(task, skill.attached_object, skill.object_id)(state)
        except InvalidInputError as e:
            if e.reason != "MISSING_JOINT_STATE":
                raise
            return False
    if skill.object_id not in true_poses:
        return False
    obj = task.object(skill.object_id)
    p = true_poses[skill.object_id].position
    lifted = p[2] > TABLE_Z + obj.half_extents[2] + LIFT_M
    near = np.linalg.norm(p - np.asarray(ee_pose[:3], float)) < max(obj.half_extents) + REACH_M
    return bool(gripper_command > 0 and gripper_width > MIN_WIDTH_M and lifted and near)
