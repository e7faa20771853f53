"""How an attempt ends: the dataset's failure reasons, planner/executor statuses mapped onto them, and the
two exceptions that end an attempt early (a failure, which is recorded; a stop, which is not)."""
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


class AttemptAborted(Exception):
    """A stop (a canceled goal, Ctrl-C, a distributed run's stop) abandoned the attempt in flight.

    Not a SkillGenError, so no in-attempt handler turns it into a failure: the attempt is not
    written, and a resumed run (or the next --first-index) runs its index again."""

    def __init__(self, reason: str):
        super().__init__(f"attempt abandoned: {reason}")
        self.reason = reason


class AttemptFailed(Exception):
    """Raised inside an attempt (attempt.py, remote_skill.py); run_attempt turns it into the result's
    reason and message. goal_infeasible: the planner refused the goal before anything moved, so the
    next initiation candidate may be tried."""

    def __init__(self, reason: FailureReason, message: str, goal_infeasible: bool = False):
        super().__init__(message)
        self.reason = reason
        self.goal_infeasible = goal_infeasible


# Planner answers that mean "this initiation pose cannot be reached" before anything moved.
GOAL_INFEASIBLE = {"GOAL_IN_COLLISION", "IK_FAILED", "NO_IK", "IK"}
