"""Rigid-body poses: the one place where position + quaternion <-> 4x4 matrix conversions live.

Quaternions are (x, y, z, w), as in geometry_msgs and scipy. Rotations go through
scipy.spatial.transform.Rotation; nothing here hand-rolls quaternion algebra.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy.spatial.transform import Rotation

from .errors import InvalidInputError

_UNIT_TOL = 1e-3


@dataclass(frozen=True)
class Pose:
    """A pose in SE(3): position (3,) metres and quaternion (4,) x, y, z, w."""

    position: np.ndarray
    quaternion: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "position", np.asarray(self.position, dtype=float).reshape(3))
        object.__setattr__(self, "quaternion", np.asarray(self.quaternion, dtype=float).reshape(4))

    @staticmethod
    def identity() -> "Pose":
        return Pose(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))

    @staticmethod
    def from_matrix(T: np.ndarray) -> "Pose":
        T = np.asarray(T, dtype=float)
        return Pose(T[:3, 3].copy(), Rotation.from_matrix(T[:3, :3]).as_quat())

    @staticmethod
    def from_xyz_rpy(xyz, rpy) -> "Pose":
        return Pose(np.asarray(xyz, float), Rotation.from_euler("xyz", rpy).as_quat())

    @property
    def rotation(self) -> Rotation:
        return Rotation.from_quat(self.quaternion)

    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.rotation.as_matrix()
        T[:3, 3] = self.position
        return T

    def inverse(self) -> "Pose":
        return Pose.from_matrix(invert(self.matrix()))

    def __matmul__(self, other: "Pose") -> "Pose":
        return Pose.from_matrix(self.matrix() @ other.matrix())

    def as_array(self) -> np.ndarray:
        """(7,) array: x, y, z, qx, qy, qz, qw."""
        return np.concatenate([self.position, self.quaternion])

    @staticmethod
    def from_array(a) -> "Pose":
        a = np.asarray(a, dtype=float).reshape(7)
        return Pose(a[:3], a[3:])


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a homogeneous transform (or a stack of them, shape (..., 4, 4))."""
    T = np.asarray(T, dtype=float)
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)
    out[..., 3, 3] = 1.0
    return out


def make_T(position, rotation_matrix) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation_matrix
    T[:3, 3] = position
    return T


def pose_arrays_to_matrices(pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """(N,3) positions + (N,4) xyzw quaternions -> (N,4,4)."""
    pos = np.asarray(pos, float).reshape(-1, 3)
    quat = np.asarray(quat, float).reshape(-1, 4)
    T = np.tile(np.eye(4), (len(pos), 1, 1))
    T[:, :3, :3] = Rotation.from_quat(quat).as_matrix()
    T[:, :3, 3] = pos
    return T


def matrices_to_pose_arrays(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,4,4) -> (N,3) positions, (N,4) xyzw quaternions."""
    T = np.asarray(T, float).reshape(-1, 4, 4)
    return T[:, :3, 3].copy(), Rotation.from_matrix(T[:, :3, :3]).as_quat()


def validate_pose(position, quaternion, what: str = "pose") -> Pose:
    """Reject NaN/inf and non-unit quaternions with a clear INVALID_INPUT error."""
    p = np.asarray(position, dtype=float).reshape(-1)
    q = np.asarray(quaternion, dtype=float).reshape(-1)
    if p.shape != (3,) or q.shape != (4,):
        raise InvalidInputError(f"{what}: expected 3 position and 4 quaternion values")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise InvalidInputError(f"{what}: NaN or inf in position {p.tolist()} / quaternion {q.tolist()}")
    n = float(np.linalg.norm(q))
    if abs(n - 1.0) > _UNIT_TOL:
        raise InvalidInputError(f"{what}: quaternion norm {n:.6f} is not 1")
    return Pose(p, q / n)


def rotation_angle(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Geodesic angle (rad) between two rotation matrices."""
    c = (np.trace(np.asarray(R_a).T @ np.asarray(R_b)) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


class Symmetry(str, Enum):
    """Rotational symmetry about the object's z axis through its frame origin."""

    NONE = "none"
    Z2 = "z2"
    Z4 = "z4"
    Z_CONTINUOUS = "z_continuous"

    @property
    def order(self) -> int:
        """Number of discrete symmetric yaws (0 for continuous)."""
        return {"none": 1, "z2": 2, "z4": 4, "z_continuous": 0}[self.value]

    @property
    def yaw_period(self) -> float:
        """Yaw range (rad) that holds one representative of every distinct pose."""
        return 0.0 if self.order == 0 else 2 * np.pi / self.order

    def rotations(self, continuous_samples: int = 1) -> list[np.ndarray]:
        """The discrete group elements as 3x3 matrices, identity first; a continuous symmetry is
        sampled at `continuous_samples` evenly spaced yaws (1: identity only)."""
        k = self.order or max(continuous_samples, 1)
        return [Rotation.from_euler("z", 2 * np.pi * i / k).as_matrix() for i in range(k)]

    @staticmethod
    def parse(value) -> "Symmetry":
        try:
            return value if isinstance(value, Symmetry) else Symmetry(str(value).lower())
        except ValueError:
            raise InvalidInputError(f"unknown symmetry {value!r}; expected one of "
                                    f"{[s.value for s in Symmetry]}") from None


def poses_in_frame(frames: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(N,7) poses expressed in (N,7) frames (x y z qx qy qz qw): row i is frames[i]^-1 * poses[i].

    Quaternions come out with qw >= 0 (one sign per rotation, so a network sees no sign flips).
    A row with a non-finite input is NaN (an object pose that was not estimated stays unknown).
    """
    frames = np.asarray(frames, float).reshape(-1, 7)
    poses = np.asarray(poses, float).reshape(-1, 7)
    out = np.full((len(poses), 7), np.nan)
    ok = np.all(np.isfinite(frames), axis=1) & np.all(np.isfinite(poses), axis=1)
    if ok.any():
        R_f = Rotation.from_quat(frames[ok, 3:])
        out[ok, :3] = R_f.inv().apply(poses[ok, :3] - frames[ok, :3])
        out[ok, 3:] = (R_f.inv() * Rotation.from_quat(poses[ok, 3:])).as_quat(canonical=True)
    return out
