"""Articulated objects: links on one-degree-of-freedom joints (a coffee machine's hinged lid, a drawer).

An articulated object is an ObjectSpec whose `parts` are its fixed base (the object frame, placed by
the reset like any object) plus `links`, each moved by one `Joint` from its parent (the base or another
link). A joint's value lives in the scene, not the spec: SceneState.joints / the sim / the driver's
`object_joint_states` topic key it as "<object id>/<joint name>" (`joint_key`). Keeping the kinematics
here, pure, lets the success rule, the simulator (core/sim/articulation.py) and the planner's obstacle
boxes pose a link from the same numbers.

Frames: a joint frame sits at `origin` in its parent's frame (at value 0); the child link's frame is
the joint frame moved by the value: rotated about `axis` (revolute, rad) or translated along it
(prismatic, m). A link's parts are in its own frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError
from ..geometry import Pose
from .shapes import Part

JOINT_TYPES = ("revolute", "prismatic")
BASE = "base"   # the parent name of a joint on the object's own (fixed) frame


@dataclass(frozen=True)
class Link:
    """A moving part of an articulated object: primitives and keypoints in the link frame."""

    name: str
    parts: tuple[Part, ...] = field(repr=False)
    mass: float
    color: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)
    keypoints: tuple[tuple[str, tuple[float, float, float]], ...] = field(repr=False, default=())

    def keypoint(self, name: str) -> np.ndarray:
        for k, v in self.keypoints:
            if k == name:
                return np.array(v, dtype=float)
        raise InvalidInputError(f"link {self.name} has no keypoint {name!r}")

    def center_of_mass(self) -> np.ndarray:
        """Volume-weighted centroid of the parts (uniform density), link frame."""
        vols = np.array([8 * np.prod(p.size) if p.kind == "box" else np.pi * p.size[0] ** 2 * 2 * p.size[1]
                         for p in self.parts])
        return (vols[:, None] * np.array([p.position for p in self.parts])).sum(axis=0) / vols.sum()


@dataclass(frozen=True)
class Joint:
    """A revolute or prismatic joint moving link `child` relative to `parent` (BASE or a link name).

    lower / upper / initial in rad (revolute) or m (prismatic); `initial` is the value a reset sets.
    damping (N m s/rad or N s/m) and friction (N m or N, Coulomb: the simulator's joint motor force)
    are what keep a joint where it was left."""

    name: str
    type: str
    child: str
    origin: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower: float
    upper: float
    initial: float
    parent: str = BASE
    origin_quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    damping: float = 0.0
    friction: float = 0.0

    def __post_init__(self):
        if self.type not in JOINT_TYPES:
            raise InvalidInputError(f"joint {self.name}: type must be one of {JOINT_TYPES}, got {self.type!r}")
        if not abs(float(np.linalg.norm(self.axis)) - 1.0) < 1e-9:
            raise InvalidInputError(f"joint {self.name}: axis must be a unit vector, got {self.axis}")
        if not self.lower <= self.initial <= self.upper:
            raise InvalidInputError(f"joint {self.name}: initial {self.initial} outside [{self.lower}, {self.upper}]")
        if self.damping < 0 or self.friction < 0:
            raise InvalidInputError(f"joint {self.name}: damping and friction must be >= 0")

    def motion(self, value: float) -> np.ndarray:
        """4x4 child-link frame in the joint frame at `value`."""
        T = np.eye(4)
        if self.type == "revolute":
            T[:3, :3] = Rotation.from_rotvec(np.asarray(self.axis, float) * float(value)).as_matrix()
        else:
            T[:3, 3] = np.asarray(self.axis, float) * float(value)
        return T

    def transform(self, value: float) -> np.ndarray:
        """4x4 child-link frame in the parent frame at `value`."""
        return Pose(self.origin, self.origin_quat).matrix() @ self.motion(value)

    def shifted(self, shift) -> "Joint":
        """The same joint with its origin moved by `shift` (the parent frame was recentred)."""
        o = tuple(float(x) for x in np.asarray(self.origin, float) + np.asarray(shift, float))
        return Joint(self.name, self.type, self.child, o, self.axis, self.lower, self.upper, self.initial,
                     self.parent, self.origin_quat, self.damping, self.friction)


def joint_key(object_id: str, joint_name: str) -> str:
    """How a scene names one object's joint (SceneState.joints, JointState.name)."""
    return f"{object_id}/{joint_name}"


def validate_articulation(object_id: str, links: tuple[Link, ...], joints: tuple[Joint, ...]) -> None:
    """One joint per link, parents known and declared before their children, unique names."""
    names = [lk.name for lk in links]
    if len(set(names)) != len(names) or BASE in names:
        raise InvalidInputError(f"object {object_id}: link names must be unique and not {BASE!r}: {names}")
    if sorted(j.child for j in joints) != sorted(names) or len({j.name for j in joints}) != len(joints):
        raise InvalidInputError(f"object {object_id}: need exactly one uniquely named joint per link")
    seen = {BASE}
    for j in joints:
        if j.parent not in seen:
            raise InvalidInputError(f"object {object_id}: joint {j.name}'s parent {j.parent!r} must come first")
        seen.add(j.child)


def initial_joint_values(objects) -> dict[str, float]:
    """{joint_key: initial value} of every joint of the given ObjectSpecs (what a reset sets)."""
    return {joint_key(o.id, j.name): float(j.initial) for o in objects for j in o.joints}


def joint_values(obj, joints: Mapping[str, float]) -> dict[str, float]:
    """{joint name: value} of `obj` read from a scene's joint map; MISSING_JOINT_STATE if one is absent."""
    out = {}
    for j in obj.joints:
        k = joint_key(obj.id, j.name)
        if k not in joints:
            raise InvalidInputError(f"scene has no value for joint {k!r}", "MISSING_JOINT_STATE")
        v = float(joints[k])
        if not np.isfinite(v):
            raise InvalidInputError(f"joint {k!r} value {v} is not finite", "MISSING_JOINT_STATE")
        out[j.name] = v
    return out


def link_frames(obj, pose: Pose, values: Mapping[str, float]) -> dict[str, np.ndarray]:
    """World 4x4 frame of every link of `obj` at object pose `pose` and {joint name: value}."""
    frames = {BASE: pose.matrix()}
    for j in obj.joints:
        frames[j.child] = frames[j.parent] @ j.transform(values[j.name])
    frames.pop(BASE)
    return frames


def link_point(obj, pose: Pose, values: Mapping[str, float], link: str, keypoint: str) -> np.ndarray:
    """World position of a link keypoint (e.g. the lid's "body_origin") at the given joint values."""
    T = link_frames(obj, pose, values)[link]
    lk = next(x for x in obj.links if x.name == link)
    return T[:3, :3] @ lk.keypoint(keypoint) + T[:3, 3]


def posed_link_parts(links, joints) -> tuple[Part, ...]:
    """The links' parts in the object frame, every joint at its reset value (for the object's mesh)."""
    frames = {BASE: np.eye(4)}
    for j in joints:
        frames[j.child] = frames[j.parent] @ j.transform(j.initial)
    out = []
    for lk in links:
        T = frames[lk.name]
        for p in lk.parts:
            R = Rotation.from_matrix(T[:3, :3]) * Rotation.from_quat(p.quaternion)
            out.append(Part(p.kind, p.size, tuple(T[:3, :3] @ np.asarray(p.position) + T[:3, 3]), tuple(R.as_quat())))
    return tuple(out)


def recorded_joints(objects, arrays: Mapping, k: int) -> dict[str, float]:
    """{joint_key: value} at step k of recorded per-object arrays ({"<id>_joints": (T, J)}, joints in spec
    order, as datasets' obs/<id>_joints hold them); objects or steps without values (NaN) give none."""
    out = {}
    for o in objects:
        a = arrays.get(f"{o.id}_joints") if o.joints else None
        if a is None:
            continue
        for j, v in zip(o.joints, np.asarray(a[k], float)):
            if np.isfinite(v):
                out[joint_key(o.id, j.name)] = float(v)
    return out
