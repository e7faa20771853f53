"""What one generation attempt records, step by step, and the arrays it becomes.

Each control step t stores the observation before the action (robomimic convention: o_t, a_t),
the normalized delta-pose action a_t (7: dpos, drot, gripper), the absolute pose it commanded
(8: x, y, z, qx, qy, qz, qw, gripper) and the labels Hybrid Skill Policies need.

Object poses have two sources, and the dataset names which one `obs/<id>_pose` holds
(`observation_source`, in env_args): "ground_truth" - the true pose at every step, which a
simulator knows (robomimic and MimicGen record it); "estimate" - what the robot believed (the
latest perception estimate, a grasped object moved rigidly with the hand), all a real robot has.
What perception estimated, at the steps where it ran, is kept apart from both (`estimates/`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from ..errors import InvalidInputError, SkillGenError
from ..geometry import Pose
from ..skills.transform import matrix_to_array

OBSERVATION_SOURCES = ("ground_truth", "estimate")  # what obs/<id>_pose holds (module docstring)


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
    object_poses: Mapping[str, np.ndarray]  # id -> (7,): the robot's belief (estimates + grasp tracking)
    images: Mapping[str, np.ndarray] = field(default_factory=dict)
    # (6,) external force (N) / torque (N m, about the EE) on the hand, world frame, as the driver
    # measures it; None when it reports none. Steers the release (release.py), not recorded.
    ee_wrench: np.ndarray | None = None
    # id -> (7,) the true poses at this state (a simulator's ground truth); None = not known (yet:
    # the graph fills them in by `stamp_ns` after the attempt, EpisodeRecorder.resolve)
    true_object_poses: Mapping[str, np.ndarray] | None = None
    stamp_ns: int | None = None  # the state's time stamp (sim time in lockstep), ns; None = unknown
    # articulated objects' joint values at this state ({"coffee_machine/lid": rad}, as the driver's
    # object_joint_states names them; {} = the scene has none); None = not known (yet: the graph
    # fills them in by `stamp_ns` after the attempt, from the driver's history, as the true poses)
    object_joints: Mapping[str, float] | None = None

    def __post_init__(self):
        object.__setattr__(self, "ee_pose", _pose7(self.ee_pose, "observation ee_pose"))
        object.__setattr__(self, "gripper", np.atleast_1d(np.asarray(self.gripper, float)))
        object.__setattr__(self, "joint_positions", np.asarray(self.joint_positions, float).reshape(-1))
        object.__setattr__(self, "object_poses",
                           {k: _pose7(v, f"observation pose of {k}") for k, v in dict(self.object_poses).items()})
        if self.true_object_poses is not None:
            object.__setattr__(self, "true_object_poses", {k: _pose7(v, f"true pose of {k}")
                                                           for k, v in dict(self.true_object_poses).items()})
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
    # perception's estimates as events: step (E,), stamp (E,), <id>_pose (E,7); see EpisodeRecorder
    estimates: dict = field(default_factory=dict)

    @property
    def num_samples(self) -> int:
        return int(len(self.actions))


class EpisodeRecorder:
    """Accumulates steps during an attempt; `episode()` freezes them into arrays.

    observation_source "ground_truth": every step's object poses are its true ones (an observation
    without them must be resolved by stamp first); "estimate": the robot's belief. Perception's
    estimates are recorded as events (`add_estimate`) at the step they precede.
    """

    def __init__(self, observation_source: str = "ground_truth"):
        if observation_source not in OBSERVATION_SOURCES:
            raise InvalidInputError(f"observation_source must be one of {OBSERVATION_SOURCES}, "
                                    f"got {observation_source!r}", reason="INVALID_PARAMETER")
        self.source = observation_source
        self._obs: list[Observation] = []
        self._actions: list[np.ndarray] = []
        self._abs: list[np.ndarray] = []
        self._labels: list[StepLabel] = []
        self._estimates: list[tuple[int, int | None, dict]] = []  # (step, stamp ns, id -> (7,))

    def __len__(self) -> int:
        return len(self._actions)

    def add(self, obs_before: Observation, action: np.ndarray, target: np.ndarray, gripper: float,
            label: StepLabel) -> None:
        self._obs.append(obs_before)
        self._actions.append(np.asarray(action, float).reshape(7))
        self._abs.append(np.concatenate([_pose7(target, "absolute action"), [float(gripper)]]))
        self._labels.append(label)

    def add_estimate(self, stamp_ns: int | None, poses: Mapping) -> None:
        """Perception ran on sensor data stamped `stamp_ns` and estimated `poses` (id -> pose);
        the attempt acts on them from the next recorded step on."""
        self._estimates.append((len(self), stamp_ns, {k: _pose7(v, f"estimate of {k}") for k, v in poses.items()}))

    def unresolved_stamps(self) -> list[int]:
        """Stamps of recorded steps whose true object poses are still to be looked up (ground_truth only)."""
        if self.source != "ground_truth":
            return []
        return [o.stamp_ns for o in self._obs if o.true_object_poses is None and o.stamp_ns is not None]

    def unresolved_joint_stamps(self) -> list[int]:
        """Stamps of recorded steps whose articulated joint values are still to be looked up (either source:
        obs/<id>_joints is the sim's in both, as in-process)."""
        return [o.stamp_ns for o in self._obs if o.object_joints is None and o.stamp_ns is not None]

    def resolve(self, truth: Mapping[int, Mapping], joints: Mapping[int, Mapping] | None = None) -> None:
        """Fill in true object poses (stamp ns -> id -> pose) and joint values (stamp ns -> name -> value)
        by stamp where a step lacks them, e.g. from the driver's history."""
        joints = joints or {}
        self._obs = [replace(o, true_object_poses=truth[o.stamp_ns])
                     if o.true_object_poses is None and o.stamp_ns in truth else o for o in self._obs]
        self._obs = [replace(o, object_joints=dict(joints[o.stamp_ns]))
                     if o.object_joints is None and o.stamp_ns in joints else o for o in self._obs]

    def require_ground_truth(self, obs: Observation, lookup) -> None:
        """observation_source ground_truth: raise NO_GROUND_TRUTH unless `obs` has true poses or the
        env can look them up by stamp (other lookup errors, e.g. a timeout, pass through)."""
        if self.source != "ground_truth" or obs.true_object_poses is not None:
            return
        try:
            if lookup is None or obs.stamp_ns is None:
                raise InvalidInputError("it has no lookup by stamp", reason="NO_GROUND_TRUTH")
            lookup([obs.stamp_ns])
        except SkillGenError as e:
            if e.reason != "NO_GROUND_TRUTH":
                raise
            raise InvalidInputError(f"observation_source ground_truth, but this robot reports no true object "
                                    f"poses ({e}); use observation_source estimate on a real robot",
                                    reason="NO_GROUND_TRUTH") from e

    def resolve_from(self, lookup, joints_lookup=None) -> None:
        """Steps recorded with only a stamp (the graph's observed steps) get their true object poses in
        one lookup(stamps) -> {stamp: {id: pose}} (RosGraphEnv.true_object_poses: the driver's history),
        and their articulated joint values from joints_lookup(stamps) -> {stamp: {name: value}}
        (RosGraphEnv.true_object_joints); without a joints_lookup they stay unknown (NaN rows)."""
        stamps = self.unresolved_stamps()
        if stamps:
            if lookup is None:
                raise InvalidInputError("steps lack true object poses and the env cannot look them up",
                                        reason="NO_GROUND_TRUTH")
            self.resolve(lookup(stamps))
        stamps = self.unresolved_joint_stamps()
        if stamps and joints_lookup is not None:
            self.resolve({}, joints_lookup(stamps))

    def _object_poses(self, ids) -> dict[str, np.ndarray]:
        if self.source == "estimate":
            return {oid: np.stack([o.object_poses[oid] for o in self._obs]) for oid in ids}
        missing = [t for t, o in enumerate(self._obs) if o.true_object_poses is None]
        if missing:
            raise InvalidInputError(f"observation_source ground_truth, but {len(missing)} steps (first: {missing[0]}) "
                                    "have no true object poses", reason="NO_GROUND_TRUTH")
        return {oid: np.stack([o.true_object_poses[oid] for o in self._obs]) for oid in ids}

    def _estimate_arrays(self) -> dict[str, np.ndarray]:
        """estimates/: step (E,), stamp (E,) s since step 0's state (NaN: unknown), <id>_pose (E,7), NaN
        where that estimate did not include the object."""
        E = len(self._estimates)
        t0 = self._obs[0].stamp_ns if self._obs else None
        out = {"step": np.array([e[0] for e in self._estimates], dtype=np.int64),
               "stamp": np.array([(e[1] - t0) * 1e-9 if e[1] is not None and t0 is not None else np.nan
                                  for e in self._estimates], dtype=float)}
        for oid in sorted({k for e in self._estimates for k in e[2]}):
            a = np.full((E, 7), np.nan)
            for i, e in enumerate(self._estimates):
                if oid in e[2]:
                    a[i] = e[2][oid]
            out[f"{oid}_pose"] = a
        return out

    def _joint_arrays(self) -> dict[str, np.ndarray]:
        """obs/<id>_joints (T, J): each articulated object's joint values, its joints in the order the first
        observation names them ("<id>/<joint>"); a step without values is NaN. None if no step has any."""
        names = next((list(o.object_joints) for o in self._obs if o.object_joints), [])
        out: dict[str, np.ndarray] = {}
        for oid in dict.fromkeys(n.split("/", 1)[0] for n in names):
            keys = [n for n in names if n.split("/", 1)[0] == oid]
            out[f"{oid}_joints"] = np.array([[float((o.object_joints or {}).get(k, np.nan)) for k in keys]
                                             for o in self._obs])
        return out

    def episode(self, success: bool) -> Episode:
        T = len(self._actions)
        first = self._obs[0] if T else None
        if T and self.source == "ground_truth" and first.true_object_poses is not None:
            ids = tuple(sorted(first.true_object_poses))
        else:
            ids = tuple(sorted(first.object_poses)) if T else ()
        obs: dict[str, np.ndarray] = {}
        if T:
            ee = np.stack([o.ee_pose for o in self._obs])
            obs["robot0_eef_pos"] = ee[:, :3]
            obs["robot0_eef_quat"] = ee[:, 3:]
            obs["robot0_gripper_qpos"] = np.stack([o.gripper for o in self._obs])
            obs["robot0_joint_pos"] = np.stack([o.joint_positions for o in self._obs])
            for oid, poses in self._object_poses(ids).items():
                obs[f"{oid}_pose"] = poses
            obs["object"] = np.concatenate([obs[f"{oid}_pose"] for oid in ids], axis=1) if ids else np.zeros((T, 0))
            obs.update(self._joint_arrays())
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
                       rewards=rewards, dones=dones, labels=labels, object_ids=ids,
                       estimates=self._estimate_arrays())
