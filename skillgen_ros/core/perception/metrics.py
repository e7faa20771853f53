"""Pose-error metrics: translation, symmetry-aware rotation error, ADD and ADD-S (Hinterstoisser 2012).

A nut turned by a quarter turn is the same nut: rotation error is the minimum over the object's
symmetry group, and ADD-S (closest-point distance) is the symmetric counterpart of ADD.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..geometry import rotation_angle
from .models import Symmetry


def translation_error(T_est: np.ndarray, T_gt: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(T_est)[:3, 3] - np.asarray(T_gt)[:3, 3]))


def rotation_error(R_est: np.ndarray, R_gt: np.ndarray, symmetry=Symmetry.NONE) -> float:
    """Smallest geodesic angle (rad) between R_est and any symmetric equivalent of R_gt.

    For continuous symmetry about z only the z axis is defined, so the error is the angle
    between the two z axes.
    """
    sym = Symmetry.parse(symmetry)
    R_est, R_gt = np.asarray(R_est, float), np.asarray(R_gt, float)
    if sym is Symmetry.Z_CONTINUOUS:
        c = float(np.clip(R_est[:, 2] @ R_gt[:, 2], -1.0, 1.0))
        return float(np.arccos(c))
    return min(rotation_angle(R_est, R_gt @ S) for S in sym.rotations())


def add(points: np.ndarray, T_est: np.ndarray, T_gt: np.ndarray) -> float:
    """Mean distance between corresponding model points under the two poses."""
    a = points @ T_est[:3, :3].T + T_est[:3, 3]
    b = points @ T_gt[:3, :3].T + T_gt[:3, 3]
    return float(np.mean(np.linalg.norm(a - b, axis=1)))


def add_s(points: np.ndarray, T_est: np.ndarray, T_gt: np.ndarray) -> float:
    """Mean distance from each estimated model point to the closest ground-truth model point."""
    a = points @ T_est[:3, :3].T + T_est[:3, 3]
    b = points @ T_gt[:3, :3].T + T_gt[:3, 3]
    d, _ = cKDTree(b).query(a)
    return float(np.mean(d))
