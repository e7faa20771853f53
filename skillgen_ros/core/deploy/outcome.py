"""How an HSP rollout ends: the deployment reason codes, and planner statuses mapped onto them.

The issue's codes: OK, INITIATION_UNREACHABLE (the planner answered that the predicted initiation
pose has no collision-free IK, before anything moved), PLAN_FAILED (no path, or its execution
failed or collided), POLICY_TIMEOUT (a skill's step budget, or the rollout's, ran out before its
termination fired, and the task was not achieved), TASK_FAILED (every skill terminated but the
task check failed), BAD_CHECKPOINT, PERCEPTION_FAILED. CONTROL_FAILED is ours: the driver did not
execute a control step (a node stopped answering), which none of the issue's codes describes.
Planner statuses are classified by generation's own table (core/generation/outcome.py), so a
status means the same thing in both halves of the project.
"""
from __future__ import annotations

import enum

from ..generation.outcome import GOAL_INFEASIBLE, motion_failure


class DeployReason(str, enum.Enum):
    OK = "OK"
    INITIATION_UNREACHABLE = "INITIATION_UNREACHABLE"
    PLAN_FAILED = "PLAN_FAILED"
    POLICY_TIMEOUT = "POLICY_TIMEOUT"
    TASK_FAILED = "TASK_FAILED"
    BAD_CHECKPOINT = "BAD_CHECKPOINT"
    PERCEPTION_FAILED = "PERCEPTION_FAILED"
    CONTROL_FAILED = "CONTROL_FAILED"


def status_name(status) -> str:
    return str(getattr(status, "name", status)).upper()


def motion_reason(status, moved: bool) -> DeployReason | None:
    """Planner/executor status -> None on success; an unreachable goal (nothing moved) is
    INITIATION_UNREACHABLE, every other failure PLAN_FAILED."""
    if motion_failure(status) is None:
        return None
    if not moved and status_name(status) in GOAL_INFEASIBLE:
        return DeployReason.INITIATION_UNREACHABLE
    return DeployReason.PLAN_FAILED
