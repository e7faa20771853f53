"""The observation a learned policy sees: the same per-step keys and values the dataset stores.

`policy_obs` turns one generation/deployment `Observation` into the dict of arrays that
`EpisodeRecorder.episode()` writes as row t of `data/demo_N/obs/*` (docs/dataset.md), so a policy
trained on a dataset is fed exactly what it was trained on. Which of these keys a network reads
is chosen by the checkpoint's config (`LOW_DIM_KEYS`, `IMAGE_KEYS`).
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import InvalidInputError
from ..generation.episode import Observation

# robomimic's low-dim observation set for its image/low-dim studies: EE pose, gripper, objects
# (robomimic/exps/templates/bc.json "low_dim"), which the issue names: "EE pose, gripper, object poses".
LOW_DIM_KEYS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object")
# The paper's cameras: a front view and a wrist view at 84x84 (Appendix "Observation Spaces").
IMAGE_KEYS = ("front_image", "wrist_image")


def policy_obs(obs: Observation) -> dict[str, np.ndarray]:
    """One step's observation as the dataset stores it (float64 low-dim, uint8 HxWx3 images)."""
    ids = sorted(obs.object_poses)
    out = {
        "robot0_eef_pos": np.asarray(obs.ee_pose[:3], float),
        "robot0_eef_quat": np.asarray(obs.ee_pose[3:], float),
        "robot0_gripper_qpos": np.asarray(obs.gripper, float),
        "robot0_joint_pos": np.asarray(obs.joint_positions, float),
    }
    for oid in ids:
        out[f"{oid}_pose"] = np.asarray(obs.object_poses[oid], float)
    out["object"] = np.concatenate([out[f"{oid}_pose"] for oid in ids]) if ids else np.zeros(0)
    for cam in sorted(obs.images):
        out[f"{cam}_image"] = np.asarray(obs.images[cam], np.uint8)
    return out


def check_obs(obs: Mapping[str, np.ndarray], shapes: Mapping[str, tuple[int, ...]]) -> None:
    """Raise InvalidInputError unless every key a network reads is present with its trained shape."""
    for k, shape in shapes.items():
        if k not in obs:
            raise InvalidInputError(f"observation lacks {k!r} (the policy reads {sorted(shapes)})")
        got = tuple(np.shape(obs[k]))
        if got != tuple(shape):
            raise InvalidInputError(f"observation {k!r} has shape {got}, the policy was trained on {tuple(shape)}")
        if np.issubdtype(np.asarray(obs[k]).dtype, np.floating) and not np.all(np.isfinite(obs[k])):
            raise InvalidInputError(f"observation {k!r} is not finite")
