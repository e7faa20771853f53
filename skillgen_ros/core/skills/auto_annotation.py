"""Propose skill annotations from a demo's arrays: gripper events + end-effector proximity.

A skill starts when the end effector first comes within `start_distance` of a point on the
skill object (object-frame `offset`, e.g. a nut's handle), minus `pre_steps`. It ends
`post_steps` after its gripper event: a close for skills reached by transit (grasps), an open
for skills reached by transfer (placements), or when the end effector leaves the object, or at
the end of the demo. Rules are configurable per task and per skill; a person then fixes the
rest with overrides (annotation.apply_overrides).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ..errors import AnnotationError
from .annotation import Annotation, SkillAnnotation, derive_motions, validate_annotation
from .protocols import TaskLike

END_EVENTS = ("auto", "close", "open", "leave", "demo_end")


@dataclass(frozen=True)
class SkillRule:
    start_distance: float = 0.10  # m between the EE and the object point that starts the skill
    end_event: str = "auto"  # auto: "close" after transit, "open" after transfer
    pre_steps: int = 0
    post_steps: int = 10
    end_distance: float = 0.15  # m, for end_event "leave"
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # object-frame point to measure to

    def __post_init__(self):
        if self.end_event not in END_EVENTS:
            raise AnnotationError(f"unknown end_event {self.end_event!r}; known: {END_EVENTS}", reason="BAD_RULES")
        if self.start_distance <= 0 or self.end_distance <= 0 or self.pre_steps < 0 or self.post_steps < 0:
            raise AnnotationError(f"annotation rule values must be positive: {self}", reason="BAD_RULES")


@dataclass(frozen=True)
class AnnotationRules:
    default: SkillRule = SkillRule()
    per_skill: dict = field(default_factory=dict)  # skill index -> SkillRule
    gripper_threshold: float = 0.0  # command > threshold means "closed" (-1 open .. +1 closed)

    def rule(self, index: int) -> SkillRule:
        return self.per_skill.get(index, self.default)


def rules_from_dict(d: dict | None) -> AnnotationRules:
    """Rules from a task's YAML block: {default: {...}, skills: {0: {...}}, gripper_threshold: 0.0}."""
    d = d or {}
    names = {f.name for f in fields(SkillRule)}

    def rule(x, base: SkillRule) -> SkillRule:
        unknown = set(x) - names
        if unknown:
            raise AnnotationError(f"unknown annotation rule fields {sorted(unknown)}", reason="BAD_RULES")
        kw = {**base.__dict__, **x}
        kw["offset"] = tuple(float(v) for v in kw["offset"])
        return SkillRule(**kw)

    default = rule(d.get("default") or {}, SkillRule())
    per = {int(k): rule(v, default) for k, v in (d.get("skills") or {}).items()}
    return AnnotationRules(default, per, float(d.get("gripper_threshold", 0.0)))


def _first(mask: np.ndarray, start: int) -> int | None:
    idx = np.flatnonzero(mask[start:])
    return int(start + idx[0]) if idx.size else None


def auto_annotate(task: TaskLike, demo: str, ee_positions: np.ndarray, gripper: np.ndarray,
                  object_poses: dict, rules: AnnotationRules = AnnotationRules()) -> Annotation:
    """Annotate one demo. object_poses: id -> (N,4,4) world poses per step; ee_positions (N,3)."""
    ee = np.asarray(ee_positions, float).reshape(-1, 3)
    g = np.asarray(gripper, float).reshape(-1)
    n = len(ee)
    if len(g) != n:
        raise AnnotationError(f"demo {demo}: {len(g)} gripper values for {n} EE poses", reason="BAD_ANNOTATION")
    closed = g > rules.gripper_threshold
    close_evt = np.zeros(n, bool)
    open_evt = np.zeros(n, bool)
    close_evt[1:] = closed[1:] & ~closed[:-1]
    open_evt[1:] = ~closed[1:] & closed[:-1]

    skills, cursor = [], 0
    for sk in sorted(task.skills, key=lambda s: s.index):
        r = rules.rule(sk.index)
        if sk.object_id not in object_poses:
            raise AnnotationError(f"demo {demo}: no poses for skill {sk.index} object {sk.object_id!r}",
                                  reason="ANNOTATION_UNKNOWN_OBJECT")
        T = np.asarray(object_poses[sk.object_id], float).reshape(-1, 4, 4)
        point = T[:, :3, :3] @ np.asarray(r.offset) + T[:, :3, 3]
        dist = np.linalg.norm(ee - point, axis=1)
        near = _first(dist <= r.start_distance, cursor)
        if near is None:
            raise AnnotationError(
                f"demo {demo}: end effector never comes within {r.start_distance} m of {sk.object_id!r} "
                f"after step {cursor} (closest {dist[cursor:].min():.3f} m)", reason="ANNOTATION_AUTO_FAILED")
        start = max(cursor, near - r.pre_steps)
        event = r.end_event
        if event == "auto":
            event = "close" if sk.mode == "transit" else "open"
        if event == "demo_end":
            end = n
        else:
            mask = {"close": close_evt, "open": open_evt, "leave": dist > r.end_distance}[event]
            hit = _first(mask, near + 1)
            if hit is None:
                raise AnnotationError(f"demo {demo}: skill {sk.index} ({sk.name}) has no gripper {event} "
                                      f"after step {near}", reason="ANNOTATION_AUTO_FAILED")
            end = min(n, hit + r.post_steps + (1 if event != "leave" else 0))
        skills.append(SkillAnnotation(sk.index, sk.object_id, int(start), int(end)))
        cursor = end
    modes = {sk.index: sk.mode for sk in task.skills}
    ann = Annotation(task.name, demo, n, tuple(skills), derive_motions(skills, n, modes), origin="auto")
    return validate_annotation(ann, task)
