"""The little this lane needs from a task (core/tasks' TaskSpec satisfies it structurally)."""
from __future__ import annotations

from typing import Protocol, Sequence


class SkillLike(Protocol):
    index: int
    object_id: str
    name: str
    mode: str  # "transit" or "transfer": the motion that precedes the skill
    attached_object: str | None


class ObjectLike(Protocol):
    id: str


class TaskLike(Protocol):
    name: str
    objects: Sequence[ObjectLike]
    skills: Sequence[SkillLike]


def known_object_ids(task: TaskLike) -> set[str]:
    """Every object id the task can mention, the clutter obstacle included when it has one."""
    ids = {o.id for o in task.objects}
    obstacle = getattr(task, "obstacle", None)
    if obstacle is not None:
        ids.add(obstacle.id)
    return ids
