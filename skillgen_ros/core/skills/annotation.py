"""Skill annotations: where each skill starts and ends in a source demo (paper Sec. "Source Demonstrations").

Format (YAML or JSON, documented in docs/annotations.md)::

    task: Square
    demo: demo_00
    num_steps: 412
    skills:  [{index: 0, object: square_nut, start_step: 80, end_step: 130}, ...]
    motions: [{start_step: 0, end_step: 80, next_skill: 0, mode: transit}, ...]

Spans are half-open [start_step, end_step) over the demo's control steps. Motions are derived
from the gaps between skills when a document omits them. `validate_annotation` raises
`AnnotationError` with a specific reason code for each kind of mistake.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, replace

import yaml

from ..errors import AnnotationError
from ..robot import CONTROL_HZ
from .protocols import TaskLike, known_object_ids


@dataclass(frozen=True)
class SkillAnnotation:
    index: int
    object: str
    start_step: int
    end_step: int


@dataclass(frozen=True)
class MotionAnnotation:
    start_step: int
    end_step: int
    next_skill: int | None
    mode: str = "transit"


@dataclass(frozen=True)
class Annotation:
    task: str
    demo: str
    num_steps: int
    skills: tuple[SkillAnnotation, ...]
    motions: tuple[MotionAnnotation, ...] = ()
    origin: str = "manual"  # "auto", "manual" or "auto+overrides"

    def __post_init__(self):
        object.__setattr__(self, "skills", tuple(self.skills))
        object.__setattr__(self, "motions", tuple(self.motions))


def derive_motions(skills, num_steps: int, modes: dict[int, str] | None = None) -> tuple[MotionAnnotation, ...]:
    """The motion segments tau_im: the non-empty gaps before, between and after the skills."""
    modes = modes or {}
    out, prev = [], 0
    for s in sorted(skills, key=lambda s: s.start_step):
        if s.start_step > prev:
            out.append(MotionAnnotation(prev, s.start_step, s.index, modes.get(s.index, "transit")))
        prev = s.end_step
    if prev < num_steps:
        out.append(MotionAnnotation(prev, num_steps, None, "transit"))
    return tuple(out)


def _where(ann: Annotation) -> str:
    return f"annotation of task {ann.task!r} demo {ann.demo!r}"


def validate_annotation(ann: Annotation, task: TaskLike | None = None, num_steps: int | None = None) -> Annotation:
    """Check spans are in range, non-empty, ordered, non-overlapping; objects known; every skill present.

    Returns the annotation unchanged so calls can be chained. `num_steps` (the demo's real length)
    overrides the document's own count when given, and must agree with it.
    """
    where = _where(ann)
    n = ann.num_steps if num_steps is None else int(num_steps)
    if num_steps is not None and ann.num_steps != num_steps:
        raise AnnotationError(f"{where}: says {ann.num_steps} steps but the demo has {num_steps}",
                              reason="ANNOTATION_OUT_OF_RANGE")
    if not ann.skills:
        raise AnnotationError(f"{where}: no skills annotated", reason="ANNOTATION_MISSING_SKILL")
    for s in ann.skills:
        if not (0 <= s.start_step < s.end_step <= n):
            raise AnnotationError(
                f"{where}: skill {s.index} span [{s.start_step}, {s.end_step}) is empty or outside [0, {n})",
                reason="ANNOTATION_OUT_OF_RANGE")
    for a, b in zip(ann.skills, ann.skills[1:]):
        if b.index <= a.index:
            raise AnnotationError(f"{where}: skills not listed in index order ({a.index} then {b.index})",
                                  reason="ANNOTATION_ORDER")
        if b.start_step < a.end_step:
            raise AnnotationError(
                f"{where}: skill {b.index} [{b.start_step}, {b.end_step}) overlaps or precedes skill {a.index} "
                f"[{a.start_step}, {a.end_step})", reason="ANNOTATION_OVERLAP")
    for m in ann.motions:
        if not (0 <= m.start_step < m.end_step <= n):
            raise AnnotationError(f"{where}: motion span [{m.start_step}, {m.end_step}) outside [0, {n})",
                                  reason="ANNOTATION_OUT_OF_RANGE")
        for s in ann.skills:
            if m.start_step < s.end_step and s.start_step < m.end_step:
                raise AnnotationError(f"{where}: motion [{m.start_step}, {m.end_step}) overlaps skill {s.index}",
                                      reason="ANNOTATION_OVERLAP")
    if task is not None:
        if ann.task != task.name:
            raise AnnotationError(f"{where}: written for task {ann.task!r}, not {task.name!r}",
                                  reason="ANNOTATION_WRONG_TASK")
        known = known_object_ids(task)
        for s in ann.skills:
            if s.object not in known:
                raise AnnotationError(f"{where}: skill {s.index} names unknown object {s.object!r}; "
                                      f"known: {sorted(known)}", reason="ANNOTATION_UNKNOWN_OBJECT")
        expected = {sk.index: sk for sk in task.skills}
        got = {s.index for s in ann.skills}
        missing = sorted(set(expected) - got)
        if missing:
            raise AnnotationError(f"{where}: skills {missing} are not annotated "
                                  f"(task has {sorted(expected)})", reason="ANNOTATION_MISSING_SKILL")
        extra = sorted(got - set(expected))
        if extra:
            raise AnnotationError(f"{where}: skills {extra} do not exist in task {task.name!r}",
                                  reason="ANNOTATION_UNKNOWN_SKILL")
        for s in ann.skills:
            if s.object != expected[s.index].object_id:
                raise AnnotationError(f"{where}: skill {s.index} is on {expected[s.index].object_id!r}, "
                                      f"annotation says {s.object!r}", reason="ANNOTATION_UNKNOWN_OBJECT")
    return ann


# ---------------------------------------------------------------- documents
def annotation_to_dict(ann: Annotation) -> dict:
    d = asdict(ann)
    d["skills"] = [dict(s) for s in d["skills"]]
    d["motions"] = [dict(m) for m in d["motions"]]
    return d


def _int(d: dict, key: str, where: str) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int):
        raise AnnotationError(f"{where}: field {key!r} must be an integer, got {v!r}", reason="BAD_ANNOTATION")
    return v


def annotation_from_dict(d: dict, source: str = "<dict>") -> Annotation:
    """Parse a document, deriving motions when it omits them; malformed input -> BAD_ANNOTATION."""
    if not isinstance(d, dict):
        raise AnnotationError(f"{source}: annotation must be a mapping, got {type(d).__name__}")
    for key in ("task", "demo", "num_steps", "skills"):
        if key not in d:
            raise AnnotationError(f"{source}: annotation lacks field {key!r}")
    if not isinstance(d["skills"], list):
        raise AnnotationError(f"{source}: 'skills' must be a list")
    skills = []
    for i, s in enumerate(d["skills"]):
        w = f"{source}: skills[{i}]"
        if not isinstance(s, dict) or "object" not in s:
            raise AnnotationError(f"{w}: needs index, object, start_step, end_step")
        skills.append(SkillAnnotation(_int(s, "index", w), str(s["object"]), _int(s, "start_step", w),
                                      _int(s, "end_step", w)))
    n = _int(d, "num_steps", source)
    motions = []
    for i, m in enumerate(d.get("motions") or []):
        w = f"{source}: motions[{i}]"
        nxt = m.get("next_skill")
        motions.append(MotionAnnotation(_int(m, "start_step", w), _int(m, "end_step", w),
                                        None if nxt is None else int(nxt), str(m.get("mode", "transit"))))
    if not motions:
        motions = list(derive_motions(skills, n))
    return Annotation(str(d["task"]), str(d["demo"]), n, tuple(skills), tuple(motions), str(d.get("origin", "manual")))


def dumps_annotation(ann: Annotation, fmt: str = "yaml") -> str:
    d = annotation_to_dict(ann)
    return json.dumps(d, indent=2) + "\n" if fmt == "json" else yaml.safe_dump(d, sort_keys=False)


def loads_annotation(text: str, source: str = "<string>") -> Annotation:
    try:
        d = yaml.safe_load(text)  # YAML is a superset of JSON: one parser for both
    except yaml.YAMLError as e:
        raise AnnotationError(f"{source}: not valid YAML/JSON: {e}") from e
    return annotation_from_dict(d, source)


def save_annotation(path: str, ann: Annotation) -> str:
    """Write a sidecar file; .json -> JSON, anything else YAML. Written atomically."""
    fmt = "json" if str(path).endswith(".json") else "yaml"
    tmp = f"{path}.tmp"
    with open(tmp, "w") as f:
        f.write(dumps_annotation(ann, fmt))
    os.replace(tmp, path)
    return str(path)


def load_annotation(path: str) -> Annotation:
    try:
        with open(path) as f:
            text = f.read()
    except OSError as e:
        raise AnnotationError(f"{path}: cannot read annotation: {e.strerror}", reason="ANNOTATION_NOT_FOUND") from e
    return loads_annotation(text, str(path))


# ---------------------------------------------------------------- manual overrides
@dataclass(frozen=True)
class Override:
    """Move one skill boundary: `skill`'s `edge` ("start" or "end") to a step, or to a time in seconds."""

    skill: int
    edge: str
    step: int | None = None
    time: float | None = None


def parse_override(text: str) -> Override:
    """'1.start=120' (step) or '1.end=4.25s' (seconds from the demo's first step)."""
    try:
        lhs, rhs = text.split("=", 1)
        idx, edge = lhs.strip().split(".", 1)
        edge = edge.strip()
        rhs = rhs.strip()
        if edge not in ("start", "end"):
            raise ValueError(edge)
        if rhs.endswith("s"):
            t = float(rhs[:-1])
            if not math.isfinite(t):
                raise ValueError(rhs)
            return Override(int(idx), edge, time=t)
        return Override(int(idx), edge, step=int(rhs))
    except ValueError as e:
        raise AnnotationError(f"override {text!r}: expected '<skill>.<start|end>=<step>' or '...=<seconds>s'",
                              reason="BAD_OVERRIDE") from e


def step_times(num_steps: int, control_hz: float = CONTROL_HZ):
    """The demo's time of each control step from its first: step k at k / control_hz (20 Hz).

    Overrides in seconds and `skillgen annotate`'s summary use this clock, not the bag's receive
    times (which drift from the control clock under load, and start wherever the recording did)."""
    import numpy as np

    return np.arange(int(num_steps)) / float(control_hz)


def time_to_step(timestamps, t: float) -> int:
    """First step whose time since the demo's start is >= t; a time before the start or more than
    one period after the last step is ANNOTATION_OUT_OF_RANGE (as a step past the end is), never clamped.
    A time within the period after the last step is the demo's end (step num_steps, an end edge)."""
    import numpy as np

    ts = np.asarray(timestamps, float)
    rel = ts - ts[0]
    period = float(np.median(np.diff(rel))) if len(rel) > 1 else 0.0
    if not (0.0 <= t <= rel[-1] + period + 1e-9):
        raise AnnotationError(f"time {t:g} s is outside the demo, which runs from 0 to {rel[-1] + period:.2f} s "
                              f"({len(ts)} steps)", reason="ANNOTATION_OUT_OF_RANGE")
    return int(np.searchsorted(rel, t - 1e-9, side="left"))


def apply_overrides(ann: Annotation, overrides, timestamps=None, task: TaskLike | None = None) -> Annotation:
    """Apply manual boundary overrides, re-derive motions and re-validate. A step or time outside
    the demo is ANNOTATION_OUT_OF_RANGE; a skill the task lacks ANNOTATION_UNKNOWN_SKILL."""
    skills = {s.index: s for s in ann.skills}
    task_skills = {sk.index for sk in task.skills} if task is not None else None
    for o in overrides:
        if task_skills is not None and o.skill not in task_skills:
            raise AnnotationError(f"{_where(ann)}: override for skill {o.skill}, which task {task.name!r} does not "
                                  f"have (skills {sorted(task_skills)})", reason="ANNOTATION_UNKNOWN_SKILL")
        if o.skill not in skills:
            raise AnnotationError(f"{_where(ann)}: override for skill {o.skill}, which is not annotated",
                                  reason="ANNOTATION_MISSING_SKILL")
        if o.step is not None:
            step = o.step
        elif timestamps is None:
            raise AnnotationError(f"{_where(ann)}: time override needs the demo's timestamps", reason="BAD_OVERRIDE")
        else:
            try:
                step = time_to_step(timestamps, float(o.time))
            except AnnotationError as e:
                raise AnnotationError(f"{_where(ann)}: override {o.skill}.{o.edge}: {e.args[0]}", e.reason) from e
        if not 0 <= step <= ann.num_steps:
            raise AnnotationError(f"{_where(ann)}: override {o.skill}.{o.edge}={step} is outside the demo's "
                                  f"steps [0, {ann.num_steps}]", reason="ANNOTATION_OUT_OF_RANGE")
        skills[o.skill] = replace(skills[o.skill], **{f"{o.edge}_step": int(step)})
    new = tuple(skills[i] for i in sorted(skills))
    modes = {sk.index: sk.mode for sk in task.skills} if task is not None else {m.next_skill: m.mode for m in ann.motions}
    out = replace(ann, skills=new, motions=derive_motions(new, ann.num_steps, modes),
                  origin=ann.origin if "overrides" in ann.origin else f"{ann.origin}+overrides")
    return validate_annotation(out, task)
