"""Panda forward kinematics and Jacobians through pinocchio, plus a batched numpy FK.

pinocchio is the reference (single configuration, ~1 us per call); the batched FK evaluates
thousands of configurations in a handful of numpy matmuls, which is what vectorized collision
checking of whole edges and the concurrent IK restarts need. Both read the same joint placements,
so they agree to machine precision (tested against each other and against pybullet).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError
from . import kernels
from ..robot import ARM_JOINTS, EE_LINK, FINGER_JOINTS, HAND_LINK, Q_LOWER, Q_UPPER, panda_urdf_path

# Links whose poses the collision model needs, in chain order; index 0 is the fixed base.
LINKS = ("panda_link0", "panda_link1", "panda_link2", "panda_link3", "panda_link4",
         "panda_link5", "panda_link6", "panda_link7", HAND_LINK)


def _rz(q: np.ndarray) -> np.ndarray:
    """(N,) angles -> (N,4,4) rotations about z."""
    c, s = np.cos(q), np.sin(q)
    T = np.zeros(q.shape + (4, 4))
    T[..., 0, 0] = c
    T[..., 0, 1] = -s
    T[..., 1, 0] = s
    T[..., 1, 1] = c
    T[..., 2, 2] = 1.0
    T[..., 3, 3] = 1.0
    return T


class PandaKinematics:
    """The 7-DoF arm (fingers locked open) from pybullet_data's panda.urdf.

    `fk(q)` gives the 4x4 pose of `panda_grasptarget` in the base (= world) frame.
    """

    def __init__(self, finger_opening: float = 0.04):
        full = pin.buildModelFromUrdf(panda_urdf_path())
        q_ref = pin.neutral(full)
        lock = []
        for name in FINGER_JOINTS:
            jid = full.getJointId(name)
            q_ref[full.joints[jid].idx_q] = finger_opening
            lock.append(jid)
        self.model = pin.buildReducedModel(full, lock, q_ref)
        self.data = self.model.createData()
        names = [self.model.names[i] for i in range(1, self.model.njoints)]
        if tuple(names) != ARM_JOINTS:
            raise InvalidInputError(f"unexpected joint order in URDF: {names}")
        self.ee_frame = self.model.getFrameId(EE_LINK)
        self.link_frames = [self.model.getFrameId(n) for n in LINKS]
        self.lower = Q_LOWER.copy()
        self.upper = Q_UPPER.copy()
        # Batched FK tables: joint placements (parent joint -> joint) and each link's fixed
        # placement in its parent joint frame.
        self._joint_T = np.stack([self.model.jointPlacements[i].homogeneous for i in range(1, 8)])
        self._link_parent = np.array([self.model.frames[f].parentJoint for f in self.link_frames],
                                     dtype=np.int64)
        self._link_T = np.stack([self.model.frames[f].placement.homogeneous for f in self.link_frames])
        self._ee_parent = self.model.frames[self.ee_frame].parentJoint
        self._ee_T = self.model.frames[self.ee_frame].placement.homogeneous

    # -- single configuration (pinocchio) -------------------------------------------------
    def _check(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (7,) or not np.all(np.isfinite(q)):
            raise InvalidInputError(f"expected 7 finite joint positions, got {q.tolist()}")
        return q

    def fk(self, q) -> np.ndarray:
        """4x4 pose of the EE (panda_grasptarget) in the world frame."""
        q = self._check(q)
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.ee_frame).homogeneous.copy()

    def link_poses(self, q) -> dict[str, np.ndarray]:
        """World poses (4x4) of panda_link0..7 and panda_hand."""
        q = self._check(q)
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return {n: self.data.oMf[f].homogeneous.copy() for n, f in zip(LINKS, self.link_frames)}

    def jacobian(self, q) -> np.ndarray:
        """6x7 geometric Jacobian of the EE, rows (v, w) in the world-aligned EE frame."""
        q = self._check(q)
        return pin.computeFrameJacobian(self.model, self.data, q, self.ee_frame,
                                        pin.LOCAL_WORLD_ALIGNED).copy()

    def within_limits(self, q, tol: float = 1e-9) -> bool:
        q = np.asarray(q, float)
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    # -- batched (numpy) --------------------------------------------------------------------
    def joint_frames_batch(self, Q: np.ndarray) -> np.ndarray:
        """(N,7) -> (N,8,4,4): universe (identity) then the seven joint frames."""
        Q = np.asarray(Q, float).reshape(-1, 7)
        n = len(Q)
        out = np.empty((n, 8, 4, 4))
        out[:, 0] = np.eye(4)
        R = _rz(Q)
        for i in range(7):
            out[:, i + 1] = out[:, i] @ self._joint_T[i] @ R[:, i]
        return out

    def link_poses_batch(self, Q: np.ndarray) -> np.ndarray:
        """(N,7) -> (N,len(LINKS),4,4) world poses of LINKS (numba kernel)."""
        Q = np.ascontiguousarray(np.asarray(Q, float).reshape(-1, 7))
        return kernels.link_poses_batch(Q, self._joint_T, self._link_parent, self._link_T)

    def fk_batch(self, Q: np.ndarray) -> np.ndarray:
        """(N,7) -> (N,4,4) EE poses."""
        J = self.joint_frames_batch(Q)
        return J[:, self._ee_parent] @ self._ee_T
