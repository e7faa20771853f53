"""MotionPlanner: the paper's three phases per query -- retreat, transit/transfer, approach.

    kin = PandaKinematics(); cm = CollisionModel(kin); cm.set_boxes(boxes)
    planner = MotionPlanner(kin, IKSolver(kin), cm)
    res = planner.plan(q_now, target_pose, Mode.TRANSIT, manipulated="cube", timeout=2.0)
    if res.status is PlanStatus.SUCCESS: execute(res.trajectory)

1. Retreat: 5 cm back along the gripper's -z from the start (Cartesian line).
2. Transit (empty hand) or transfer (with `attached` in the hand): RRT-Connect in joint space
   from the retreat's end to the pre-approach configuration, then shortcutting.
3. Approach: 5 cm along the gripper's +z to the target (computed backwards from the goal IK).
During retreat and approach the hand may touch the manipulated object, and the held object its
support; with `movable` (the paper's rule) the hand may touch every manipulated object and the held
object anything. Transit and transfer allow no contact. The whole path is timed with ruckig.
The result is a complete immutable value: status, trajectory, joint path, phase timings.

IK randomness (restarts) is drawn per plan() call from SeedSequence((seed, k)), k counting the
calls since `reseed(seed)`. RRT-Connect is OMPL's: before each search OMPL's process-wide seed
generator restarts from SeedSequence((seed, k, 1)) and the search gets a fresh sampler and path
simplifier, so a plan depends on (seed, k) and its inputs only, not on what the process planned
before (a run sharded across processes plans what the unsharded run plans). The goal IK is
budgeted in iterations (`ik_iterations`; `ik_timeout` is only a safety cap), and so is RRT-Connect
(`rrt_iterations`; the request's timeout is the cap), so a plan is the same on a loaded or slower
machine unless the cap cuts it first.
"""
from __future__ import annotations

import enum
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose, validate_pose
from . import kernels
from .collision import AllowedContacts, AttachedObject, CollisionModel, phase_contacts
from .ik import IKSolver
from .kinematics import PandaKinematics
from .phases import CartesianPathError, cartesian_line
from .rrt import JointSpaceRRT, RRTStatus
from .start_repair import START_REPAIRS, StartRepairs
from .timing import JointTrajectory, time_parameterize


# A measured start may sit slightly past a joint limit (tracking error, encoder noise); within this
# tolerance it is clipped onto the limit instead of rejected.
START_LIMIT_TOL = 0.05  # rad


class PlanStatus(enum.IntEnum):
    """Values match skillgen_interfaces/srv/PlanToPose."""

    SUCCESS = 0
    IK_FAILED = 1
    START_IN_COLLISION = 2
    GOAL_IN_COLLISION = 3
    PLAN_TIMEOUT = 4
    INVALID_REQUEST = 5


class Mode(enum.Enum):
    TRANSIT = "transit"
    TRANSFER = "transfer"


@dataclass(frozen=True)
class PlanResult:
    status: PlanStatus
    trajectory: JointTrajectory | None = None
    joint_path: np.ndarray = field(default_factory=lambda: np.empty((0, 7)))
    # (phase, first index, last index) into joint_path
    segments: tuple = ()
    timings: dict = field(default_factory=dict)
    message: str = ""
    retreat_length: float = 0.0  # m the hand backs out before transit (doubled against a fixture)

    @property
    def ok(self) -> bool:
        return self.status is PlanStatus.SUCCESS


def _shift_z(T: np.ndarray, d: float) -> np.ndarray:
    S = np.eye(4)
    S[2, 3] = d
    return T @ S


def _seed_like(v) -> bool:
    """An int >= 0 (numpy ints too; not a bool): what reseed() and plan(seed=...) accept."""
    return not isinstance(v, bool) and isinstance(v, (int, np.integer)) and v >= 0


class MotionPlanner(StartRepairs):
    def __init__(self, kin: PandaKinematics, ik: IKSolver, collision: CollisionModel,
                 retreat_distance: float = 0.05, approach_distance: float = 0.05,
                 dt: float = 0.01, ik_timeout: float = 5.0, ik_iterations: int = 2000,
                 ik_solutions: int = 4, velocity_scale: float = 1.0, seed: int | None = None,
                 rrt_iterations: int = 100):
        """ik_iterations: the goal IK's budget in batch iterations (2000 take about 50 ms on one
        2020s core); ik_timeout only caps its wall time (100x that, so a loaded machine does not
        reach it), so plans do not depend on CPU load.
        rrt_iterations: RRT-Connect's budget in search iterations (1-12 ms each here; the searches
        of the datagen and planning benches and the tests need at most 19), capped by the request's
        timeout in the same way."""
        if ik_iterations < 1 or ik_timeout <= 0 or rrt_iterations < 1:
            raise InvalidInputError(f"ik_iterations and rrt_iterations must be >= 1 and ik_timeout > 0, got "
                                    f"{ik_iterations}, {rrt_iterations}, {ik_timeout}")
        self.kin, self.ik, self.cm = kin, ik, collision
        self.retreat_distance = float(retreat_distance)
        self.approach_distance = float(approach_distance)
        self.dt = float(dt)
        self.ik_timeout = float(ik_timeout)
        self.ik_iterations = int(ik_iterations)
        self.rrt_iterations = int(rrt_iterations)
        self.ik_solutions = int(ik_solutions)
        self.velocity_scale = float(velocity_scale)
        self.seed: int | None = None
        self._calls = 0
        self._rrt_seed: int | None = None
        self.rrt = JointSpaceRRT(kin.lower, kin.upper)
        if seed is not None:
            self.reseed(seed)

    def warm_up(self) -> None:
        """Compile the numba kernels now (seconds on a fresh clone) instead of inside the first
        plan, whose IK wall-time cap would cut the compile and answer IK_FAILED (CI, 2026-12-03)."""
        q = 0.5 * (self.kin.lower + self.kin.upper)
        rng, self.ik.rng = self.ik.rng, np.random.default_rng(0)
        try:
            self.ik.solve(self.kin.fk(q), seed_q=q, timeout=600.0, max_iterations=self.ik.chunk)
        finally:
            self.ik.rng = rng
        self.cm.in_collision(q[None])

    def reseed(self, seed: int) -> None:
        """Restart the IK randomness: the k-th plan() after this draws its IK restarts from (seed, k)
        only. The IK solver's `rng` (shared with its other users) is replaced per call, and so is
        the seed of the call's RRT searches (see the module docstring)."""
        if not _seed_like(seed):
            raise InvalidInputError(f"planner seed must be an int >= 0, got {seed!r}")
        self.seed, self._calls = int(seed), 0

    def _reseed_ik_for_call(self, seed_k: tuple[int, int] | None = None) -> None:
        """Per-call IK streams (the IK's rng and numba's restart RNG) and RRT seed, from `seed_k` =
        (seed, k) if given (leaving the planner's own count alone), else from (self.seed, next k);
        without either the IK keeps its own stream and the RRT is not reseeded."""
        if seed_k is None:
            if self.seed is None:
                self._rrt_seed = None
                return
            seed_k = (self.seed, self._calls)
            self._calls += 1
        ik_seq = np.random.SeedSequence(seed_k)
        self._rrt_seed = int(np.random.SeedSequence((*seed_k, 1)).generate_state(1)[0])
        self.ik.rng = np.random.default_rng(ik_seq)
        kernels.seed_rng(int(self.ik.rng.integers(2**31)))

    def plan(self, start_q, target: Pose, mode: Mode = Mode.TRANSIT,
             attached: AttachedObject | None = None, manipulated: str | None = None,
             released: str | None = None, start_support: str | None = "table", goal_support: str | None = "table",
             timeout: float = 5.0, retreat: bool = True, approach: bool = True,
             released_support: str | None = None, seed: tuple[int, int] | None = None,
             extras: bool = True, movable: tuple[str, ...] | None = None) -> PlanResult:
        """Plan from `start_q` to the EE pose `target`. See the module docstring.

        seed=(s, k): draw as the k-th plan after reseed(s) would, whatever this planner ran before
        (the planner node serving datagen's attempts); the planner's own count does not advance.
        manipulated: object the hand may touch on the approach (transit: about to be grasped);
        released: object the hand may touch on the retreat (just put down; default manipulated).
        released_support: what `released` was put on (a peg, a bin); the hand may touch it on the retreat.
        start_support/goal_support: what the held object may touch when lifted from / put down on
        (a box name or "table"), transfer only.
        movable: the scene's manipulated objects (a task's non-fixture objects), for the paper's rule:
        it ignores robot/manipulated-object and manipulated-object/environment contacts on the retreat
        and the approach (its Appendix, "Motion Planning"), so there the hand may touch any of them (a
        round nut grasped beside the square nut already on its peg) and a held object may touch
        anything. None: only the named objects above (and a held object only its support).
        extras: this project's start repairs beyond the paper's retreat -> transit -> approach (a hand
        on a fixture backs out along a retreat doubled to 10 cm; a grazing arm escapes along its null
        space; a retreat IK cannot follow is shortened or preceded by a self-motion; an approach IK
        cannot follow is shortened or dropped). False (the
        `paper` profile, core/generation/profile.py): a start that collides is START_IN_COLLISION,
        and a blocked retreat from a start in contact too.
        """
        t_all = time.perf_counter()
        if seed is not None and (len(seed) != 2 or not all(map(_seed_like, seed))):
            raise InvalidInputError(f"plan seed must be (seed, index), two ints >= 0, got {seed!r}")
        self._reseed_ik_for_call(None if seed is None else (int(seed[0]), int(seed[1])))  # every call takes its index
        try:
            q0 = self.kin._check(start_q)
            target = validate_pose(target.position, target.quaternion, "target")
            if timeout <= 0 or not np.isfinite(timeout):
                raise InvalidInputError(f"timeout must be > 0, got {timeout}")
            mode = Mode(mode)
            if mode is Mode.TRANSFER and attached is None:
                raise InvalidInputError("transfer needs an attached object")
        except (InvalidInputError, ValueError) as e:
            return PlanResult(PlanStatus.INVALID_REQUEST, message=str(e), timings={})
        if mode is Mode.TRANSIT:
            allow = phase_contacts(self.cm, (released or manipulated, released_support), (manipulated,), movable)
        else:
            allow = phase_contacts(self.cm, (start_support,), (goal_support,), movable, attached.name,
                                   start_support, goal_support)
        c = _Call(self.cm, attached if mode is Mode.TRANSFER else None, t_all, *allow)
        try:
            q0, escape, touching = self._start(c, q0, extras)
            rounds = self._goal_candidates(c, q0, target.matrix())
            retreat_path = np.vstack([escape[:-1], self._retreat(c, q0, touching, retreat, extras)])
            approach_path = self._approach(c, rounds, approach, extras)
            transit = self._transit(c, mode, retreat_path[-1], approach_path[0], timeout)
        except _PlanFailure as e:
            return c.fail(e.status, str(e))
        path = np.vstack([retreat_path, transit[1:], approach_path[1:]])
        n_r, n_t = len(retreat_path), len(transit)
        segments = (("retreat", 0, n_r - 1), (mode.value, n_r - 1, n_r + n_t - 2),
                    ("approach", n_r + n_t - 2, len(path) - 1))
        t = time.perf_counter()
        traj = time_parameterize(path, self.dt, scale=self.velocity_scale)
        c.timings["parameterize"] = time.perf_counter() - t
        c.timings["total"] = time.perf_counter() - t_all
        retreat_length = float(np.linalg.norm(self.kin.fk(retreat_path[-1])[:3, 3] - self.kin.fk(retreat_path[0])[:3, 3]))
        return PlanResult(PlanStatus.SUCCESS, traj, path, segments, c.timings,
                          "; ".join([f"{len(path)} waypoints, {traj.duration:.2f} s"] + c.notes), retreat_length)

    def _start(self, c: "_Call", q0, extras: bool):
        """The start, clipped onto the joint limits and repaired if it collides (extras):
        (start, escape path ending at it, the boxes the hand may touch on the retreat)."""
        if not self.kin.within_limits(q0, tol=START_LIMIT_TOL):
            raise _PlanFailure(PlanStatus.INVALID_REQUEST, "start configuration outside joint limits")
        q0 = np.clip(q0, self.kin.lower, self.kin.upper)
        if not c.collides(q0[None], c.allow_start)[0]:
            return q0, q0[None], ()
        if not extras:
            raise _PlanFailure(PlanStatus.START_IN_COLLISION, "start configuration collides (planner extras off)")
        touching = self._touching_hand(q0, c.allow_start, c.collides)
        if touching:  # the replayed skill left the hand against a fixture: back out along the retreat
            c.allow_start = replace(c.allow_start, hand_object=c.allow_start.hand_names() + touching)
            c.notes.append(f"{START_REPAIRS['hand_backout']} {', '.join(touching)} (allowed on the retreat)")
            return q0, q0[None], touching
        escape = self._null_space_escape(q0, lambda q: bool(c.collides(q[None], c.allow_start)[0]))
        if escape is None and self._wrist_clears(q0, c.allow_start, c.collides):
            c.allow_start = replace(c.allow_start, wrist=True)
            touched = ", ".join(c.allow_start.hand_names())
            c.notes.append(f"{START_REPAIRS['wrist_backout']} {touched} (allowed on the retreat)")
            return q0, q0[None], True
        if escape is None:
            raise _PlanFailure(PlanStatus.START_IN_COLLISION, "start configuration collides")
        moved = np.abs(escape[-1] - q0).max()
        c.notes.append(f"{START_REPAIRS['null_space_escape']} {moved:.2f} rad in the null space")
        return escape[-1], escape, ()

    def _goal_candidates(self, c: "_Call", q0, T_goal):
        """Goal IK: first without collisions (reachability: IK_FAILED if none), then, in rounds, the
        collision-free ones and, if none of those admits an approach, a collision-aware IK for more."""
        t = time.perf_counter()
        ik_res = self.ik.solve(T_goal, seed_q=q0, timeout=self.ik_timeout,
                               max_solutions=self.ik_solutions, max_iterations=self.ik_iterations)
        c.timings["ik"] = time.perf_counter() - t
        if not ik_res.solutions:
            raise _PlanFailure(PlanStatus.IK_FAILED, "no IK solution for the target pose")
        checked_ik = IKSolver(self.kin, lambda Q: c.collides(Q, c.allow_goal), batch=self.ik.batch,
                              rng=self.ik.rng)
        return (
            lambda: [q for q in ik_res.solutions if not c.collides(q[None], c.allow_goal)[0]],
            lambda: list(checked_ik.solve(T_goal, seed_q=q0, timeout=2 * self.ik_timeout,
                                          max_solutions=3 * self.ik_solutions,
                                          max_iterations=2 * self.ik_iterations).solutions),
        )

    def _retreat(self, c: "_Call", q0, touching, retreat: bool, extras: bool) -> np.ndarray:
        """The retreat from q0 (just q0 when off), shortened or repaired when it collides."""
        t = time.perf_counter()
        try:
            if not (retreat and self.retreat_distance > 0):
                return q0[None]
            try:
                path = cartesian_line(self.kin, self.ik, q0, -self.retreat_distance)
                if touching and c.collides(path[-1:])[0]:  # still against the fixture: back out further
                    path = cartesian_line(self.kin, self.ik, q0, -2 * self.retreat_distance, steps=20)
                if self._segment_free(path, c.edge_free, c.allow_start):
                    return path
                why = "retreat collides"
            except CartesianPathError as e:
                why = f"retreat: {e}"
            # A start that is free without any allowed contact can go straight to transit; one in
            # contact (fingertips at the table after a low grasp) may still get clear on the part
            # of the line IK can follow (the wrist at its limit loses it later).
            if not c.collides(q0[None])[0]:
                c.notes.append(f"{why}; {START_REPAIRS['retreat_skipped']} (start is clear)")
                return q0[None]
            if not extras:
                raise _PlanFailure(PlanStatus.START_IN_COLLISION, f"{why} (planner extras off)")
            path = self._partial_retreat(q0, c.edge_free, c.allow_start, c.collides)
            if path is not None:
                c.notes.append(f"{why}; {START_REPAIRS['retreat_shortened']} to where IK held the line")
                return path
            path = self._self_motion_retreat(q0, c.edge_free, c.allow_start, c.collides)
            if path is None:
                raise _PlanFailure(PlanStatus.START_IN_COLLISION, why)
            c.notes.append(f"{why}; the arm moved in its {START_REPAIRS['self_motion_retreat']}")
            return path
        finally:
            c.timings["retreat"] = time.perf_counter() - t

    def _approach(self, c: "_Call", rounds, approach: bool, extras: bool = True) -> np.ndarray:
        """The approach, computed backwards from each goal candidate until one is clear. With extras,
        when IK can follow no candidate's line back (the arm at full reach, the wrist at a limit),
        the approach is shortened to the part IK follows, or dropped (_short_approach)."""
        t = time.perf_counter()
        blocked, kinematic, tried, unfollowed = 0, "", [], []
        try:
            for next_round in rounds:
                for qg in next_round():
                    if any(np.abs(qg - q).max() < 1e-3 for q in tried):
                        continue
                    tried.append(qg)
                    if approach and self.approach_distance > 0:
                        try:
                            path = cartesian_line(self.kin, self.ik, qg, -self.approach_distance)[::-1]
                        except CartesianPathError as e:
                            kinematic = f"approach: {e}"
                            unfollowed.append(qg)
                            continue
                    else:
                        path = qg[None]
                    if not self._approach_clear(c, path):
                        blocked += 1
                        continue
                    return path
            path = self._short_approach(c, unfollowed, kinematic) if extras else None
            if path is not None:
                return path
        finally:
            c.timings["approach"] = time.perf_counter() - t
        if not tried:
            raise _PlanFailure(PlanStatus.GOAL_IN_COLLISION, "every IK solution for the target collides")
        if blocked:
            raise _PlanFailure(PlanStatus.GOAL_IN_COLLISION, f"approach blocked for {blocked} of "
                               f"{len(tried)} collision-free goal IK solutions")
        raise _PlanFailure(PlanStatus.IK_FAILED, f"no goal IK solution admits the straight approach ({kinematic})")

    def _approach_clear(self, c: "_Call", path: np.ndarray) -> bool:
        """An approach's first configuration is free without allowances, the rest with the goal's."""
        return not c.collides(path[:1])[0] and self._segment_free(path, c.edge_free, c.allow_goal)

    def _short_approach(self, c: "_Call", candidates, why: str) -> np.ndarray | None:
        """The first collision-free of: the part of a candidate's line IK follows, else the goal alone
        (the transit then ends at the goal; still collision-checked, only not straight)."""
        for qg in candidates:
            try:
                path = cartesian_line(self.kin, self.ik, qg, -self.approach_distance, partial=True)[::-1]
                note = "approach shortened to where IK held the line"
            except CartesianPathError:
                path, note = qg[None], "approach dropped"
            if self._approach_clear(c, path):
                c.notes.append(f"{why}; {note}")
                return path
        return None

    def _transit(self, c: "_Call", mode: Mode, q_a, q_b, timeout: float) -> np.ndarray:
        """RRT-Connect from the retreat's end to the approach's start, in what is left of the timeout."""
        if c.collides(q_a[None])[0]:
            raise _PlanFailure(PlanStatus.START_IN_COLLISION, "the retreat ends in collision")
        t = time.perf_counter()
        remaining = max(1e-3, timeout - (t - c.t_all))
        res = self.rrt.plan(q_a, q_b, c.collides, c.edge_free, remaining, seed=self._rrt_seed,
                            max_iterations=self.rrt_iterations)
        c.timings[mode.value] = time.perf_counter() - t
        if res.status is not RRTStatus.SOLVED:
            cut = (f"its {self.rrt_iterations} iterations" if res.iterations > self.rrt_iterations
                   else f"the {remaining:.2f} s left of the timeout")
            raise _PlanFailure(PlanStatus.PLAN_TIMEOUT, f"{mode.value}: no path within {cut}")
        return res.path


class _PlanFailure(Exception):
    """A phase of plan() failed: plan() answers PlanResult(status) with the message."""

    def __init__(self, status: PlanStatus, message: str):
        super().__init__(message)
        self.status = status


class _Call:
    """One plan() call: what the hand and held object may touch at the start and at the goal, the
    attached object every check carries, and the timings and notes gathered so far."""

    def __init__(self, cm: CollisionModel, attached: AttachedObject | None, t_all: float,
                 allow_start: AllowedContacts, allow_goal: AllowedContacts):
        self.cm, self.attached, self.t_all = cm, attached, t_all
        self.allow_start, self.allow_goal = allow_start, allow_goal
        self.timings: dict[str, float] = {}
        self.notes: list[str] = []

    def collides(self, Q, allow: AllowedContacts = AllowedContacts()):
        return self.cm.in_collision(Q, self.attached, allow)

    def edge_free(self, a, b, allow: AllowedContacts = AllowedContacts()):
        return self.cm.check_motion(a, b, self.attached, allow)

    def fail(self, status: PlanStatus, message: str) -> PlanResult:
        self.timings["total"] = time.perf_counter() - self.t_all
        return PlanResult(status, timings=self.timings, message=message)
