"""Validation of what a driver is asked to do: OSC targets, gripper commands, joint trajectories.

Pure numpy (no pybullet) so the kinematic mock driver applies exactly the same rules as the
simulated one. Policy for targets outside the workspace box (WORKSPACE_LOW/HIGH, world frame):
up to WORKSPACE_CLAMP_MARGIN outside -> clamped onto the box; farther -> rejected with
OUT_OF_WORKSPACE and the robot keeps its previous target.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose, validate_pose
from ..robot import ARM_JOINTS, Q_LOWER, Q_UPPER, TABLE_Z, V_MAX

WORKSPACE_LOW = np.array([0.10, -0.65, TABLE_Z + 0.005])
WORKSPACE_HIGH = np.array([1.00, 0.65, TABLE_Z + 0.90])  # x: robosuite's table ends 0.96 m out
WORKSPACE_CLAMP_MARGIN = 0.10
POSITION_LIMIT_TOL = 1e-3   # rad beyond the URDF limits still accepted (numerical slack)
VELOCITY_LIMIT_TOL = 1.01   # factor over V_MAX still accepted
START_TOLERANCE = 0.1       # rad: a trajectory starting farther than this from the robot is rejected


class TrajectoryCode(IntEnum):
    """Result codes of ExecuteTrajectory (same numbers as the action definition)."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5


class TrajectoryError(InvalidInputError):
    """A rejected trajectory; `code` is the TrajectoryCode the action reports."""

    def __init__(self, message: str, code: TrajectoryCode):
        super().__init__(message, code.name)
        self.code = code


@dataclass(frozen=True)
class TrajectoryResult:
    code: TrajectoryCode
    message: str
    final_error: float  # max abs joint error at the end (rad)


@dataclass(frozen=True)
class Contact:
    body: str          # scene object id or "table"
    robot_link: str
    distance: float    # negative = penetration
    normal_force: float


@dataclass(frozen=True)
class JointTrajectory:
    """Arm trajectory in ARM_JOINTS order: times (N,) s from start, positions (N,7), velocities (N,7)|None."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None = None

    @property
    def duration(self) -> float:
        return float(self.times[-1])


def validate_osc_target(position, quaternion) -> Pose:
    """Finite, unit quaternion, inside (or clamped onto) the workspace box; raises otherwise."""
    pose = validate_pose(position, quaternion, "osc target")
    p = pose.position
    clamped = np.clip(p, WORKSPACE_LOW, WORKSPACE_HIGH)
    if np.linalg.norm(p - clamped) > WORKSPACE_CLAMP_MARGIN:
        raise InvalidInputError(f"osc target {p.round(3).tolist()} is more than {WORKSPACE_CLAMP_MARGIN} m outside "
                                f"the workspace box {WORKSPACE_LOW.tolist()}..{WORKSPACE_HIGH.tolist()}",
                                "OUT_OF_WORKSPACE")
    return Pose(clamped, pose.quaternion)


def validate_gripper(command) -> float:
    """Gripper command in [-1 open, +1 closed]; finite values are clipped, NaN/inf rejected."""
    g = float(command)
    if not np.isfinite(g):
        raise InvalidInputError(f"gripper command {g} is not finite")
    return float(np.clip(g, -1.0, 1.0))


def validate_trajectory(joint_names, times, positions, velocities=None, q_now=None) -> JointTrajectory:
    """Check and reorder a joint trajectory to ARM_JOINTS; raise TrajectoryError with a code.

    The robot's current configuration `q_now` becomes the t=0 point: prepended when the first
    point is later than 0, or replacing a t=0 first point that lies within START_TOLERANCE.
    """
    names = list(joint_names)
    if sorted(names) != sorted(ARM_JOINTS) or len(set(names)) != len(names):
        raise TrajectoryError(f"joint names {names} must be exactly {list(ARM_JOINTS)} (any order)",
                              TrajectoryCode.INVALID_JOINTS)
    order = [names.index(j) for j in ARM_JOINTS]
    t = np.asarray(times, float).reshape(-1)
    q = np.asarray(positions, float)
    if len(t) == 0 or q.shape != (len(t), 7):
        raise TrajectoryError(f"need N>=1 points with 7 positions each, got times {t.shape} positions {q.shape}",
                              TrajectoryCode.INVALID_GOAL)
    q = q[:, order]
    v = None
    if velocities is not None and len(velocities) > 0:
        v = np.asarray(velocities, float)
        if v.shape != q.shape:
            raise TrajectoryError(f"velocities shape {v.shape} != positions shape {q.shape}", TrajectoryCode.INVALID_GOAL)
        v = v[:, order]
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q)) and (v is None or np.all(np.isfinite(v)))):
        raise TrajectoryError("NaN or inf in trajectory", TrajectoryCode.INVALID_GOAL)
    if t[0] < 0 or np.any(np.diff(t) <= 0):
        raise TrajectoryError("time_from_start must be >= 0 and strictly increasing", TrajectoryCode.INVALID_GOAL)
    if np.any(q < Q_LOWER - POSITION_LIMIT_TOL) or np.any(q > Q_UPPER + POSITION_LIMIT_TOL):
        raise TrajectoryError("positions outside the joint limits", TrajectoryCode.INVALID_GOAL)
    if v is not None and np.any(np.abs(v) > V_MAX * VELOCITY_LIMIT_TOL):
        raise TrajectoryError("velocities over the joint velocity limits", TrajectoryCode.INVALID_GOAL)
    if q_now is not None:
        q_now = np.asarray(q_now, float).reshape(7)
        if t[0] == 0.0:
            if np.max(np.abs(q[0] - q_now)) > START_TOLERANCE:
                raise TrajectoryError(f"first point is more than {START_TOLERANCE} rad from the current state",
                                      TrajectoryCode.INVALID_GOAL)
            q = q.copy()
            q[0] = q_now
        else:
            t = np.concatenate([[0.0], t])
            q = np.vstack([q_now, q])
            v = None if v is None else np.vstack([np.zeros(7), v])
    if len(t) > 1:
        fd = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
        if np.any(fd > V_MAX * VELOCITY_LIMIT_TOL):
            raise TrajectoryError("average velocity between points exceeds the joint velocity limits",
                                  TrajectoryCode.INVALID_GOAL)
    return JointTrajectory(t, q, v)
