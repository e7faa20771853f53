"""MimicGen-style action conversion: absolute target poses <-> normalized delta-pose actions.

robosuite's OSC_POSE convention, as MimicGen uses it: the delta position (target - current, world
frame) is divided by max_dpos (0.05 m) and the delta rotation R_target R_current^T as an
axis-angle vector is divided by max_drot (0.5 rad); both are clipped to [-1, 1]. The inverse
applies the delta to the current pose: p = p_cur + a[:3] max_dpos, R = Rot(a[3:6] max_drot) R_cur.
Action noise N(0,1)*sigma goes on the six pose dimensions only; the gripper is copied as is.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError

MAX_DPOS = 0.05  # m per step at action 1.0 (robosuite OSC_POSE output_max)
MAX_DROT = 0.5  # rad per step at action 1.0
POSE_DIMS = 6  # actions are (dx, dy, dz, rx, ry, rz, gripper)


@dataclass(frozen=True)
class ActionScale:
    """The controller's per-step bounds that map a delta pose to [-1, 1]."""

    max_dpos: float = MAX_DPOS
    max_drot: float = MAX_DROT

    def __post_init__(self):
        if not (self.max_dpos > 0 and self.max_drot > 0):
            raise InvalidInputError(f"action scale must be positive, got {self.max_dpos}, {self.max_drot}")


def pose_to_delta_action(target: np.ndarray, current: np.ndarray, scale: ActionScale = ActionScale(),
                         clip: bool = True) -> np.ndarray:
    """Absolute target (4,4) from the current EE pose (4,4) -> normalized (6,) delta action."""
    target = np.asarray(target, float)
    current = np.asarray(current, float)
    dpos = (target[:3, 3] - current[:3, 3]) / scale.max_dpos
    drot = Rotation.from_matrix(target[:3, :3] @ current[:3, :3].T).as_rotvec() / scale.max_drot
    a = np.concatenate([dpos, drot])
    return np.clip(a, -1.0, 1.0) if clip else a


def delta_action_to_pose(action: np.ndarray, current: np.ndarray, scale: ActionScale = ActionScale()) -> np.ndarray:
    """Normalized delta action (>= 6 values; extra dims ignored) applied to the current pose -> (4,4)."""
    a = np.asarray(action, float).reshape(-1)
    if a.size < POSE_DIMS:
        raise InvalidInputError(f"delta action needs {POSE_DIMS} pose values, got {a.size}")
    current = np.asarray(current, float)
    T = np.eye(4)
    T[:3, 3] = current[:3, 3] + a[:3] * scale.max_dpos
    T[:3, :3] = Rotation.from_rotvec(a[3:6] * scale.max_drot).as_matrix() @ current[:3, :3]
    return T


def add_action_noise(action: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Add N(0,1)*sigma to the pose dims of a (7,) or (N,7) action and clip them to [-1, 1].

    The gripper dimension (index 6) is returned untouched, as the paper specifies.
    """
    if sigma < 0:
        raise InvalidInputError(f"action noise sigma must be >= 0, got {sigma}")
    a = np.array(action, dtype=float, copy=True)
    if a.shape[-1] < POSE_DIMS:
        raise InvalidInputError(f"action needs at least {POSE_DIMS} dims, got shape {a.shape}")
    if sigma > 0:
        noise = rng.standard_normal(a[..., :POSE_DIMS].shape) * sigma
        a[..., :POSE_DIMS] = np.clip(a[..., :POSE_DIMS] + noise, -1.0, 1.0)
    return a


def make_action(target: np.ndarray, current: np.ndarray, gripper: float, sigma: float,
                rng: np.random.Generator | None, scale: ActionScale = ActionScale()) -> tuple[np.ndarray, np.ndarray]:
    """One control step: (7,) noisy normalized action and the (4,4) absolute pose it commands.

    The executed target is recomputed from the (clipped, noisy) action, so the dataset's delta
    action and absolute action always describe the same command.
    """
    a = np.concatenate([pose_to_delta_action(target, current, scale), [float(gripper)]])
    if sigma > 0:
        if rng is None:
            raise InvalidInputError("action noise requested without a random generator")
        a = add_action_noise(a, sigma, rng)
    return a, delta_action_to_pose(a, current, scale)
