"""Where a grasped object is: the paper's rigid-attachment assumption, without ground truth.

Perception sees an object on the table before its grasp skill (Algorithm 1 estimates before each
skill). When the gripper closes, the object stops moving relative to the hand, so its pose from
then on is T_W^O(t) = T_W^E(t) (T_W^E(grasp))^-1 T_W^O(estimate). Transfer planning uses this to
attach the object to the hand and to filter its points out of the obstacle cloud.
"""
from __future__ import annotations

import numpy as np

from ..geometry import Pose, invert


class GraspTracker:
    def __init__(self):
        self._in_hand: dict[str, np.ndarray] = {}  # object id -> T_E^O (object in the EE frame)

    def clear(self) -> None:
        self._in_hand.clear()

    def grasped(self, object_id: str, T_W_O_before: np.ndarray, T_W_E_at_grasp: np.ndarray) -> None:
        self._in_hand = {object_id: invert(np.asarray(T_W_E_at_grasp, float)) @ np.asarray(T_W_O_before, float)}

    def released(self) -> None:
        self._in_hand.clear()

    def holding(self) -> str | None:
        return next(iter(self._in_hand), None)

    def object_in_ee(self, object_id: str) -> np.ndarray | None:
        return self._in_hand.get(object_id)

    def pose_now(self, object_id: str, T_W_E_now: np.ndarray) -> Pose | None:
        T = self._in_hand.get(object_id)
        return None if T is None else Pose.from_matrix(np.asarray(T_W_E_now, float) @ T)


def grasp_step(gripper_commands: np.ndarray) -> int | None:
    """Index of the step where the gripper command last switched from open (<= 0) to closed (> 0)
    and stayed closed to the end; None if the hand ends open."""
    g = np.asarray(gripper_commands, float)
    if len(g) == 0 or g[-1] <= 0:
        return None
    opened = np.flatnonzero(g <= 0)
    return int(opened[-1] + 1) if len(opened) else 0


# -- transfer skills carry the object, not the hand ------------------------------------------
# SkillGen replays a transfer skill as T_W^{A'} = T_W^{O'} T_O^A: the hand repeats the demo's
# motion relative to the target object (the peg). The held object lands where the demo put it only
# if it sits in the hand as it did in the demo; action noise on the grasp shifts it by millimetres
# and degrees (Square: a 6 deg yaw, 6 cm out from the fingers, sets the nut on the peg's top
# instead of around it). With the object in the hand now (T_E^H, from the attempt's grasp) and in
# the demo (T_E^H_demo, from the demo's grasp skill), every target becomes T_W^{A'} C with
# C = T_E^H_demo (T_E^H)^-1, so that T_W^{A'} C T_E^H = T_W^{O'} T_O^A T_E^H_demo: the held
# object, not the hand, follows the demo. Offsets beyond the limits below are not noise (a wrong
# estimate, another grasp), and are left alone.
MAX_CORRECTION_M = 0.02
MAX_CORRECTION_RAD = 0.35


def object_in_hand(T_W_E_close: np.ndarray, T_W_O_before: np.ndarray) -> np.ndarray:
    """T_E^H at a grasp: the object's pose before its grasp skill (the estimate the skill was
    replayed in) in the frame of the hand when the close command went out. The same on both sides
    of the correction -- the demo's (demo_object_in_hand) and the attempt's -- so the object's
    settling as the fingers close, alike in both, cancels."""
    return invert(np.asarray(T_W_E_close, float)) @ np.asarray(T_W_O_before, float)


def demo_object_in_hand(demo, task, skill_index: int) -> np.ndarray | None:
    """T_E^H in `demo` for the object that `skill_index` (a transfer skill) carries: its grasp
    skill's EE pose at the close command (before any lift), relative to the object's pose before
    that skill, inverted. None if the skill carries nothing or the demo's grasp skill does not end
    closed."""
    skills = sorted(task.skills, key=lambda s: s.index)
    skill = next((s for s in skills if s.index == skill_index), None)
    held = getattr(skill, "attached_object", None) if skill is not None else None
    if skill is None or skill.mode != "transfer" or not held:
        return None
    grasp = next((s for s in reversed(skills) if s.index < skill_index and s.object_id == held), None)
    if grasp is None:
        return None
    seg = demo.skill(grasp.index)
    k = grasp_step(seg.gripper)
    if k is None:
        return None
    return object_in_hand(seg.ee_poses_in_object[k], np.eye(4))  # the segment is in the object's frame


def in_hand_correction(T_E_H_demo: np.ndarray | None, T_E_H_now: np.ndarray | None) -> np.ndarray:
    """C = T_E^H_demo (T_E^H_now)^-1, the right factor on a transfer skill's targets; the identity
    when either is unknown or the offset is beyond MAX_CORRECTION_M / MAX_CORRECTION_RAD."""
    if T_E_H_demo is None or T_E_H_now is None:
        return np.eye(4)
    C = np.asarray(T_E_H_demo, float) @ invert(np.asarray(T_E_H_now, float))
    angle = float(np.arccos(np.clip((np.trace(C[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)))
    if not np.all(np.isfinite(C)) or np.linalg.norm(C[:3, 3]) > MAX_CORRECTION_M or angle > MAX_CORRECTION_RAD:
        return np.eye(4)
    return C
