"""The continuous 6D rotation representation (Zhou et al., CVPR 2019) used by HSP-Reg's targets.

A rotation is stored as the first two columns of its matrix, [r11 r21 r31 r12 r22 r32]; any 6
numbers map back to a rotation by Gram-Schmidt, so a regressed 6D vector is always a valid
rotation. Poses are x y z qx qy qz qw (the dataset's convention) <-> x y z + 6D (9 numbers).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError


def matrix_to_rotation_6d(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 6): the first two columns."""
    m = np.asarray(m, float)
    return np.concatenate([m[..., :, 0], m[..., :, 1]], axis=-1)


def rotation_6d_to_matrix(r6: np.ndarray) -> np.ndarray:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt (Zhou et al., Sec. 4.2)."""
    r6 = np.asarray(r6, float)
    a1, a2 = r6[..., :3], r6[..., 3:6]
    n1 = np.linalg.norm(a1, axis=-1, keepdims=True)
    if np.any(n1 < 1e-9):
        raise InvalidInputError("6D rotation has a zero first column")
    b1 = a1 / n1
    u2 = a2 - np.sum(b1 * a2, axis=-1, keepdims=True) * b1
    n2 = np.linalg.norm(u2, axis=-1, keepdims=True)
    if np.any(n2 < 1e-9):
        raise InvalidInputError("6D rotation has parallel columns")
    b2 = u2 / n2
    b3 = np.cross(b1, b2)
    return np.stack([b1, b2, b3], axis=-1)


def quat_to_rotation_6d(q: np.ndarray) -> np.ndarray:
    """(..., 4) x y z w -> (..., 6)."""
    q = np.asarray(q, float)
    return matrix_to_rotation_6d(Rotation.from_quat(q.reshape(-1, 4)).as_matrix()).reshape(*q.shape[:-1], 6)


def rotation_6d_to_quat(r6: np.ndarray) -> np.ndarray:
    """(..., 6) -> (..., 4) x y z w, w >= 0."""
    r6 = np.asarray(r6, float)
    q = Rotation.from_matrix(rotation_6d_to_matrix(r6.reshape(-1, 6))).as_quat()
    q = np.where(q[:, 3:4] < 0, -q, q)
    return q.reshape(*r6.shape[:-1], 4)


def pose_to_pos_rot6d(pose: np.ndarray) -> np.ndarray:
    """(..., 7) x y z qx qy qz qw -> (..., 9) x y z + 6D."""
    pose = np.asarray(pose, float)
    return np.concatenate([pose[..., :3], quat_to_rotation_6d(pose[..., 3:7])], axis=-1)


def pos_rot6d_to_pose(v: np.ndarray) -> np.ndarray:
    """(..., 9) -> (..., 7)."""
    v = np.asarray(v, float)
    return np.concatenate([v[..., :3], rotation_6d_to_quat(v[..., 3:9])], axis=-1)
