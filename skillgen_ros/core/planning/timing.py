"""Time parameterization of a joint path with ruckig within the Panda's V/A/J limits.

Community ruckig computes state-to-state trajectories only (waypoints are a Pro feature), so the
path is timed segment by segment, each from rest to rest. Each segment q(s) = a + s (b - a) is
timed as a 1-DoF ruckig problem in the path parameter s in [0, 1], with the tightest of the
joints' limits divided by |b_j - a_j|. The motion therefore stays *exactly on the straight
joint-space segment* the planner collision-checked (7-DoF phase synchronization does this only
"when possible" and silently falls back to time synchronization, which leaves the line), and every
joint stays within its V/A/J limits. The cost is a stop at each waypoint; shortcutting keeps them
few.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from ..errors import InvalidInputError
from ..robot import A_MAX, J_MAX, V_MAX


@dataclass(frozen=True)
class JointTrajectory:
    """Sampled trajectory: times (T,), positions/velocities/accelerations (T,7)."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.times[-1]) if len(self.times) else 0.0


def time_parameterize(path: np.ndarray, dt: float = 0.01, v_max=V_MAX, a_max=A_MAX, j_max=J_MAX,
                      scale: float = 1.0) -> JointTrajectory:
    """Rest-to-rest ruckig segments through `path` (K,7), sampled every `dt` seconds.

    `scale` (0, 1] scales velocity, acceleration and jerk limits alike.
    """
    P = np.asarray(path, float)
    if P.ndim != 2 or P.shape[1] != 7 or len(P) < 1 or not np.all(np.isfinite(P)):
        raise InvalidInputError("path must be a finite (K,7) array")
    if not 0.0 < scale <= 1.0 or dt <= 0:
        raise InvalidInputError("scale must be in (0, 1] and dt > 0")
    v_max, a_max, j_max = (np.asarray(x, float) * scale for x in (v_max, a_max, j_max))
    otg = Ruckig(1)
    times, pos, vel, acc = [0.0], [P[0]], [np.zeros(7)], [np.zeros(7)]
    t_offset = 0.0
    for a, b in zip(P[:-1], P[1:]):
        d = b - a
        ad = np.abs(d)
        if ad.max() < 1e-12:
            continue
        moving = ad > 1e-12
        inp = InputParameter(1)
        inp.current_position, inp.target_position = [0.0], [1.0]
        inp.max_velocity = [float(np.min(v_max[moving] / ad[moving]))]
        inp.max_acceleration = [float(np.min(a_max[moving] / ad[moving]))]
        inp.max_jerk = [float(np.min(j_max[moving] / ad[moving]))]
        traj = Trajectory(1)
        res = otg.calculate(inp, traj)
        if res not in (Result.Working, Result.Finished):
            raise InvalidInputError(f"ruckig failed on a segment: {res}")
        T = traj.duration
        n = max(1, int(np.ceil(T / dt)))
        for t in np.linspace(T / n, T, n):
            s_, sd, sdd = (x[0] for x in traj.at_time(float(t)))
            times.append(t_offset + float(t))
            pos.append(a + min(max(s_, 0.0), 1.0) * d)
            vel.append(sd * d)
            acc.append(sdd * d)
        pos[-1] = b.copy()
        t_offset += T
    return JointTrajectory(np.array(times), np.array(pos), np.array(vel), np.array(acc))
