"""Human-like motion for the scripted demonstrator: min-jerk reaches with tremor, pauses, speed changes.

Only the source-demo demonstrator uses this (see `core/demonstrator/__init__.py`). A person
teleoperating a robot moves in smooth, bell-shaped velocity profiles (Flash & Hogan's minimum
jerk), at a speed that varies from demo to demo, sometimes pauses before a careful phase, and
never hits a pose exactly; `DemoStyle` holds those per-demo choices, drawn from a seeded rng.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..geometry import Pose


def min_jerk(tau: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 on tau in [0, 1]."""
    t = np.clip(np.asarray(tau, float), 0.0, 1.0)
    return t ** 3 * (10 - 15 * t + 6 * t * t)


@dataclass(frozen=True)
class DemoStyle:
    """One demo's 'operator': speed, tremor, hesitation habits and approach choices (all seeded)."""

    speed: float  # multiplies every nominal duration (>1 = slower)
    tremor: float  # m, std of the smooth positional noise in free space
    hesitation_prob: float  # chance of a pause before each careful phase
    approach_height: float  # m above a grasp / place point where the careful descent begins
    approach_offset: np.ndarray  # (2,) lateral offset (m) of the pre-grasp point: the approach direction
    place_offset: np.ndarray  # (2,) small xy error of where the person aims a placement
    yaw_error: float  # rad, small orientation error of the person's grasp

    @staticmethod
    def sample(rng: np.random.Generator) -> "DemoStyle":
        ang = rng.uniform(-np.pi, np.pi)
        r = rng.uniform(0.0, 0.04)
        return DemoStyle(
            speed=float(rng.uniform(0.85, 1.35)), tremor=float(rng.uniform(0.0005, 0.0015)),
            hesitation_prob=float(rng.uniform(0.1, 0.5)), approach_height=float(rng.uniform(0.06, 0.11)),
            approach_offset=np.array([np.cos(ang), np.sin(ang)]) * r,
            place_offset=rng.uniform(-0.003, 0.003, 2), yaw_error=float(rng.uniform(-0.05, 0.05)))


class SmoothNoise:
    """Band-limited 3D noise (first-order low-pass of white noise): hand tremor, not jitter."""

    def __init__(self, rng: np.random.Generator, alpha: float = 0.85):
        self.rng, self.alpha, self.state = rng, alpha, np.zeros(3)

    def __call__(self, sigma: float) -> np.ndarray:
        self.state = self.alpha * self.state + np.sqrt(1 - self.alpha ** 2) * self.rng.standard_normal(3)
        return self.state * sigma


def reach(start: Pose, goal: Pose, steps: int) -> list[Pose]:
    """`steps` poses from start (exclusive) to goal (inclusive) on a min-jerk profile, slerped rotation."""
    steps = max(1, int(steps))
    s = min_jerk(np.arange(1, steps + 1) / steps)
    rots = Slerp([0.0, 1.0], Rotation.from_quat([start.quaternion, goal.quaternion]))(s)
    pos = start.position[None] + s[:, None] * (goal.position - start.position)[None]
    return [Pose(p, q) for p, q in zip(pos, rots.as_quat())]


def down_pose(position, yaw: float) -> Pose:
    """EE pointing straight down (z to -world z) with its x axis at `yaw` about world z.

    The fingers close along EE y = (sin yaw, -cos yaw, 0).
    """
    R = Rotation.from_euler("z", yaw) * Rotation.from_matrix(np.diag([1.0, -1.0, -1.0]))
    return Pose(np.asarray(position, float), R.as_quat())


def ee_yaw(pose: Pose) -> float:
    """Yaw of the EE x axis projected on the table plane."""
    x = pose.rotation.apply([1.0, 0.0, 0.0])
    return float(np.arctan2(x[1], x[0]))


def object_yaw(pose: Pose) -> float:
    x = pose.rotation.apply([1.0, 0.0, 0.0])
    return float(np.arctan2(x[1], x[0]))


def wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def nearest_yaw(base: float, period: float, reference: float) -> float:
    """The angle base + k*period closest to `reference` (symmetric grasps / placements)."""
    k = np.round((reference - base) / period)
    return float(base + k * period)
