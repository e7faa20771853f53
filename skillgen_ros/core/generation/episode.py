"""What one generation attempt records, step by step, and the arrays it becomes.

Each control step t stores the observation before the action (robomimic convention: o_t, a_t),
the normalized delta-pose action a_t (7: dpos, drot, gripper), the absolute pose it commanded
(8: x, y, z, qx, qy, qz, qw, gripper) and the labels Hybrid Skill Policies need.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose
from ..skills.transform import matrix_to_array


def _pose7(p, what: str) -> np.ndarray:
    if isinstance(p, Pose):
        return p.as_array()
    a = np.asarray(p, float)
    if a.shape == (4, 4):
        return matrix_to_array(a)
    if a.shape != (7,):
        raise InvalidInputError(f"{what}: expected a Pose, (7,) or (4,4), got shape {a.shape}")
    return a


@dataclass(frozen=True)
class Observation:
    """Low-dim robot + object state at one step; images (camera -> HxWx3 uint8) are optional."""

    ee_pose: np.ndarray  # (7,) x, y, z, qx, qy, qz, qw (a Pose is accepted)
    gripper: np.ndarray  # (G,) finger joint positions (or width)
    joint_positions: np.ndarray  # (7,)
    object_poses: Mapping[str, np.ndarray]  # id -> (7,) (Poses accepted)
    images: Mapping[str, np.ndarray] = field(default_factory=dict)
    # (6,) external force (N) / torque (N m, about the EE) on the hand, world frame, as the driver
    # measures it; None when it reports none. Steers the release (release.py), not recorded.
    ee_wrench: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "ee_pose", _pose7(self.ee_pose, "observation ee_pose"))
        object.__setattr__(self, "gripper", np.atleast_1d(np.asarray(self.gripper, float)))
        object.__setattr__(self, "joint_positions", np.asarray(self.joint_positions, float).reshape(-1))
        object.__setattr__(self, "object_poses",
                           {k: _pose7(v, f"observation pose of {k}") for k, v in dict(self.object_poses).items()})
        if self.ee_wrench is not None:
            w = np.asarray(self.ee_wrench, float).reshape(-1)
            if w.shape != (6,):
                raise InvalidInputError(f"observation ee_wrench: expected 6 values, got {w.shape}")
            object.__setattr__(self, "ee_wrench", w)

    def ee_matrix(self) -> np.ndarray:
        return Pose.from_array(self.ee_pose).matrix()


@dataclass(frozen=True)
class StepLabel:
    mp_step: bool  # True: motion-planner / interpolation step; False: skill (replay) step
    skill_index: int  # the skill this step belongs to, or that the motion leads to
    source_demo: int  # index of the source demo the skill segment came from (-1: none)
    initiation_target: np.ndarray  # (7,) the pose the motion targeted for this skill
    augmented: bool = False  # True on recovery steps that initiation augmentation added


@dataclass(frozen=True)
class Episode:
    """One attempt as arrays, in the dataset's layout (see docs/dataset.md)."""

    obs: dict  # key -> (T, ...)
    actions: np.ndarray  # (T,7)
    actions_abs: np.ndarray  # (T,8)
    states: np.ndarray  # (T,S)
    rewards: np.ndarray  # (T,)
    dones: np.ndarray  # (T,)
    labels: dict  # key -> (T, ...)
    object_ids: tuple[str, ...] = ()

    @property
    def num_samples(self) -> int:
        return int(len(self.actions))


class EpisodeRecorder:
    """Accumulates steps during an attempt; `episode()` freezes them into arrays."""

    def __init__(self):
        self._obs: list[Observation] = []
        self._actions: list[np.ndarray] = []
        self._abs: list[np.ndarray] = []
        self._labels: list[StepLabel] = []

    def __len__(self) -> int:
        return len(self._actions)

    def add(self, obs_before: Observation, action: np.ndarray, target: np.ndarray, gripper: float,
            label: StepLabel) -> None:
        self._obs.append(obs_before)
        self._actions.append(np.asarray(action, float).reshape(7))
        self._abs.append(np.concatenate([_pose7(target, "absolute action"), [float(gripper)]]))
        self._labels.append(label)

    def episode(self, success: bool) -> Episode:
        T = len(self._actions)
        ids = tuple(sorted(self._obs[0].object_poses)) if T else ()
        obs: dict[str, np.ndarray] = {}
        if T:
            ee = np.stack([o.ee_pose for o in self._obs])
            obs["robot0_eef_pos"] = ee[:, :3]
            obs["robot0_eef_quat"] = ee[:, 3:]
            obs["robot0_gripper_qpos"] = np.stack([o.gripper for o in self._obs])
            obs["robot0_joint_pos"] = np.stack([o.joint_positions for o in self._obs])
            for oid in ids:
                obs[f"{oid}_pose"] = np.stack([o.object_poses[oid] for o in self._obs])
            obs["object"] = np.concatenate([obs[f"{oid}_pose"] for oid in ids], axis=1) if ids else np.zeros((T, 0))
            for cam in sorted(self._obs[0].images):
                obs[f"{cam}_image"] = np.stack([np.asarray(o.images[cam], np.uint8) for o in self._obs])
            states = np.concatenate([obs["robot0_joint_pos"], obs["robot0_gripper_qpos"], ee, obs["object"]], axis=1)
        else:  # an attempt that failed before moving still gets every key, with zero rows
            obs = {"robot0_eef_pos": np.zeros((0, 3)), "robot0_eef_quat": np.zeros((0, 4)),
                   "robot0_gripper_qpos": np.zeros((0, 0)), "robot0_joint_pos": np.zeros((0, 0)),
                   "object": np.zeros((0, 0))}
            states = np.zeros((0, 0))
        rewards = np.zeros(T)
        dones = np.zeros(T, dtype=np.int64)
        if T:
            dones[-1] = 1
            rewards[-1] = 1.0 if success else 0.0
        labels = {
            "mp_step": np.array([lb.mp_step for lb in self._labels], dtype=np.uint8),
            "skill_index": np.array([lb.skill_index for lb in self._labels], dtype=np.int64),
            "source_demo": np.array([lb.source_demo for lb in self._labels], dtype=np.int64),
            "initiation_target": np.stack([lb.initiation_target for lb in self._labels]) if T else np.zeros((0, 7)),
            "augmented": np.array([lb.augmented for lb in self._labels], dtype=np.uint8),
        }
        return Episode(obs=obs, actions=np.stack(self._actions) if T else np.zeros((0, 7)),
                       actions_abs=np.stack(self._abs) if T else np.zeros((0, 8)), states=states,
                       rewards=rewards, dones=dones, labels=labels, object_ids=ids)
