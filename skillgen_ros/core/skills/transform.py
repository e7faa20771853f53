"""Object-frame transforms of end-effector poses (paper Sec. "Source Demonstrations").

A skill's pose actions are stored relative to the skill object observed before the skill,
T_O^A = (T_W^O)^-1 T_W^A, and replayed in a new scene as T_W^A' = T_W^O' T_O^A. Everything
here works on 4x4 homogeneous matrices or stacks of them (..., 4, 4); `Pose` is accepted too.
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose, invert


def as_matrix(pose, what: str = "pose") -> np.ndarray:
    """A `Pose`, a (7,) x,y,z,qx,qy,qz,qw array or a (4,4)/(N,4,4) matrix -> matrix (stack)."""
    if isinstance(pose, Pose):
        return pose.matrix()
    a = np.asarray(pose, dtype=float)
    if a.shape == (7,):
        return Pose.from_array(a).matrix()
    if a.ndim >= 2 and a.shape[-2:] == (4, 4):
        return a
    raise InvalidInputError(f"{what}: expected a Pose, a (7,) array or (...,4,4) matrices, got shape {a.shape}")


def to_object_frame(T_W_O, T_W_A) -> np.ndarray:
    """World-frame poses T_W^A (stack) -> object-frame poses T_O^A = (T_W^O)^-1 T_W^A."""
    return invert(as_matrix(T_W_O, "object pose")) @ as_matrix(T_W_A, "world pose")


def to_world(T_W_O, T_O_A) -> np.ndarray:
    """Object-frame poses T_O^A (stack) -> world-frame poses T_W^A' = T_W^O' T_O^A."""
    return as_matrix(T_W_O, "object pose") @ as_matrix(T_O_A, "object-frame pose")


def matrix_to_array(T: np.ndarray) -> np.ndarray:
    """(4,4) or (N,4,4) -> (7,) or (N,7) x,y,z,qx,qy,qz,qw (the dataset's pose layout)."""
    from scipy.spatial.transform import Rotation

    T = np.asarray(T, dtype=float)
    flat = T.reshape(-1, 4, 4)
    out = np.concatenate([flat[:, :3, 3], Rotation.from_matrix(flat[:, :3, :3]).as_quat()], axis=1)
    return out[0] if T.ndim == 2 else out
