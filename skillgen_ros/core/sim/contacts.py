"""The external wrench on the hand, from pybullet's contact points.

A real Panda reports its estimated external wrench (libfranka's O_F_ext_hat_K, from the joint
torque sensors); the simulated driver reports the contact forces that produce it: every contact
on the hand and finger links, normal and friction, summed as force and torque about the EE.
"""
from __future__ import annotations

from typing import Iterable

import numpy as np


def hand_wrench(p, robot: int, links: Iterable[int], origin: np.ndarray) -> np.ndarray:
    """(6,) force (N) and torque (N m, about `origin`) that other bodies exert on `links`, world frame."""
    links = set(links)
    wrench = np.zeros(6)
    for c in p.getContactPoints(bodyA=robot):
        if c[3] not in links or c[2] == robot:
            continue
        # contactNormalOnB points from B to A: the normal force pushes the robot along it
        f = c[9] * np.asarray(c[7]) + c[10] * np.asarray(c[11]) + c[12] * np.asarray(c[13])
        wrench[:3] += f
        wrench[3:] += np.cross(np.asarray(c[5]) - origin, f)
    return wrench
