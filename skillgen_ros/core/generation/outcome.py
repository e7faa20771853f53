"""How an attempt ends: the dataset's failure reasons, and planner/executor statuses mapped onto them."""
from __future__ import annotations

import enum


class FailureReason(str, enum.Enum):
    OK = "OK"
    PERCEPTION_FAILED = "PERCEPTION_FAILED"
    IK_FAILED = "IK_FAILED"
    PLAN_FAILED = "PLAN_FAILED"
    EXECUTION_COLLISION = "EXECUTION_COLLISION"
    SKILL_FAILED = "SKILL_FAILED"
    TASK_FAILED = "TASK_FAILED"
    TIMEOUT = "TIMEOUT"


# Planner statuses (core/planning PlanStatus: PLAN_TIMEOUT, GOAL_IN_COLLISION, ... -> PLAN_FAILED) and
# executor outcomes: a trajectory the driver could not track counts as an execution failure.
_STATUS = {"OK": None, "SUCCESS": None, "SUCCEEDED": None, "SUCCESSFUL": None, "IK_FAILED": FailureReason.IK_FAILED,
           "EXECUTION_FAILED": FailureReason.EXECUTION_COLLISION, "ABORTED": FailureReason.EXECUTION_COLLISION,
           "NO_IK": FailureReason.IK_FAILED, "IK": FailureReason.IK_FAILED,
           "COLLISION": FailureReason.EXECUTION_COLLISION, "EXECUTION_COLLISION": FailureReason.EXECUTION_COLLISION,
           "TIMEOUT": FailureReason.TIMEOUT, "TIMED_OUT": FailureReason.TIMEOUT}


def motion_failure(status) -> FailureReason | None:
    """Planner/executor status -> None on success, else the attempt's failure reason (PLAN_FAILED default)."""
    name = str(getattr(status, "name", status)).upper()
    return _STATUS.get(name, FailureReason.PLAN_FAILED)


# Planner answers that mean "this initiation pose cannot be reached" before anything moved.
GOAL_INFEASIBLE = {"GOAL_IN_COLLISION", "IK_FAILED", "NO_IK", "IK"}
