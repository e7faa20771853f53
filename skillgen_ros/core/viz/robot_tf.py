"""The Panda's TF tree: world -> panda_link0 -> every URDF link, from joint positions.

Forward kinematics is pinocchio's over the same URDF the sim and the planner load
(core/robot.panda_urdf_path), with the fingers included; each URDF joint becomes one transform
parent link -> child link, as robot_state_publisher would publish it: fixed joints on /tf_static,
moving ones on /tf. The robot base is the world origin (core/robot.py).
"""
from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import pinocchio as pin

from ..errors import InvalidInputError
from ..robot import BASE_LINK, panda_urdf_path
from .messages import Transform

WORLD = "world"


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    kind: str  # revolute, prismatic, fixed, ...
    parent: str
    child: str


class PandaTf:
    """Transforms of every Panda link for a joint state (names -> positions)."""

    def __init__(self, urdf_path: str | None = None):
        path = urdf_path or panda_urdf_path()
        self.model = pin.buildModelFromUrdf(path)
        self.data = self.model.createData()
        root = ET.parse(path).getroot()
        self.joints = tuple(UrdfJoint(j.get("name"), j.get("type"), j.find("parent").get("link"),
                                      j.find("child").get("link")) for j in root.findall("joint"))
        self.links = (BASE_LINK,) + tuple(j.child for j in self.joints)
        self.joint_names = tuple(self.model.names[i] for i in range(1, self.model.njoints))
        self._frame = {n: self.model.getFrameId(n) for n in self.links}

    @property
    def moving(self) -> tuple[UrdfJoint, ...]:
        return tuple(j for j in self.joints if j.kind != "fixed")

    def _placements(self, positions: Mapping[str, float]) -> dict[str, "pin.SE3"]:
        q = pin.neutral(self.model)
        for name, value in positions.items():
            if name in self.joint_names:
                v = float(value)
                if not np.isfinite(v):
                    raise InvalidInputError(f"joint {name} position is not finite: {value}")
                q[self.model.joints[self.model.getJointId(name)].idx_q] = v
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return {n: self.data.oMf[f] for n, f in self._frame.items()}

    def link_poses(self, positions: Mapping[str, float]) -> dict[str, np.ndarray]:
        """World pose (4x4) of every link; joints missing from `positions` stay at 0."""
        return {n: M.homogeneous.copy() for n, M in self._placements(positions).items()}

    def transforms(self, positions: Mapping[str, float], stamp_ns: int, fixed: bool = False) -> list[Transform]:
        """parent -> child per URDF joint: the moving joints, or (fixed=True) world -> base and the fixed ones.
        pinocchio's SE3 and quaternion all the way (scipy's from_matrix cost 10x the rest per message)."""
        poses = self._placements(positions)
        out = [_se3_transform(WORLD, BASE_LINK, poses[BASE_LINK], stamp_ns)] if fixed else []
        for j in self.joints:
            if (j.kind == "fixed") == fixed:
                out.append(_se3_transform(j.parent, j.child, poses[j.parent].actInv(poses[j.child]), stamp_ns))
        return out


def _se3_transform(parent: str, child: str, M, stamp_ns: int) -> Transform:
    q = pin.Quaternion(M.rotation).coeffs()  # x, y, z, w
    t = M.translation
    return Transform(parent, child, (float(t[0]), float(t[1]), float(t[2])),
                     (float(q[0]), float(q[1]), float(q[2]), float(q[3])), int(stamp_ns))


@functools.lru_cache(maxsize=1)
def panda_tf() -> PandaTf:
    return PandaTf()


def joint_map(names: Sequence[str], positions: Sequence[float]) -> dict[str, float]:
    """A JointState's names/positions as a dict (shorter of the two wins, as robot_state_publisher)."""
    return {str(n): float(p) for n, p in zip(names, positions)}
