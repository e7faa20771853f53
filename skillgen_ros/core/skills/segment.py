"""Typed source demos: the alternating motion and skill segments of the paper (tau_im, tau_is).

A `SkillSegment` keeps everything generation and HSP need about one skill in one demo: the skill
object O_i, its pose T_W^{O_i} observed before the skill, the end-effector pose actions and the
observed end-effector poses expressed in the object frame, the gripper actions, and so the
initiation state T_O^{E_0} (first EE pose) and termination state T_O^{E_K} (last EE pose).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .transform import to_world


def _frozen_array(a) -> np.ndarray:
    arr = np.array(a, dtype=float, copy=True)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class SkillSegment:
    """One annotated skill segment tau_is of a source demo, stored in its object's frame.

    Steps are the demo's control steps; the span is half-open [start_step, end_step).
    """

    index: int
    name: str
    object_id: str
    mode: str  # "transit" (hand free before the skill) or "transfer" (holding an object)
    start_step: int
    end_step: int
    object_pose: np.ndarray  # (4,4) T_W^O observed before the skill
    actions_in_object: np.ndarray  # (K,4,4) T_O^{A_t}: pose actions (controller targets)
    ee_poses_in_object: np.ndarray  # (K,4,4) T_O^{E_t}: observed end-effector poses
    gripper: np.ndarray  # (K,) gripper actions, -1 open .. +1 closed

    def __post_init__(self):
        for name in ("object_pose", "actions_in_object", "ee_poses_in_object", "gripper"):
            object.__setattr__(self, name, _frozen_array(getattr(self, name)))

    @property
    def num_steps(self) -> int:
        return int(self.end_step - self.start_step)

    @property
    def initiation(self) -> np.ndarray:
        """T_O^{E_0}: the motion planner's target, relative to the skill object."""
        return self.ee_poses_in_object[0]

    @property
    def termination(self) -> np.ndarray:
        """T_O^{E_K}: the last pose, which implicitly defines the termination state."""
        return self.ee_poses_in_object[-1]

    def actions_in_world(self, T_W_O_new) -> np.ndarray:
        """The transformed segment tau'_is: T_W^{A_t'} = T_W^{O'} T_O^{A_t}, shape (K,4,4)."""
        return to_world(T_W_O_new, self.actions_in_object)

    def initiation_in_world(self, T_W_O_new) -> np.ndarray:
        """T_W^{E_0'} = T_W^{O'} T_O^{E_0}."""
        return to_world(T_W_O_new, self.initiation)


@dataclass(frozen=True)
class MotionSegment:
    """A free-space motion tau_im between skills: transit or transfer, span [start_step, end_step)."""

    start_step: int
    end_step: int
    next_skill: int | None  # index of the skill this motion leads to; None after the last skill
    mode: str = "transit"

    @property
    def num_steps(self) -> int:
        return int(self.end_step - self.start_step)


@dataclass(frozen=True)
class SourceDemo:
    """One annotated source demonstration: its skill and motion segments plus whole-demo arrays.

    The whole-demo arrays (world frame) serve the Replay-Noise baseline; `variant` and
    `scene_seed` say how to reset the scene to the demo's own initial state.
    """

    name: str
    task: str
    source: str  # file the demo came from, for error messages
    skills: tuple[SkillSegment, ...]
    motions: tuple[MotionSegment, ...]
    timestamps: np.ndarray  # (N,) seconds
    ee_poses: np.ndarray  # (N,4,4) observed end-effector poses, world frame
    action_poses: np.ndarray  # (N,4,4) absolute pose actions, world frame
    gripper: np.ndarray  # (N,) gripper actions
    initial_object_poses: dict = field(default_factory=dict)  # id -> (4,4) at step 0
    variant: str = "D0"
    scene_seed: int | None = None

    def __post_init__(self):
        for name in ("timestamps", "ee_poses", "action_poses", "gripper"):
            object.__setattr__(self, name, _frozen_array(getattr(self, name)))
        object.__setattr__(self, "skills", tuple(self.skills))
        object.__setattr__(self, "motions", tuple(self.motions))
        object.__setattr__(self, "initial_object_poses",
                           {k: _frozen_array(v) for k, v in dict(self.initial_object_poses).items()})

    @property
    def num_steps(self) -> int:
        return int(len(self.timestamps))

    def skill(self, index: int) -> SkillSegment:
        for s in self.skills:
            if s.index == index:
                return s
        from ..errors import AnnotationError

        raise AnnotationError(f"{self.source}: demo {self.name} has no skill {index}",
                              reason="ANNOTATION_MISSING_SKILL")
