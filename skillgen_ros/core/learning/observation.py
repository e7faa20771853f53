"""The observation a learned policy sees: the per-step keys the dataset stores, plus DERIVED_KEYS.

`policy_obs` turns one generation/deployment `Observation` into the dict of arrays that
`EpisodeRecorder.episode()` writes as row t of `data/demo_N/obs/*` (docs/dataset.md), plus the keys
`add_derived` computes from them (the training reader derives them the same way), so a policy
trained on a dataset is fed exactly what it was trained on. Which of these keys a network reads
is chosen by the checkpoint's config (`LOW_DIM_KEYS`, `IMAGE_KEYS`).
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import InvalidInputError
from ..generation.episode import Observation
from ..geometry import poses_in_frame

# robomimic's low-dim observation set for its image/low-dim studies: EE pose, gripper, objects
# (robomimic/exps/templates/bc.json "low_dim"), which the issue names: "EE pose, gripper, object poses".
# robomimic's "object" is robosuite's object-state: per object its pose *and* its pose in the hand's
# frame (robosuite/environments/manipulation/nut_assembly.py `{nut}_to_{pf}eef_pos`/`_quat`; MimicGen's
# variants add the same for their objects). Our dataset's obs/object holds the world poses; the
# hand-frame part is `object_to_eef`, derived from the stored keys (DERIVED_KEYS), never stored.
LOW_DIM_KEYS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object", "object_to_eef")
DERIVED_KEYS = ("object_to_eef",)
DERIVED_FROM = ("robot0_eef_pos", "robot0_eef_quat", "object")  # the stored keys they are computed from
# The paper's cameras: a front view and a wrist view at 84x84 (Appendix "Observation Spaces").
IMAGE_KEYS = ("front_image", "wrist_image")


def object_to_eef(eef_pos: np.ndarray, eef_quat: np.ndarray, objects: np.ndarray) -> np.ndarray:
    """(T,7K) each object's pose in the end-effector frame, from (T,3), (T,4) and obs/object (T,7K)."""
    objects = np.asarray(objects, float)
    T = len(objects)
    ee = np.concatenate([np.asarray(eef_pos, float).reshape(T, 3), np.asarray(eef_quat, float).reshape(T, 4)], 1)
    blocks = [poses_in_frame(ee, objects[:, i:i + 7]) for i in range(0, objects.shape[1], 7)]
    return np.concatenate(blocks, axis=1) if blocks else np.zeros((T, 0))


def add_derived(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """obs (one step or a (T, ...) sequence of the stored keys) with DERIVED_KEYS added, in place."""
    single = np.ndim(obs["object"]) == 1
    rows = {k: np.atleast_2d(obs[k]) for k in DERIVED_FROM}
    rel = object_to_eef(rows["robot0_eef_pos"], rows["robot0_eef_quat"], rows["object"])
    obs["object_to_eef"] = rel[0] if single else rel
    return obs


def derived_shapes(shapes: Mapping[str, tuple[int, ...]]) -> dict[str, tuple[int, ...]]:
    """Per-step shapes of DERIVED_KEYS, given the stored keys' shapes."""
    return {"object_to_eef": tuple(shapes["object"])} if "object" in shapes else {}


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
    return add_derived(out)


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
