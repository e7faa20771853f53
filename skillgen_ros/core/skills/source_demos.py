"""Source-demo loader: plain per-step arrays + an annotation -> a typed `SourceDemo`.

A bag reader (or anything else) fills a `DemoArrays`; `source_demo_from_arrays` validates it
(shapes, NaN/inf poses, annotation) and cuts it into skill segments stored in their objects'
frames, T_O^{A_t} = (T_W^O)^-1 T_W^{A_t}, with T_W^O the object pose at the skill's first step.
Every error names the file and the demo.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import AnnotationError, InvalidInputError
from ..geometry import pose_arrays_to_matrices
from .annotation import Annotation, validate_annotation
from .protocols import TaskLike
from .segment import MotionSegment, SkillSegment, SourceDemo
from .transform import to_object_frame


@dataclass(frozen=True)
class DemoArrays:
    """One recorded demo resampled to its control steps (N steps, world frame, xyzw quaternions).

    action_* are the absolute pose targets sent to the controller; when absent, the next observed
    EE pose stands in for them (the last step repeats). object_* map object id -> per-step arrays.
    """

    name: str
    source: str
    timestamps: np.ndarray  # (N,)
    ee_positions: np.ndarray  # (N,3)
    ee_quaternions: np.ndarray  # (N,4)
    gripper: np.ndarray  # (N,) gripper actions, -1 open .. +1 closed
    object_positions: dict  # id -> (N,3)
    object_quaternions: dict  # id -> (N,4)
    action_positions: np.ndarray | None = None  # (N,3)
    action_quaternions: np.ndarray | None = None  # (N,4)
    joint_positions: np.ndarray | None = None  # (N,7)
    variant: str = "D0"
    scene_seed: int | None = None
    extra: dict = field(default_factory=dict)
    object_joints: dict = field(default_factory=dict)  # "<id>/<joint>" -> (N,) articulated objects' joint values


def sample_and_hold(step_times: np.ndarray, sample_times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Values of a sparse stream (e.g. object poses) at each step time: the latest sample at or
    before it, or the first sample for steps before any sample."""
    step_times = np.asarray(step_times, float)
    sample_times = np.asarray(sample_times, float)
    values = np.asarray(values, float)
    if len(sample_times) == 0:
        raise InvalidInputError("sample_and_hold: no samples")
    idx = np.searchsorted(sample_times, step_times, side="right") - 1
    return values[np.clip(idx, 0, len(values) - 1)]


def _check(where: str, what: str, a, shape_tail: tuple[int, ...], n: int) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.shape != (n, *shape_tail):
        raise InvalidInputError(f"{where}: {what} has shape {arr.shape}, expected {(n, *shape_tail)}",
                                reason="BAD_DEMO")
    bad = ~np.isfinite(arr.reshape(n, -1)).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"{where}: NaN or inf in {what} at step {k} ({int(bad.sum())} bad steps)",
                                reason="NAN_POSE")
    return arr


def _check_quat(where: str, what: str, q: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(q, axis=1)
    bad = np.abs(norms - 1.0) > 1e-3
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"{where}: {what} at step {k} has norm {norms[k]:.4f}, not a unit quaternion",
                                reason="NAN_POSE")
    return q / norms[:, None]


def source_demo_from_arrays(arrays: DemoArrays, annotation: Annotation | None, task: TaskLike) -> SourceDemo:
    """Validate the arrays and the annotation, then build the demo's skill and motion segments."""
    where = f"{arrays.source}: demo {arrays.name}"
    if annotation is None:
        raise AnnotationError(f"{where}: has no annotation; run `skillgen annotate` first",
                              reason="ANNOTATION_NOT_FOUND")
    ts = np.asarray(arrays.timestamps, float).reshape(-1)
    n = len(ts)
    if n < 2:
        raise InvalidInputError(f"{where}: only {n} steps", reason="BAD_DEMO")
    _check(where, "timestamps", ts, (), n)
    if np.any(np.diff(ts) < 0):
        raise InvalidInputError(f"{where}: timestamps go backwards", reason="BAD_DEMO")
    ee_p = _check(where, "ee position", arrays.ee_positions, (3,), n)
    ee_q = _check_quat(where, "ee quaternion", _check(where, "ee quaternion", arrays.ee_quaternions, (4,), n))
    grip = _check(where, "gripper", arrays.gripper, (), n)
    ee = pose_arrays_to_matrices(ee_p, ee_q)
    if arrays.action_positions is not None and arrays.action_quaternions is not None:
        a_p = _check(where, "action position", arrays.action_positions, (3,), n)
        a_q = _check_quat(where, "action quaternion",
                          _check(where, "action quaternion", arrays.action_quaternions, (4,), n))
        actions = pose_arrays_to_matrices(a_p, a_q)
    else:
        actions = np.concatenate([ee[1:], ee[-1:]], axis=0)
    objects = {}
    for oid in arrays.object_positions:
        if oid not in arrays.object_quaternions:
            raise InvalidInputError(f"{where}: object {oid!r} has positions but no orientations", reason="BAD_DEMO")
        p = _check(where, f"pose of object {oid!r}", arrays.object_positions[oid], (3,), n)
        q = _check_quat(where, f"orientation of object {oid!r}",
                        _check(where, f"pose of object {oid!r}", arrays.object_quaternions[oid], (4,), n))
        objects[oid] = pose_arrays_to_matrices(p, q)

    try:
        validate_annotation(annotation, task, num_steps=n)
    except AnnotationError as e:
        raise AnnotationError(f"{arrays.source}: {e.args[0]}", reason=e.reason) from e
    if annotation.demo != arrays.name:
        raise AnnotationError(f"{where}: annotation is for demo {annotation.demo!r}", reason="ANNOTATION_WRONG_DEMO")

    specs = {s.index: s for s in task.skills}
    segments = []
    for a in annotation.skills:
        if a.object not in objects:
            raise AnnotationError(f"{where}: skill {a.index} object {a.object!r} has no recorded poses",
                                  reason="ANNOTATION_UNKNOWN_OBJECT")
        T_W_O = objects[a.object][a.start_step]
        span = slice(a.start_step, a.end_step)
        spec = specs[a.index]
        segments.append(SkillSegment(
            index=a.index, name=spec.name, object_id=a.object, mode=spec.mode,
            start_step=a.start_step, end_step=a.end_step, object_pose=T_W_O,
            actions_in_object=to_object_frame(T_W_O, actions[span]),
            ee_poses_in_object=to_object_frame(T_W_O, ee[span]),
            gripper=grip[span]))
    motions = tuple(MotionSegment(m.start_step, m.end_step, m.next_skill, m.mode) for m in annotation.motions)
    return SourceDemo(
        name=arrays.name, task=task.name, source=arrays.source, skills=tuple(segments), motions=motions,
        timestamps=ts, ee_poses=ee, action_poses=actions, gripper=grip,
        initial_object_poses={k: v[0] for k, v in objects.items()},
        variant=arrays.variant, scene_seed=arrays.scene_seed)


def build_source_demos(items, task: TaskLike) -> list[SourceDemo]:
    """(DemoArrays, Annotation | None) pairs -> SourceDemos; none at all -> NO_SOURCE_DEMOS."""
    demos = [source_demo_from_arrays(arrays, ann, task) for arrays, ann in items]
    if not demos:
        raise InvalidInputError(f"no source demos for task {task.name!r}", reason="NO_SOURCE_DEMOS")
    return demos
