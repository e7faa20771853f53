"""Inverse kinematics in the style of TRAC-IK (Beeson & Ames 2015).

TRAC-IK runs two solvers concurrently and returns whichever finds a solution first: KDL's
Newton pseudo-inverse with random restarts, and an SQP that keeps the joints inside their
limits. Here both run *as one numpy batch*: each row of the batch is a seed; half of the rows take
damped Newton (pseudo-inverse) steps and half take bound-constrained Gauss-Newton steps (the SQP
subproblem with box constraints, solved by an active set: joints at a limit whose step would push
them out are frozen). Rows that stall are re-seeded uniformly within the limits. The first row
whose 6-D error (metres, radians) is below `tol` -- and, with a collision checker, whose
configuration is collision-free -- wins. One batched iteration costs about as much as one Python
Newton step, so the batch buys restarts almost for free.
"""
from __future__ import annotations

import enum
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose
from . import kernels
from .kinematics import PandaKinematics


class IKStatus(enum.Enum):
    SUCCESS = "SUCCESS"
    FAILED = "FAILED"  # no solution within the iteration budget / timeout
    IN_COLLISION = "IN_COLLISION"  # solutions exist, but every one found collides


@dataclass(frozen=True)
class IKResult:
    status: IKStatus
    solutions: tuple = ()  # of (7,) arrays, best (closest to the seed) first
    time: float = 0.0
    iterations: int = 0
    rejected_in_collision: int = 0

    @property
    def ok(self) -> bool:
        return self.status is IKStatus.SUCCESS


class IKSolver:
    """Concurrent Newton + bounded Gauss-Newton IK with random restarts (see module docstring).

    `collision_checker`, if given, is a CollisionModel or a callable (N,7) -> (N,) bool.
    """

    def __init__(self, kin: PandaKinematics, collision_checker=None, batch: int = 24,
                 rng: np.random.Generator | int | None = None, max_row_iters: int = 30,
                 chunk: int = 2):
        self.kin = kin
        # a CollisionModel (its in_collision) or any callable Q (N,7) -> bool (N,)
        self.checker = getattr(collision_checker, "in_collision", collision_checker)
        self.batch = int(batch)
        self.max_row_iters = int(max_row_iters)
        self.chunk = int(chunk)  # kernel iterations between timeout checks
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        kernels.seed_rng(int(self.rng.integers(2**31)))
        self.lower, self.upper = kin.lower, kin.upper
        self._newton_rows = np.arange(self.batch) % 2 == 0  # even rows Newton, odd rows bounded GN
        # compile (or load from numba's cache) now, not inside the first timed solve
        self.solve_local(kin.fk(np.clip(np.zeros(7), self.lower, self.upper)), np.zeros(7), iters=1)

    def _sample(self, n: int) -> np.ndarray:
        return self.rng.uniform(self.lower, self.upper, size=(n, 7))

    def solve_local(self, target, seed_q, tol: float = 1e-5, iters: int = 50):
        """Newton from `seed_q` only (no restarts): for tracking a Cartesian line. None if it
        does not converge. The caller checks the joint jump."""
        T_target = np.ascontiguousarray(target.matrix() if isinstance(target, Pose) else np.asarray(target, float))
        Q = np.clip(np.asarray(seed_q, float).reshape(1, 7), self.lower, self.upper).copy()
        state = np.array([[np.inf, 0.0, 0.0]])
        kin = self.kin
        done = kernels.ik_iterate(Q, state, T_target, kin._joint_T, kin._ee_parent, kin._ee_T,
                                  self.lower, self.upper, np.ones(1, np.bool_), tol, iters, iters,
                                  False)
        return Q[0].copy() if done[0] else None

    def solve(self, target, seed_q=None, timeout: float = 0.005, tol: float = 1e-5,
              max_solutions: int = 1, distinct: float = 0.05,
              max_iterations: int | None = None) -> IKResult:
        """Solve for the EE pose `target` (Pose or 4x4). Seed row 0 with `seed_q` if given.

        With max_solutions > 1 it keeps going until that many solutions that differ by more than
        `distinct` rad (max-norm) are found, `max_iterations` batch iterations have run, or the
        timeout expires. An iteration budget makes the answer independent of CPU speed and load
        (the same rng gives the same solutions on any machine) as long as the timeout, then only a
        safety cap, does not cut it first.
        """
        t0 = time.perf_counter()
        T_target = np.ascontiguousarray(target.matrix() if isinstance(target, Pose) else np.asarray(target, float))
        if T_target.shape != (4, 4) or not np.all(np.isfinite(T_target)):
            raise InvalidInputError("IK target must be a finite Pose or 4x4 matrix")
        if timeout <= 0 or tol <= 0 or max_solutions < 1 or (max_iterations is not None and max_iterations < 1):
            raise InvalidInputError("IK timeout and tol must be > 0, max_solutions and max_iterations >= 1")
        Q = self._sample(self.batch)
        if seed_q is not None:
            seed = np.asarray(seed_q, float).reshape(7)
            if not np.all(np.isfinite(seed)):
                raise InvalidInputError("IK seed has NaN/inf")
            Q[0] = np.clip(seed, self.lower, self.upper)
        state = np.zeros((self.batch, 3))
        state[:, 0] = np.inf
        solutions: list[np.ndarray] = []
        rejected = 0
        it = 0
        kin = self.kin
        while True:
            done = kernels.ik_iterate(Q, state, T_target, kin._joint_T, kin._ee_parent, kin._ee_T,
                                      self.lower, self.upper, self._newton_rows, tol,
                                      self.chunk, self.max_row_iters)
            it += self.chunk
            idx = np.flatnonzero(done)
            if len(idx):
                cand = Q[idx].copy()
                if self.checker is not None:
                    free = ~np.asarray(self.checker(cand), bool)
                    rejected += int(np.count_nonzero(~free))
                    cand = cand[free]
                for c in cand:
                    if all(np.abs(c - s).max() > distinct for s in solutions):
                        solutions.append(c)
                if len(solutions) >= max_solutions:
                    break
                Q[idx] = self._sample(len(idx))
                state[idx] = (np.inf, 0.0, 0.0)
            if (max_iterations is not None and it >= max_iterations) or time.perf_counter() - t0 > timeout:
                break
        elapsed = time.perf_counter() - t0
        if solutions:
            if seed_q is not None:
                solutions.sort(key=lambda s: float(np.abs(s - np.asarray(seed_q, float)).sum()))
            return IKResult(IKStatus.SUCCESS, tuple(solutions[:max_solutions]), elapsed, it, rejected)
        status = IKStatus.IN_COLLISION if rejected else IKStatus.FAILED
        return IKResult(status, (), elapsed, it, rejected)
