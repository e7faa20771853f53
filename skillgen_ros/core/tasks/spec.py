"""Typed task descriptions: objects, skills, reset regions (D0/D1/D2, clutter variants), scene description.

A task is data (objects with meshes, a skill list, per-variant reset regions) plus one success
predicate over a SceneState (true object poses + the EE position + the gripper command). Keeping the
predicate a pure function of that state lets the kinematic mock driver, the physics driver and the
in-process environment answer `task_success` the same way.

Object frames: the origin is the centre of the object's axis-aligned bounding box in its own
frame, z up when the object rests upright, so a resting object's world z is `half_extents[2]`
above the table top (TABLE_Z).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError, SkillGenError, UnknownVariantError
from ..geometry import Pose
from ..robot import TABLE_Z
from .articulation import Joint, Link, validate_articulation
from .shapes import Part

MAX_SEED = 2**32 - 1
SEPARATION_MARGIN = 0.01  # metres between the bounding circles of two sampled objects
SYMMETRIES = ("none", "z2", "z4", "z_continuous")
FOOTPRINTS = ("circle", "box")
DEFAULT_CAMERA_SIZE = (128, 128)  # a task's sim camera (width, height) unless it needs more (TaskSpec.camera_size)


@dataclass(frozen=True)
class SceneState:
    """What a success rule reads: true world poses of the objects, the EE (panda_grasptarget) position
    and the last gripper command (-1 open .. +1 closed). robosuite's nut rule needs the EE: a nut still
    in the hand near its centre does not count (nut_assembly.py _check_success, r_reach < 0.6).
    `joints`: articulated objects' joint values by articulation.joint_key ("coffee_machine/lid")."""

    poses: Mapping[str, Pose]
    ee_position: np.ndarray
    gripper: float = -1.0
    joints: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class ObjectSpec:
    """A rigid object or fixture. mesh_path: OBJ in the object frame; half_extents: AABB half size.

    An articulated object adds `links` moved by `joints` (core/tasks/articulation.py); `parts`,
    `half_extents` and the mesh are its fixed base only."""

    id: str
    type: str
    mesh_path: str
    half_extents: tuple[float, float, float]
    is_fixture: bool
    symmetry: str
    mass: float
    parts: tuple[Part, ...] = field(repr=False, default=())
    color: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)
    friction: float = 1.0
    keypoints: tuple[tuple[str, tuple[float, float, float]], ...] = field(repr=False, default=())
    links: tuple[Link, ...] = field(repr=False, default=())
    joints: tuple[Joint, ...] = field(repr=False, default=())

    def __post_init__(self):
        if self.links or self.joints:
            validate_articulation(self.id, self.links, self.joints)

    def keypoint(self, name: str) -> np.ndarray:
        """A named point in the object frame (e.g. "handle", "ring_center", "tip")."""
        for k, v in self.keypoints:
            if k == name:
                return np.array(v, dtype=float)
        raise InvalidInputError(f"object {self.id} has no keypoint {name!r}")

    @property
    def footprint_radius(self) -> float:
        """Radius of the circle around the origin that covers the object seen from above."""
        return float(np.hypot(self.half_extents[0], self.half_extents[1]))


@dataclass(frozen=True)
class SkillSpec:
    """One skill segment: the object it manipulates and how the arm moves before it.

    mode: "transit" (free arm) or "transfer" (carrying attached_object) for the motion that
    precedes the skill, as in the paper's Transit/Transfer primitives.
    """

    index: int
    object_id: str
    name: str
    mode: str
    attached_object: str | None = None


@dataclass(frozen=True)
class Region:
    """Reset region of one object: world x/y ranges of its origin (m) and its yaw range (rad).

    `z`: the world z of the object frame's origin when the object does not rest on the table top but in
    or on a fixture (Coffee Prep's pod on the drawer's tray: MimicGen samples it on its own, inside the
    drawer). Such an object is not kept apart from the others: it lies inside its fixture's footprint."""

    x: tuple[float, float]
    y: tuple[float, float]
    yaw: tuple[float, float] = (0.0, 0.0)
    z: float | None = None

    def sample(self, rng: np.random.Generator) -> tuple[float, float, float]:
        return (float(rng.uniform(*self.x)), float(rng.uniform(*self.y)), float(rng.uniform(*self.yaw)))

    def contains(self, pose: Pose, tol: float = 1e-6, obj: "ObjectSpec | None" = None) -> bool:
        """True if the pose's xy (of obj's "body_origin" keypoint when obj is given) lies in the box
        and its yaw (about world z) in the yaw range."""
        yaw = float(Rotation.from_quat(pose.quaternion).as_euler("ZYX")[0])
        x, y = pose.position[:2] + (_anchor_offset(obj, yaw) if obj is not None else 0.0)
        lo, hi = self.yaw
        # compare yaw modulo 2*pi against the range
        k = np.round(((lo + hi) / 2 - yaw) / (2 * np.pi))
        yaw = yaw + 2 * np.pi * k
        return (self.x[0] - tol <= x <= self.x[1] + tol and self.y[0] - tol <= y <= self.y[1] + tol
                and lo - 1e-6 <= yaw <= hi + 1e-6)


@dataclass(frozen=True)
class TaskSpec:
    """A task: objects, skills, variants and their reset regions, and the success predicate.

    `objects` are present in every variant; `obstacle` (if any) is added in the `clutter_variants`.
    `footprint`: how the reset keeps sampled objects apart: "circle" (bounding circles, every task so far)
    or "box" (oriented x-y bounding boxes: Coffee Prep, whose reference sets the drawer and the machine
    closer than their bounding circles allow; robosuite checks hand-set radii there).
    `hidden_until`: object id -> index of the first skill before which perception must find it. An object
    that can lie inside a closed container at reset (Coffee Prep's pod in the drawer) is not visible to the
    camera until an earlier skill opens it, so it is not required before then (required_ids).
    `camera_size`: (width, height) of a sim camera configured as 0 x 0 ("the task's size": the perception
    camera's default) in this task's scenes. Thin parts need more pixels: Threading's 1 cm needle shaft.
    """

    name: str
    objects: tuple[ObjectSpec, ...]
    skills: tuple[SkillSpec, ...]
    variants: tuple[str, ...]
    region_table: Mapping[str, Mapping[str, Region]] = field(repr=False, default_factory=dict)
    success_fn: Callable[[SceneState], bool] | None = field(repr=False, default=None)
    obstacle: ObjectSpec | None = None
    clutter_variants: tuple[str, ...] = ()
    footprint: str = "circle"
    hidden_until: Mapping[str, int] = field(default_factory=dict)
    camera_size: tuple[int, int] = DEFAULT_CAMERA_SIZE

    def __post_init__(self):
        if self.footprint not in FOOTPRINTS:
            raise InvalidInputError(f"task {self.name}: footprint must be one of {FOOTPRINTS}, got {self.footprint!r}")
        for oid, k in self.hidden_until.items():
            uses = [s.index for s in self.skills if s.object_id == oid]
            if oid not in {o.id for o in self.objects} or not uses or not 0 < k <= min(uses):
                raise InvalidInputError(f"task {self.name}: hidden_until[{oid!r}] = {k} must name an object and a skill "
                                        f"index in (0, its first skill {min(uses, default=None)}]")
        if len(self.camera_size) != 2 or min(self.camera_size) < 1:
            raise InvalidInputError(f"task {self.name}: camera_size must be (width, height) >= 1, "
                                    f"got {self.camera_size}")

    def hidden_at(self, skill_index: int) -> frozenset[str]:
        """Objects the camera may not see before skill `skill_index` starts (hidden_until)."""
        return frozenset(oid for oid, k in self.hidden_until.items() if skill_index < k)

    def required_ids(self, object_ids: Iterable[str], skill_index: int, held: str | None = None) -> list[str]:
        """The objects perception must find before skill `skill_index`: the scene's, less the obstacle (unknown
        clutter: no model), the held one (the hand occludes it; the grasp tracker has it) and the hidden ones."""
        skip = self.hidden_at(skill_index) | {held, self.obstacle.id if self.obstacle else "obstacle"}
        return [oid for oid in object_ids if oid not in skip]

    def _check_variant(self, variant: str) -> None:
        if variant not in self.variants:
            raise UnknownVariantError(f"task {self.name} has no variant {variant!r}; known: {list(self.variants)}")

    def objects_for(self, variant: str) -> tuple[ObjectSpec, ...]:
        """Objects present in the scene of this variant (adds the obstacle in a clutter variant)."""
        self._check_variant(variant)
        return self.objects + ((self.obstacle,) if variant in self.clutter_variants and self.obstacle else ())

    def object(self, object_id: str) -> ObjectSpec:
        for o in self.objects + ((self.obstacle,) if self.obstacle else ()):
            if o.id == object_id:
                return o
        raise InvalidInputError(f"task {self.name} has no object {object_id!r}")

    def regions(self, variant: str) -> dict[str, Region]:
        """The documented reset region of every object in this variant (docs/tasks.md)."""
        self._check_variant(variant)
        return dict(self.region_table[variant])

    def sample_reset(self, variant: str, rng: np.random.Generator) -> dict[str, Pose]:
        """Sample object poses: uniform in each region, bounding circles kept apart (rejection).

        A region holds the object's "body_origin" keypoint when it has one (the reference model's body
        origin, e.g. robosuite's nut body at the ring centre), else the object-frame origin. Objects are
        placed in the order of the variant's region table (the reference's sampling order)."""
        regions = self.regions(variant)
        objs = sorted(self.objects_for(variant), key=lambda o: list(regions).index(o.id))  # region order
        for _ in range(500):
            placed: dict[str, Pose] = {}
            ok = True
            for o in objs:
                r = regions[o.id]
                for _ in range(100):
                    x, y, yaw = r.sample(rng)
                    x, y = np.array([x, y]) - _anchor_offset(o, yaw)
                    if r.z is not None or all(self._apart(o, x, y, yaw, self.object(k), p)
                                              for k, p in placed.items() if regions[k].z is None):
                        z = TABLE_Z + o.half_extents[2] if r.z is None else r.z
                        placed[o.id] = Pose([x, y, z], Rotation.from_euler("z", yaw).as_quat())
                        break
                else:
                    ok = False
                    break
            if ok:
                return {o.id: placed[o.id] for o in self.objects_for(variant)}
        raise SkillGenError(f"{self.name}/{variant}: could not sample a collision-free reset", "RESET_FAILED")

    def _apart(self, o: ObjectSpec, x: float, y: float, yaw: float, other: ObjectSpec, pose: Pose) -> bool:
        """Whether `o` at (x, y, yaw) keeps SEPARATION_MARGIN from `other` at `pose`, by this task's footprint."""
        if self.footprint == "circle":
            return bool(np.hypot(x - pose.position[0], y - pose.position[1])
                        >= o.footprint_radius + other.footprint_radius + SEPARATION_MARGIN)
        other_yaw = float(Rotation.from_quat(pose.quaternion).as_euler("ZYX")[0])
        return not boxes_overlap((x, y), yaw, o.half_extents[:2], pose.position[:2], other_yaw,
                                 other.half_extents[:2], SEPARATION_MARGIN)

    def is_success(self, state: SceneState) -> bool:
        """The task's success predicate, evaluated on the scene state (true poses, EE, gripper)."""
        if not isinstance(state, SceneState):
            raise InvalidInputError(f"is_success takes a SceneState, got {type(state).__name__}")
        return bool(self.success_fn(state)) if self.success_fn else False


def boxes_overlap(ca, yaw_a: float, half_a, cb, yaw_b: float, half_b, margin: float = 0.0) -> bool:
    """Whether two x-y rectangles (centre, yaw, half sizes) come within `margin` of each other
    (separating-axis test on the rectangles grown by margin / 2 each)."""
    d = np.asarray(cb, float)[:2] - np.asarray(ca, float)[:2]
    axes = [np.array([np.cos(a), np.sin(a)]) for a in (yaw_a, yaw_b)]
    axes += [np.array([-u[1], u[0]]) for u in axes]
    ea, eb = np.asarray(half_a, float)[:2] + margin / 2, np.asarray(half_b, float)[:2] + margin / 2

    def reach(half, yaw, n):   # half-width of a rectangle's projection onto n
        u, v = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
        return abs(half[0] * (u @ n)) + abs(half[1] * (v @ n))
    return all(abs(d @ n) < reach(ea, yaw_a, n) + reach(eb, yaw_b, n) for n in axes)


def _anchor_offset(o: ObjectSpec, yaw: float) -> np.ndarray:
    """xy of the object's "body_origin" keypoint from its frame origin at this yaw (0 if it has none)."""
    if not any(k == "body_origin" for k, _ in o.keypoints):
        return np.zeros(2)
    return Rotation.from_euler("z", yaw).apply(o.keypoint("body_origin"))[:2]


@dataclass(frozen=True)
class SceneDescription:
    """What reset_scene returns: the objects present and their poses (true poses in the sim)."""

    task: str
    variant: str
    seed: int
    objects: tuple[ObjectSpec, ...]
    poses: Mapping[str, Pose]
    joint_positions: np.ndarray
    object_joints: Mapping[str, float] = field(default_factory=dict)  # articulated objects' joint values


def validate_seed(seed) -> int:
    """Seeds are integers in [0, 2**32 - 1] (numpy's seed range); anything else is INVALID_SEED."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InvalidInputError(f"seed must be an integer, got {seed!r}", "INVALID_SEED")
    if not 0 <= int(seed) <= MAX_SEED:
        raise InvalidInputError(f"seed {seed} outside [0, {MAX_SEED}]", "INVALID_SEED")
    return int(seed)
