"""Graph mode's skill replay: the skill_replay node runs a skill and this records what it executed.

The node streams the same plan_replay + make_action steps the in-process path runs (attempt.py
`skillgen_skill`) and returns every step it sent, with the observations it saw; they are recorded
exactly as local steps would be, so a dataset does not show which path made it.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from ..errors import SkillGenError
from ..geometry import Pose
from ..skills.protocols import SkillLike
from .episode import Observation, StepLabel
from .outcome import AttemptFailed, FailureReason

if TYPE_CHECKING:
    from .attempt import _Attempt


def run_remote_skill(att: _Attempt, skill: SkillLike, j: int, T_W_O: np.ndarray, goal7: np.ndarray) -> None:
    """Run skill `skill.index` of source demo j on the skill_replay node and record its steps."""
    att._budget()
    t = time.perf_counter()
    seed = int(att.rng_noise.integers(2**63 - 1))
    try:
        steps, ok, reason, message = att.env.replay_skill(skill.index, j, T_W_O, att.cfg.action_noise,
                                                          att.cfg.augment, seed)
    except (SkillGenError, TimeoutError) as e:
        why = FailureReason.TIMEOUT if getattr(e, "reason", "") == "TIMEOUT" else FailureReason.SKILL_FAILED
        raise AttemptFailed(why, f"skill {skill.index} replay: {e}") from e
    finally:
        att._timed("skill", t)
    objects = dict(att.obs.object_poses)
    beliefs, stamps, truth, joints = (steps.get(k) for k in ("object_poses", "stamps_ns", "true_object_poses",
                                                             "object_joints"))
    fingers = steps.get("fingers", np.repeat(np.asarray(steps["gripper_widths"])[:, None] / 2, 2, axis=1))
    for k in range(len(steps["actions"])):  # per step what the env has: stamps, the sim's truth, beliefs
        obs = Observation(ee_pose=steps["ee_poses"][k], gripper=fingers[k],
                          joint_positions=steps["joint_positions"][k],
                          object_poses=beliefs[k] if beliefs is not None else objects,
                          true_object_poses=truth[k] if truth is not None else None,
                          object_joints=joints[k] if joints is not None else None,
                          stamp_ns=int(stamps[k]) if stamps is not None else None)
        att.rec.add(obs, steps["actions"][k], steps["actions_abs"][k][:7], float(steps["actions_abs"][k][7]),
                    StepLabel(False, skill.index, j, goal7, bool(steps["recovery"][k])))
        att.gripper = float(steps["actions_abs"][k][7])
    if len(steps["actions"]):  # the last pose sent (with its noise): the release's drift reference
        att.last_target = Pose.from_array(steps["actions_abs"][-1][:7]).matrix()
    att.obs = att.env.observe()
    if not ok:
        why = FailureReason.TIMEOUT if reason == "TIMEOUT" else FailureReason.SKILL_FAILED
        raise AttemptFailed(why, f"skill {skill.index} replay failed: {reason}: {message}")
    att._budget()
