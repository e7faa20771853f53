"""Object models as markers: each task object's primitive parts (core/tasks/objects.py), in the
object's own TF frame (frame_locked), so Foxglove draws them where /tf puts the object."""
from __future__ import annotations

import functools

from ..tasks.spec import ObjectSpec
from ..tasks.suite import TASK_NAMES, get_task
from .messages import MarkerSpec

UNKNOWN_SIZE = 0.03  # m: a sphere for an object type no task defines (a real robot's own objects)


@functools.lru_cache(maxsize=1)
def object_types() -> dict[str, ObjectSpec]:
    """Every task object, by model type (ObjectPose.type)."""
    out: dict[str, ObjectSpec] = {}
    for name in TASK_NAMES:
        t = get_task(name)
        for v in t.variants:
            for o in t.objects_for(v):
                out.setdefault(o.type, o)
    return out


def object_markers(frame: str, type_name: str, marker_id: int) -> list[MarkerSpec]:
    """Markers of one object in TF frame `frame` (its parts; a sphere if the type is unknown)."""
    spec = object_types().get(type_name)
    if spec is None or not spec.parts:
        return [MarkerSpec("objects", marker_id * 100, "SPHERE", frame, scale=(UNKNOWN_SIZE,) * 3,
                           color=(0.9, 0.3, 0.9, 1.0))]
    out = []
    for k, part in enumerate(spec.parts):
        if part.kind == "box":
            kind, scale = "CUBE", tuple(2.0 * s for s in part.size)
        else:
            kind, scale = "CYLINDER", (2.0 * part.size[0], 2.0 * part.size[0], 2.0 * part.size[1])
        out.append(MarkerSpec("objects", marker_id * 100 + k, kind, frame, tuple(part.position),
                              tuple(part.quaternion), scale, tuple(spec.color)))
    out.append(MarkerSpec("object_labels", marker_id, "TEXT_VIEW_FACING", frame, (0.0, 0.0, 0.06),
                          scale=(0.02, 0.02, 0.02), color=(1.0, 1.0, 1.0, 1.0), text=frame))
    return out
