"""Initiation augmentation (paper Sec. "Initiation Augmentation", Appendix "Data Generation Details").

The planner's target T_W^{E_0} is perturbed to T_W^{E_0'}: uniform position noise U[-t, t] per
axis, and a rotation by an angle U[0, r] about a uniformly random axis, applied in the world
frame (R' = R_noise R). A recovery segment of pose actions then moves the end effector from the
perturbed pose back to the original initiation pose, so the closed-loop skill learns to recover.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import InvalidInputError


MAX_TRANSLATION = 0.5  # m: beyond the Panda's workspace scale a perturbation is a mistake, not noise


@dataclass(frozen=True)
class AugmentationConfig:
    translation: float = 0.08  # t, metres (paper: 0.08)
    rotation_deg: float = 80.0  # r, degrees (paper: 80)
    recovery_step_pos: float = 0.01  # max metres per recovery step
    recovery_step_rot: float = 0.05  # max radians per recovery step

    def __post_init__(self):
        # written so that NaN fails every comparison (issue 19: NaN reached rng.uniform)
        if not (0 <= self.translation <= MAX_TRANSLATION and 0 <= self.rotation_deg <= 180):
            raise InvalidInputError(f"augmentation needs 0 <= t <= {MAX_TRANSLATION} m and 0 <= r <= 180 deg, "
                                    f"got {self}", reason="INVALID_PARAMETER")
        if not (0 < self.recovery_step_pos < float("inf") and 0 < self.recovery_step_rot < float("inf")):
            raise InvalidInputError("recovery step sizes must be positive", reason="INVALID_PARAMETER")


def perturb_initiation(T: np.ndarray, config: AugmentationConfig, rng: np.random.Generator) -> np.ndarray:
    """T_W^{E_0} (4,4) -> perturbed T_W^{E_0'} (4,4)."""
    T = np.asarray(T, float)
    out = T.copy()
    out[:3, 3] = T[:3, 3] + rng.uniform(-config.translation, config.translation, size=3)
    axis = rng.standard_normal(3)
    axis /= max(np.linalg.norm(axis), 1e-12)  # uniform on the sphere
    angle = rng.uniform(0.0, np.deg2rad(config.rotation_deg))
    out[:3, :3] = Rotation.from_rotvec(axis * angle).as_matrix() @ T[:3, :3]
    return out


def interpolate_poses(T_from: np.ndarray, T_to: np.ndarray, num: int) -> np.ndarray:
    """`num` poses strictly after T_from up to and including T_to: linear position, slerp rotation."""
    if num < 1:
        raise InvalidInputError(f"interpolation needs at least one step, got {num}")
    T_from = np.asarray(T_from, float)
    T_to = np.asarray(T_to, float)
    s = np.arange(1, num + 1) / num
    rots = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T_from[:3, :3], T_to[:3, :3]])))(s)
    out = np.tile(np.eye(4), (num, 1, 1))
    out[:, :3, :3] = rots.as_matrix()
    out[:, :3, 3] = T_from[:3, 3] + s[:, None] * (T_to[:3, 3] - T_from[:3, 3])
    out[-1] = T_to  # exact end point
    return out


def recovery_segment(T_from: np.ndarray, T_to: np.ndarray, config: AugmentationConfig = AugmentationConfig()) -> np.ndarray:
    """Pose actions (K,4,4) from the perturbed pose back to the original initiation pose.

    K is the fewest steps that keep each step within the configured position/rotation step.
    """
    T_from = np.asarray(T_from, float)
    T_to = np.asarray(T_to, float)
    dist = float(np.linalg.norm(T_to[:3, 3] - T_from[:3, 3]))
    ang = float(Rotation.from_matrix(T_to[:3, :3] @ T_from[:3, :3].T).magnitude())
    k = max(1, int(np.ceil(max(dist / config.recovery_step_pos, ang / config.recovery_step_rot) - 1e-9)))
    return interpolate_poses(T_from, T_to, k)
