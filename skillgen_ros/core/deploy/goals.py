"""HSP-TAMP's privileged termination: each skill's goal checked on the sim's true state.

HSP-TAMP (paper Sec. 4, "HSP Variants") deploys only the learned policy pi inside HITL-TAMP
(Mandlekar et al., 2023), whose planner, not a learned classifier, decides when a skill's
effect holds and takes control back. It is the paper's privileged upper reference. We check the
effects HITL-TAMP's planner would, on ground-truth poses (never on perception):
- a skill whose motion is a transit (the hand arrives free: grasp_nut, grasp_milk, grasp_needle,
  ...): the object is grasped, i.e. the hand has been commanded closed for CLOSE_PERIODS steps
  (when the env's grasp tracker attaches the object, core/generation/grasp.py), the fingers have
  stopped (moved less than SETTLED_M since the last step) short of shut, and the object is within
  reach of the hand. Lifting it is the next motion's (the transfer's retreat), as in HITL-TAMP, where
  the planner takes over once the grasp holds: our skill segments, and so pi's training data,
  end `post_steps` (10) after the close (core/skills/auto_annotation.py) with the object still
  on the table (Square D1: 2 mm up). Requiring a 3 cm lift, as this module first did, never
  fired, and every grasp ran pi to its 400-step budget, off its data;
- a transfer skill (carrying the object to a fixture): the task's own placement predicate for
  that pair (core/tasks/suite.py: nut_on_peg, object_in_bin, needle_through_ring) holds, and the
  hand has been commanded open (the object is let go, so a following transit starts free).
"""
from __future__ import annotations

from typing import Callable, Mapping

import numpy as np

from ..errors import InvalidInputError
from ..generation.grasp import CLOSE_PERIODS
from ..geometry import Pose
from ..tasks import suite
from ..tasks.spec import SceneState, SkillSpec, TaskSpec

SETTLED_M = 0.0005  # fingers moved less than this (m, both together) since the last step: the grasp holds
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
                       joints: Mapping[str, float] | None = None, gripper_width_change: float = 0.0,
                       closed_steps: int = CLOSE_PERIODS) -> bool:
    """The skill's effect on the true state (see the module docstring); `joints`: articulated objects'
    joint values (Coffee's lid). Without the values a rule needs, the goal is not known to be reached: the
    skill runs on to its termination or budget, and the task's own success check decides.
    `gripper_width_change`: width - the width one control step earlier (a grasp holds once it is ~0);
    `closed_steps`: control steps the hand has been commanded closed without a break."""
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
    settled = abs(gripper_width_change) < SETTLED_M
    near = np.linalg.norm(p - np.asarray(ee_pose[:3], float)) < max(obj.half_extents) + REACH_M
    closed = gripper_command > 0 and closed_steps >= CLOSE_PERIODS
    return bool(closed and gripper_width > MIN_WIDTH_M and settled and near)
