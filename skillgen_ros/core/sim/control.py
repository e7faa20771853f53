"""Torque-level controllers: operational-space (robosuite OSC_POSE style) and joint computed torque.

Pure numpy on the dynamics quantities the simulator supplies (mass matrix M, EE Jacobian J,
gravity + Coriolis h), so the control law is unit-testable without a physics engine.

OSC (Khatib): F = Lambda [kp e - kd v], Lambda = (J M^-1 J^T)^-1 computed separately for position
and orientation (robosuite's uncoupled variant), tau = J^T F + N^T tau_null + h, with the nullspace
pulling toward a rest posture. kd = 2 * zeta * sqrt(kp) (critically damped for zeta = 1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator

from .commands import JointTrajectory, TrajectoryCode, TrajectoryResult

EFFORT_LIMITS = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])


@dataclass(frozen=True)
class OscGains:
    """Stiffness (position N/m-like, orientation) and damping ratio; robosuite OSC_POSE defaults."""

    kp_pos: float = 150.0
    kp_ori: float = 150.0
    damping_ratio: float = 1.0
    kp_null: float = 10.0

    @property
    def kd_pos(self) -> float:
        return 2.0 * self.damping_ratio * np.sqrt(self.kp_pos)

    @property
    def kd_ori(self) -> float:
        return 2.0 * self.damping_ratio * np.sqrt(self.kp_ori)

    @property
    def kd_null(self) -> float:
        return 2.0 * self.damping_ratio * np.sqrt(self.kp_null)


@dataclass(frozen=True)
class JointGains:
    """Computed-torque gains for joint trajectory tracking (critically damped)."""

    kp: float = 400.0
    damping_ratio: float = 1.0

    @property
    def kd(self) -> float:
        return 2.0 * self.damping_ratio * np.sqrt(self.kp)


def orientation_error(R_target: np.ndarray, R_current: np.ndarray) -> np.ndarray:
    """robosuite's OSC orientation error: 0.5 * sum_i c_i x t_i over the rotation matrices' columns.

    Equals sin(angle) * axis (world frame), i.e. the rotation vector for small errors, and needs no
    quaternion conversion (this runs at the physics rate)."""
    return 0.5 * np.cross(R_current.T, R_target.T).sum(axis=0)


def _lambda(Jp: np.ndarray, Mi: np.ndarray) -> np.ndarray:
    A = Jp @ Mi @ Jp.T
    if abs(np.linalg.det(A)) > 1e-12:
        return np.linalg.inv(A)
    return np.linalg.pinv(A, rcond=1e-4)  # at a singularity


def osc_torques(target_p: np.ndarray, target_R: np.ndarray, ee_p: np.ndarray, ee_R: np.ndarray, J: np.ndarray,
                M: np.ndarray, h: np.ndarray, q: np.ndarray, qd: np.ndarray, q_rest: np.ndarray,
                gains: OscGains) -> np.ndarray:
    """Joint torques (7,) driving the EE toward the target. J is (6,7): linear rows then angular."""
    Mi = np.linalg.inv(M)
    Jp, Jo = J[:3], J[3:]
    v, w = Jp @ qd, Jo @ qd
    f = gains.kp_pos * (target_p - ee_p) - gains.kd_pos * v
    m = gains.kp_ori * orientation_error(target_R, ee_R) - gains.kd_ori * w
    tau = Jp.T @ (_lambda(Jp, Mi) @ f) + Jo.T @ (_lambda(Jo, Mi) @ m)
    # dynamically consistent nullspace projection of a posture torque
    Jbar = Mi @ J.T @ _lambda(J, Mi)
    posture = M @ (gains.kp_null * (q_rest - q) - gains.kd_null * qd)
    tau = tau + (np.eye(7) - J.T @ Jbar.T) @ posture
    return np.clip(tau + h, -EFFORT_LIMITS, EFFORT_LIMITS)


def joint_torques(q_des, qd_des, qdd_des, q, qd, M, h, gains: JointGains) -> np.ndarray:
    """Computed-torque joint tracking: tau = M (qdd_des + kp e + kd e_dot) + h."""
    a = qdd_des + gains.kp * (q_des - q) + gains.kd * (qd_des - qd)
    return np.clip(M @ a + h, -EFFORT_LIMITS, EFFORT_LIMITS)


class TrajectorySampler:
    """Desired (q, qd, qdd) at time t: cubic Hermite through given velocities, else PCHIP."""

    def __init__(self, traj: JointTrajectory):
        self.traj = traj
        if len(traj.times) == 1:
            self._f = None
        elif traj.velocities is not None:
            self._f = CubicHermiteSpline(traj.times, traj.positions, traj.velocities, axis=0)
        else:
            self._f = PchipInterpolator(traj.times, traj.positions, axis=0)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._f is None or t >= self.traj.duration:
            return self.traj.positions[-1], np.zeros(7), np.zeros(7)
        t = max(t, 0.0)
        return self._f(t), self._f(t, 1), self._f(t, 2)


DEFAULT_GOAL_TOLERANCE = 0.02  # rad


@dataclass
class ActiveTrajectory:
    """A joint trajectory being tracked: its clock and, once the time is up, FollowJointTrajectory's
    verdict (the final joint error within goal_tolerance, checked for up to settle_limit s)."""
    sampler: TrajectorySampler
    t: float = 0.0
    goal_tolerance: float = DEFAULT_GOAL_TOLERANCE
    settle_limit: float = 0.5
    done: TrajectoryResult | None = None

    def check_goal(self, q: np.ndarray) -> TrajectoryResult | None:
        """After a control period ending at joint positions q: the result once decided, else None."""
        dur = self.sampler.traj.duration
        if self.t >= dur:
            err = float(np.max(np.abs(q - self.sampler.traj.positions[-1])))
            if err <= self.goal_tolerance:
                self.done = TrajectoryResult(TrajectoryCode.SUCCESSFUL, "goal reached", err)
            elif self.t >= dur + self.settle_limit:
                self.done = TrajectoryResult(TrajectoryCode.GOAL_TOLERANCE_VIOLATED,
                                             f"final error {err:.4f} rad > {self.goal_tolerance}", err)
        return self.done

    @property
    def progress(self) -> float:
        dur = self.sampler.traj.duration
        return min(1.0, self.t / dur) if dur > 0 else 1.0
