"""Typed errors with reason codes.

Every failure a user can cause (bad bag, NaN pose, unknown task, invalid parameter) raises a
`SkillGenError` subclass carrying a stable `reason` code, so nodes can report it in a response
field and tests can assert on it. Never `assert` for input validation: asserts vanish under -O.
"""
from __future__ import annotations


class SkillGenError(Exception):
    """Base error. `reason` is a stable UPPER_SNAKE code; the message says what and where."""

    reason: str = "ERROR"

    def __init__(self, message: str, reason: str | None = None):
        super().__init__(message)
        if reason is not None:
            self.reason = reason

    def __str__(self) -> str:  # "REASON: message" reads well in logs and CLI output
        return f"{self.reason}: {self.args[0]}"


class InvalidInputError(SkillGenError):
    reason = "INVALID_INPUT"


class UnknownTaskError(SkillGenError):
    reason = "UNKNOWN_TASK"


class UnknownVariantError(SkillGenError):
    reason = "UNKNOWN_VARIANT"


class BagError(SkillGenError):
    reason = "BAD_BAG"


class AnnotationError(SkillGenError):
    reason = "BAD_ANNOTATION"


class ParameterError(SkillGenError):
    reason = "INVALID_PARAMETER"


class NoAnswerError(SkillGenError):
    """A node of the graph did not answer in time (killed, crashed, restarting, or overloaded): the
    attempt in flight fails with this reason, the run goes on (issue 19, chaos). Never a request error."""

    reason = "TIMEOUT"


class CheckpointError(SkillGenError):
    """A policy checkpoint that is missing, unreadable, not ours, or for another task/observation layout."""

    reason = "BAD_CHECKPOINT"
