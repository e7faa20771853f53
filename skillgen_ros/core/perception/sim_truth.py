"""Ground truth from the pybullet world for tests and benchmarks (never used to estimate poses).

pybullet reports a body's centre-of-mass frame (getBasePositionAndOrientation), which differs from
the object's mesh frame when the centre of mass is off the AABB centre (a nut's handle, a needle's
shaft). Perception estimates the mesh frame, so truth is taken as the COM frame composed with the
inverse of the body's local inertial offset, read from pybullet itself.
"""
from __future__ import annotations

import numpy as np

from ..geometry import pose_arrays_to_matrices


def object_frame_poses(world) -> dict[str, np.ndarray]:
    """id -> 4x4 world pose of each object's mesh frame in a core.sim.SimWorld."""
    p = world.p
    out = {}
    for oid, body in world.bodies.items():
        pos, quat = p.getBasePositionAndOrientation(body)
        info = p.getDynamicsInfo(body, -1)
        T_com = pose_arrays_to_matrices(np.array(pos), np.array(quat))[0]
        T_loc = pose_arrays_to_matrices(np.array(info[3]), np.array(info[4]))[0]
        out[oid] = T_com @ np.linalg.inv(T_loc)
    return out
