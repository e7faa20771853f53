"""RRT-Connect in joint space (OMPL 2 nanobind bindings) with vectorized edge validation.

OMPL owns the search; validity comes from a batch checker `in_collision(Q) -> bool[N]`. Each edge
is validated by one call on all its interpolated configurations (a MotionValidator subclass),
so Python is entered once per edge rather than once per state. After a solution, OMPL's
shortcutting (reduceVertices, ropeShortcutPath) and a greedy farthest-reachable pass cut the
path to few waypoints, which matters because each waypoint is a stop in the timed trajectory.
"""
from __future__ import annotations

import atexit
import enum
import gc
import time
import weakref
from dataclasses import dataclass
from typing import Callable

import numpy as np
import ompl.base as ob
import ompl.geometric as og
import ompl.util as ou

ou.setLogLevel(ou.LogLevel.LOG_WARN)
_live: "weakref.WeakSet[JointSpaceRRT]" = weakref.WeakSet()


@atexit.register
def _release_all() -> None:
    """Free OMPL objects before interpreter teardown; otherwise nanobind prints leak reports."""
    for rrt in list(_live):
        rrt.release()
    gc.collect()


def seed_ompl(seed: int) -> None:
    """Restart OMPL's process-wide seed generator: every OMPL RNG made after this (a planner's
    state sampler, a path simplifier) draws its seed from `seed` alone. OMPL logs an error when
    sampling already started ("will not lead to deterministic sampling"); that holds for RNGs that
    already exist, so callers make fresh ones right after (JointSpaceRRT.plan)."""
    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    try:
        ou.RNG.setSeed(max(1, int(seed) & 0x7FFFFFFF))
    finally:
        ou.setLogLevel(ou.LogLevel.LOG_WARN)


class RRTStatus(enum.Enum):
    SOLVED = "SOLVED"
    TIMEOUT = "TIMEOUT"
    INVALID_START = "INVALID_START"
    INVALID_GOAL = "INVALID_GOAL"


@dataclass(frozen=True)
class RRTResult:
    status: RRTStatus
    path: np.ndarray  # (K,7); empty unless SOLVED
    plan_time: float
    simplify_time: float
    iterations: int = 0  # RRT-Connect loop iterations the search ran (0: no tree was grown)


class _EdgeValidator(ob.MotionValidator):
    def __init__(self, si, check_edge):
        super().__init__(si)
        self._check_edge = check_edge

    def checkMotion(self, s1, s2):  # noqa: N802 (OMPL name)
        return self._check_edge(np.array([s1[i] for i in range(7)]), np.array([s2[i] for i in range(7)]))


class JointSpaceRRT:
    """RRT-Connect between two configurations (one instance serves many queries)."""

    def __init__(self, lower, upper, range_: float = 0.0):
        """The OMPL objects are built once and reused (ss.clear() between queries): cheaper, and
        nanobind then reports one Python<->C++ validator cycle at exit instead of one per plan."""
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.in_collision: Callable[[np.ndarray], np.ndarray] | None = None
        self.check_motion: Callable[[np.ndarray, np.ndarray], bool] | None = None
        self.edge_checks = 0
        self.space = ob.RealVectorStateSpace(7)
        bounds = ob.RealVectorBounds(7)
        for i in range(7):
            bounds.setLow(i, float(self.lower[i]))
            bounds.setHigh(i, float(self.upper[i]))
        self.space.setBounds(bounds)
        self.ss = og.SimpleSetup(self.space)
        self.si = self.ss.getSpaceInformation()
        self.ss.setStateValidityChecker(
            lambda s: not bool(self.in_collision(np.array([[s[i] for i in range(7)]]))[0]))
        self._validator = _EdgeValidator(self.si, self.edge_free)
        self.si.setMotionValidator(self._validator)
        self.range = float(range_)
        self._new_planner()
        self.simplifier = og.PathSimplifier(self.si)
        _live.add(self)

    def _new_planner(self) -> None:
        """A new RRT-Connect: a reused one keeps its sampler, and so its RNG, across ss.clear()."""
        self.planner = og.RRTConnect(self.si)
        if self.range > 0:
            self.planner.setRange(self.range)
        self.ss.setPlanner(self.planner)

    def release(self) -> None:
        for name in ("simplifier", "planner", "_validator", "si", "ss", "space"):
            self.__dict__.pop(name, None)

    def edge_free(self, q0, q1) -> bool:
        self.edge_checks += 1
        return bool(self.check_motion(q0, q1))

    def path_free(self, path: np.ndarray) -> bool:
        return all(self.edge_free(a, b) for a, b in zip(path[:-1], path[1:]))

    def _shortcut(self, path: np.ndarray) -> np.ndarray:
        """Greedy: from each kept waypoint jump to the farthest one reachable in a straight line."""
        out = [path[0]]
        i = 0
        while i < len(path) - 1:
            j = len(path) - 1
            while j > i + 1 and not self.edge_free(path[i], path[j]):
                j -= 1
            out.append(path[j])
            i = j
        return np.array(out)

    def plan(self, start, goal, in_collision: Callable[[np.ndarray], np.ndarray],
             check_motion: Callable[[np.ndarray, np.ndarray], bool], timeout: float,
             simplify: bool = True, seed: int | None = None, max_iterations: int | None = None) -> RRTResult:
        """in_collision(Q (N,7)) -> bool (N,) checks states; check_motion(q0, q1) -> bool checks a
        whole edge in one vectorized call (CollisionModel.check_motion, continuous).

        max_iterations: the search's budget in RRT-Connect iterations (OMPL evaluates the
        termination condition once per iteration). With a seed, a search so budgeted finds the
        same path on a loaded or slower machine; `timeout` then only caps its wall time."""
        self.in_collision, self.check_motion = in_collision, check_motion
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        if self.in_collision(start[None])[0]:
            return RRTResult(RRTStatus.INVALID_START, np.empty((0, 7)), 0.0, 0.0)
        if self.in_collision(goal[None])[0]:
            return RRTResult(RRTStatus.INVALID_GOAL, np.empty((0, 7)), 0.0, 0.0)
        t0 = time.perf_counter()
        if self.edge_free(start, goal):  # the trivial plan: no tree needed
            return RRTResult(RRTStatus.SOLVED, np.array([start, goal]), time.perf_counter() - t0, 0.0)
        if seed is not None:
            self._new_planner()
        self.ss.clear()
        s, g = self.space.allocState(), self.space.allocState()
        for i in range(7):
            s[i] = float(start[i])
            g[i] = float(goal[i])
        self.ss.setStartAndGoalStates(s, g)
        if seed is not None:  # set up first: a first setup draws seeds that a later one does not
            self.ss.setup()
            seed_ompl(seed)
            self.simplifier = og.PathSimplifier(self.si)
        count = [0]
        end = time.perf_counter() + float(timeout)
        budget = float("inf") if max_iterations is None else int(max_iterations)

        def stop() -> bool:
            count[0] += 1
            return count[0] > budget or time.perf_counter() > end

        solved = self.ss.solve(ob.PlannerTerminationCondition(stop))
        plan_time = time.perf_counter() - t0
        if not solved or not self.ss.haveExactSolutionPath():
            return RRTResult(RRTStatus.TIMEOUT, np.empty((0, 7)), plan_time, 0.0, count[0])
        t1 = time.perf_counter()
        path = self.ss.getSolutionPath()
        if simplify:
            self.simplifier.reduceVertices(path)
            self.simplifier.ropeShortcutPath(path)
        P = np.array([[path.getState(k)[i] for i in range(7)] for k in range(path.getStateCount())])
        P = self._shortcut(P)
        return RRTResult(RRTStatus.SOLVED, P, plan_time, time.perf_counter() - t1, count[0])
