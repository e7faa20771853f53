"""The paper's retreat and approach: straight Cartesian moves along the gripper's z axis.

`cartesian_line` tracks T(s) = T0 @ Trans(0, 0, s * d) for s in [0, 1] with Newton IK seeded by
the previous waypoint (so the arm does not flip branches), then keeps only the waypoints needed
for the joint-space interpolation between them to stay within `tol_m` of the line and `tol_rad` of
the orientation -- the timed
trajectory moves in straight joint-space segments, so this bounds the Cartesian deviation.
"""
from __future__ import annotations

import numpy as np

from ..errors import SkillGenError
from .ik import IKSolver
from .kinematics import PandaKinematics


class CartesianPathError(SkillGenError):
    reason = "CARTESIAN_PATH_FAILED"


def _translate_z(d: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = d
    return T


def cartesian_line(kin: PandaKinematics, ik: IKSolver, q0, distance: float, steps: int = 10,
                   max_joint_step: float = 0.2, tol_m: float = 1e-3,
                   tol_rad: float = 1e-3, partial: bool = False) -> np.ndarray:
    """Joint waypoints (K,7) moving the EE `distance` metres along its own z (negative = back).

    partial: where IK loses the line (e.g. the wrist at its joint limit after a grasp), return
    the part already done instead of failing, provided at least one step was made."""
    q = np.asarray(q0, float).copy()
    T0 = kin.fk(q)
    dense = [q]
    for s in np.linspace(0.0, 1.0, steps + 1)[1:]:
        qn = ik.solve_local(T0 @ _translate_z(s * distance), q)
        why = None
        if qn is None:
            why = f"IK lost the line at {s * distance:+.3f} m"
        elif np.abs(qn - q).max() > max_joint_step:
            why = f"joint jump {np.abs(qn - q).max():.2f} rad at {s * distance:+.3f} m"
        if why is not None:
            if partial and len(dense) > 1:
                break
            raise CartesianPathError(why)
        dense.append(qn)
        q = qn
    dense = np.array(dense)
    return _reduce(kin, T0, dense, tol_m, tol_rad)


def line_deviation(kin: PandaKinematics, T0: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Distance (m) of each configuration's EE from the line through T0 along its z axis."""
    p = kin.fk_batch(Q)[:, :3, 3] - T0[:3, 3]
    z = T0[:3, 2]
    return np.linalg.norm(p - np.outer(p @ z, z), axis=1)


def orientation_deviation(kin: PandaKinematics, T0: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Angle (rad) between each configuration's EE orientation and T0's."""
    R = kin.fk_batch(Q)[:, :3, :3]
    c = (np.einsum("nij,ij->n", R, T0[:3, :3]) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def _reduce(kin, T0, dense, tol_m, tol_rad) -> np.ndarray:
    """Keep the fewest waypoints whose joint-linear interpolation stays within tol_m of the line
    and within tol_rad of the start orientation."""
    keep = [0]
    i = 0
    while i < len(dense) - 1:
        j = len(dense) - 1
        while j > i + 1:
            s = np.linspace(0.0, 1.0, 21)[:, None]
            Q = dense[i] + s * (dense[j] - dense[i])
            if (line_deviation(kin, T0, Q).max() <= tol_m
                    and orientation_deviation(kin, T0, Q).max() <= tol_rad):
                break
            j -= 1
        keep.append(j)
        i = j
    return dense[keep]
