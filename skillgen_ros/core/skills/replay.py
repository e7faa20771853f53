"""What a skill replay streams: the transformed segment, optionally after a recovery segment.

Shared by the skill_replay node and in-process generation so both replay identically:
targets T_W^{A_t'} = T_W^{O'} T_O^{A_t}; with initiation augmentation the robot starts at a
perturbed pose, so a recovery segment from the current end-effector pose back to the segment's
initiation pose T_W^{E_0'} goes first (gripper held at the segment's first command, no noise).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .augmentation import AugmentationConfig, recovery_segment
from .segment import SkillSegment


@dataclass(frozen=True)
class ReplayPlan:
    targets: np.ndarray  # (K,4,4) absolute EE targets, world frame
    gripper: np.ndarray  # (K,) gripper commands
    recovery: np.ndarray  # (K,) True for recovery-segment steps (no action noise on these)
    initiation: np.ndarray  # (4,4) T_W^{E_0'}


def plan_replay(segment: SkillSegment, T_W_O: np.ndarray, current_ee: np.ndarray | None = None,
                recovery: bool = False, config: AugmentationConfig = AugmentationConfig()) -> ReplayPlan:
    targets = segment.actions_in_world(T_W_O)
    gripper = np.asarray(segment.gripper, float)
    init = segment.initiation_in_world(T_W_O)
    rec = np.zeros(len(targets), bool)
    if recovery and current_ee is not None:
        back = recovery_segment(np.asarray(current_ee, float), init, config)
        targets = np.concatenate([back, targets])
        gripper = np.concatenate([np.full(len(back), gripper[0]), gripper])
        rec = np.concatenate([np.ones(len(back), bool), rec])
    return ReplayPlan(targets, gripper, rec, init)
