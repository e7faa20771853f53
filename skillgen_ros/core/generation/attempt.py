"""One demonstration-generation attempt: the paper's Algorithm 1 over a `GenerationEnv`.

skillgen:  per skill i - estimate T_W^{O_i'}, pick a source demo, T_W^{E_0'} = T_W^{O_i'} T_O^{E_0},
           (optionally perturb it), plan + execute a transit/transfer motion there, (replay the
           recovery segment), then replay T_W^{A_t'} = T_W^{O_i'} T_O^{A_t} as noisy delta actions.
mimicgen:  NVlabs/mimicgen's generator (mimicgen.py): object-centric subtasks with randomized ends,
           whole-segment transform, linear interpolation between them; no planner, no collisions.
replay_noise: the whole source demo replayed with action noise from its own initial scene.
Then the task success check decides whether the attempt is kept. The env does the acting; this
module does the bookkeeping and the math, and records every step for the dataset.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Protocol, Sequence

import numpy as np

from ..errors import InvalidInputError, NoAnswerError, SkillGenError
from ..geometry import Pose
from ..skills.actions import ActionScale, make_action, pose_to_delta_action
from ..skills.augmentation import AugmentationConfig, perturb_initiation
from ..skills.replay import plan_replay
from ..skills.protocols import SkillLike, TaskLike
from ..skills.segment import SourceDemo
from ..skills.transform import matrix_to_array
from .episode import OBSERVATION_SOURCES, Episode, EpisodeRecorder, Observation, StepLabel
from .initiation import initiation_candidates
from .mimicgen import check_subtasks, run_mimicgen
from .outcome import GOAL_INFEASIBLE, FailureReason, motion_failure  # noqa: F401 (re-exported)
from .outcome import AttemptAborted, AttemptFailed as _Fail  # noqa: F401 (AttemptAborted re-exported)
from .remote_skill import run_remote_skill
from .profile import DEFAULT_PROFILE
from .release import Feedback, ReleaseConfig, release_targets
from .replay_noise import check_initial_states, run_replay_noise
from .seeds import attempt_rng, scene_seed
from .selection import make_strategy

METHODS = ("skillgen", "mimicgen", "replay_noise")


class GenerationEnv(Protocol):
    """What an attempt needs from the world (in-process sim or the ROS graph behind clients).

    plan_and_execute returns the planner's status (a str or an enum whose name is OK/SUCCESS,
    IK_FAILED, PLAN_FAILED, COLLISION, TIMEOUT, ...) and the observation after each executed
    control step. step() runs one 20 Hz OSC step towards an absolute target and returns the
    observation after it. An optional `skill_succeeded(skill_index) -> bool` is used if present, and
    an optional `set_next_skill(skill_index)` is told the skill before its pose estimate.
    """

    def reset(self, task: str, variant: str, seed: int): ...
    def observe(self) -> Observation: ...
    def estimate_poses(self) -> Mapping[str, Pose]: ...
    def current_ee_pose(self) -> Pose: ...
    def current_q(self) -> np.ndarray: ...
    def plan_and_execute(self, target: Pose, mode: str, attached: str | None) -> tuple[object, Sequence[Observation]]: ...
    def step(self, target: Pose, gripper: float) -> Observation: ...
    def task_success(self) -> bool: ...
    def collided(self) -> bool: ...


@dataclass(frozen=True)
class GenerationConfig:
    variant: str = "D0"
    action_noise: float = 0.05  # sigma on normalized delta-pose actions (paper: 0.05)
    selection: str = "random"
    selection_params: dict = field(default_factory=dict)
    augment: bool = False
    augmentation: AugmentationConfig = AugmentationConfig()
    scale: ActionScale = ActionScale()
    interpolation_steps: int = 5  # MimicGen's num_interpolation_steps (mimicgen.py)
    fixed_steps: int = 0  # MimicGen's num_fixed_steps
    max_steps: int = 3000  # total control steps before TIMEOUT
    time_limit_s: float | None = None  # wall time before TIMEOUT
    check_collisions: bool = True  # fail planned motions that the env reports as colliding
    # skillgen: (source demo, symmetric object frame) pairs tried for a skill whose initiation pose
    # has no collision-free IK (initiation.py); 1 = the paper (the attempt fails on the first).
    initiation_candidates: int = 6
    # before a planned motion, let the object just released come free of the hand (release.py):
    # hold while the fingers open (settle), unjam fingers stopped short of open, follow a push by
    # an open finger, clear a finger still touching. ReleaseConfig().without_moves() = only the settle.
    release: ReleaseConfig = ReleaseConfig()
    profile: str = DEFAULT_PROFILE  # recorded; RunRequest.config() applies it (profile.py)
    planner_extras: bool = True  # the planner's start repairs (MotionPlanner.plan extras)
    # what obs/<id>_pose records (episode.py): "ground_truth" (a sim: the true pose at every step) or
    # "estimate" (a real robot: perception's estimates, a grasped object moved with the hand)
    observation_source: str = "ground_truth"

    def __post_init__(self):
        if (self.action_noise < 0 or self.interpolation_steps < 0 or self.fixed_steps < 0 or self.max_steps < 1
                or self.initiation_candidates < 1 or self.observation_source not in OBSERVATION_SOURCES):
            raise InvalidInputError(f"invalid generation config {self}", reason="INVALID_PARAMETER")


@dataclass(frozen=True)
class AttemptResult:
    index: int
    method: str
    success: bool
    reason: FailureReason
    message: str
    scene_seed: int
    source_demos: tuple[int, ...]  # per skill (replay_noise: the one demo)
    episode: Episode | None  # None in a RunResult once the dataset holds it (session.run_generation)
    timings: dict  # stage -> seconds: reset, perception, motion, skill, success, total
    initiation_candidates_used: tuple[int, ...] = ()  # skillgen: initiation poses tried, per skill reached


class _Attempt:
    """State of one attempt in flight; methods follow Algorithm 1's steps."""

    def __init__(self, env: GenerationEnv, demos: Sequence[SourceDemo], task: TaskLike, method: str,
                 index: int, seed: int, config: GenerationConfig, should_abort: Callable[[], str] | None = None):
        self.env, self.demos, self.task, self.method, self.cfg = env, demos, task, method, config
        self.should_abort = should_abort
        self.index = index
        self.scene_seed = scene_seed(seed, index)
        self.rng_select = attempt_rng(seed, index, "selection")
        self.rng_noise = attempt_rng(seed, index, "noise")
        self.rng_aug = attempt_rng(seed, index, "augmentation")
        self.rng_fallback = attempt_rng(seed, index, "initiation")
        self.rng_subtasks = attempt_rng(seed, index, "subtasks")
        self.candidates_used: list[int] = []
        self.success_seen = False  # MimicGen: task success at any step (mimicgen.py)
        self.strategy = make_strategy(config.selection, **config.selection_params)
        self.rec = EpisodeRecorder(config.observation_source)
        self.timings = {k: 0.0 for k in ("reset", "perception", "motion", "skill", "success")}
        self.t0 = time.perf_counter()
        self.obs: Observation | None = None
        self.gripper = -1.0  # last gripper command; the hand starts open
        self.last_target: np.ndarray | None = None  # last noise-free pose target streamed
        self.chosen: list[int] = []

    # -- bookkeeping
    def _budget(self) -> None:
        """Before every step and env call: the step and time limits, and a stop request."""
        why = self.should_abort() if self.should_abort else ""
        if why:
            raise AttemptAborted(why)
        if len(self.rec) >= self.cfg.max_steps:
            raise _Fail(FailureReason.TIMEOUT, f"attempt exceeded {self.cfg.max_steps} control steps")
        if self.cfg.time_limit_s is not None and time.perf_counter() - self.t0 > self.cfg.time_limit_s:
            raise _Fail(FailureReason.TIMEOUT, f"attempt exceeded {self.cfg.time_limit_s} s")

    def _step(self, target: np.ndarray, gripper: float, sigma: float, label: StepLabel, rng=None) -> None:
        """One OSC step toward `target`: normalized delta action (+ noise), executed and recorded."""
        self._budget()
        current = self.obs.ee_matrix()
        action, commanded = make_action(target, current, gripper, sigma, rng or self.rng_noise, self.cfg.scale)
        try:
            nxt = self.env.step(Pose.from_matrix(commanded), float(gripper))
        except (SkillGenError, TimeoutError) as e:
            raise _Fail(FailureReason.SKILL_FAILED, f"control step failed: {e}") from e
        self.rec.add(self.obs, action, commanded, gripper, label)
        self.obs, self.gripper, self.last_target = nxt, float(gripper), np.asarray(target, float)

    def _timed(self, stage: str, t: float) -> None:
        self.timings[stage] += time.perf_counter() - t

    # -- Algorithm 1 pieces
    def reset(self, variant: str, seed: int) -> None:
        t = time.perf_counter()
        self.env.reset(self.task.name, variant, seed)
        extras = getattr(self.env, "set_planner_extras", None)
        if extras is not None:
            extras(self.cfg.planner_extras)
        self.obs = self.env.observe()
        self._timed("reset", t)
        try:  # a ground_truth dataset needs an env that knows the true poses: fail before anything moves
            self.rec.require_ground_truth(self.obs, getattr(self.env, "true_object_poses", None))
        except (SkillGenError, TimeoutError) as e:
            if getattr(e, "reason", "") == "NO_GROUND_TRUTH":
                raise
            raise _Fail(FailureReason.TIMEOUT, f"true object poses after the reset: {e}") from e

    def estimate(self, skill: SkillLike) -> np.ndarray:
        t = time.perf_counter()
        hint = getattr(self.env, "set_next_skill", None)
        if hint is not None:  # perception requires an object hidden at reset only from its skill on (TaskSpec.hidden_until)
            hint(skill.index)
        try:
            poses = self.env.estimate_poses()
        except (SkillGenError, TimeoutError) as e:
            raise _Fail(FailureReason.PERCEPTION_FAILED, f"pose estimation failed: {e}") from e
        finally:
            self._timed("perception", t)
        if skill.object_id not in poses:
            raise _Fail(FailureReason.PERCEPTION_FAILED, f"no pose for skill {skill.index} object {skill.object_id!r}")
        if not self.obs.object_poses or not self.rec:  # observations carry the estimates from here on
            self.obs = self.env.observe()
        stamp, seen = getattr(self.env, "last_estimate", None) or (self.obs.stamp_ns, poses)
        self.rec.add_estimate(stamp, seen)  # what perception saw, apart from the recorded observations
        p = poses[skill.object_id]
        return p.matrix() if isinstance(p, Pose) else np.asarray(p, float)

    def select(self, skill: SkillLike, T_W_O: np.ndarray) -> int:
        prev = self.chosen[-1] if self.chosen else None
        j = self.strategy.select(self.demos, skill.index, T_W_O, prev, self.rng_select)
        self.chosen.append(j)
        return j

    def plan_motion(self, skill: SkillLike, target: np.ndarray, label: StepLabel) -> None:
        """Transit/transfer motion to the initiation pose; executed steps are recorded as mp steps."""
        self._budget()
        t = time.perf_counter()
        hint = getattr(self.env, "set_skill_object", None)
        if hint is not None:  # lets the env allow hand/object contact in approach (paper, App. planning)
            hint(skill.object_id)
        try:
            status, steps = self.env.plan_and_execute(Pose.from_matrix(target), skill.mode, skill.attached_object)
        except TimeoutError as e:
            raise _Fail(FailureReason.TIMEOUT, f"motion to skill {skill.index} timed out: {e}") from e
        except SkillGenError as e:
            raise _Fail(motion_failure(e.reason) or FailureReason.PLAN_FAILED, f"motion to skill {skill.index}: {e}") from e
        finally:
            self._timed("motion", t)
        for nxt in steps:  # action of an mp step: the delta to where the tracked trajectory went
            a = np.concatenate([pose_to_delta_action(nxt.ee_matrix(), self.obs.ee_matrix(), self.cfg.scale),
                                [self.gripper]])
            self.rec.add(self.obs, a, nxt.ee_pose, self.gripper, label)
            self.obs = nxt
        reason = motion_failure(status)
        if reason is not None:
            name = str(getattr(status, "name", status))
            raise _Fail(reason, f"motion to skill {skill.index} ({skill.mode}) failed: {name}",
                        goal_infeasible=not steps and name.upper() in GOAL_INFEASIBLE)
        if self.cfg.check_collisions and self.env.collided():
            raise _Fail(FailureReason.EXECUTION_COLLISION, f"collision during the motion to skill {skill.index}")
        if not steps:
            self.obs = self.env.observe()
        self._budget()

    def settle_gripper(self, label: StepLabel) -> None:
        """Before a planned motion: let the object just released come free of the hand (release.py)."""
        if self.gripper > 0:
            return
        moves = release_targets(self.obs.ee_matrix(), float(np.sum(self.obs.gripper)), self.cfg.release,
                                self.last_target, self.obs.ee_wrench)
        t = time.perf_counter()
        try:
            target = next(moves, None)
            while target is not None:
                self._step(target, self.gripper, 0.0, label)
                try:
                    target = moves.send(Feedback(float(np.sum(self.obs.gripper)), self.obs.ee_matrix()[:3, 3],
                                                 self.obs.ee_wrench))
                except StopIteration:
                    target = None
        finally:
            self._timed("motion", t)

    def replay(self, targets: np.ndarray, gripper: np.ndarray, label: StepLabel, sigma: float) -> None:
        t = time.perf_counter()
        try:
            for T, g in zip(targets, gripper):
                self._step(T, float(g), sigma, label)
        finally:
            self._timed("skill", t)

    def check_skill(self, skill: SkillLike) -> None:
        fn = getattr(self.env, "skill_succeeded", None)
        if fn is not None and not fn(skill.index):
            raise _Fail(FailureReason.SKILL_FAILED, f"skill {skill.index} ({skill.name}) did not succeed")

    # -- methods
    def run_skill_based(self) -> None:
        """Algorithm 1: for each skill, estimate -> select -> reach the segment start -> replay."""
        self.reset(self.cfg.variant, self.scene_seed)
        for skill in sorted(self.task.skills, key=lambda s: s.index):
            T_W_O = self.estimate(skill)  # T_W^{O_i'}
            j = self.select(skill, T_W_O)
            self.skillgen_skill(skill, self.demos[j].skill(skill.index), j, T_W_O)
            self.check_skill(skill)

    def skillgen_skill(self, skill: SkillLike, seg, j: int, T_W_O: np.ndarray) -> None:
        """Plan to T_W^{E_0'} (perturbed when augmenting), recover, replay T_W^{O'} T_O^{A_t}.
        An initiation pose the planner cannot reach is swapped for the next candidate."""
        candidates = list(initiation_candidates(self.demos, self.task, skill, j, T_W_O, self.rng_fallback,
                                                self.cfg.initiation_candidates))
        self.settle_gripper(StepLabel(True, skill.index, j, matrix_to_array(seg.initiation_in_world(T_W_O))))
        self.candidates_used.append(0)
        for k, (j, T_W_O) in enumerate(candidates):
            self.candidates_used[-1] = k + 1
            seg = self.demos[j].skill(skill.index)
            init = seg.initiation_in_world(T_W_O)
            goal = perturb_initiation(init, self.cfg.augmentation, self.rng_aug) if self.cfg.augment else init
            goal7 = matrix_to_array(goal)
            try:
                self.plan_motion(skill, goal, StepLabel(True, skill.index, j, goal7))
                break
            except _Fail as f:
                if not f.goal_infeasible or k == len(candidates) - 1:
                    raise
        self.chosen[-1] = j
        if hasattr(self.env, "replay_skill"):
            return run_remote_skill(self, skill, j, T_W_O, goal7)
        cmds = plan_replay(seg, T_W_O, self.obs.ee_matrix(), self.cfg.augment, self.cfg.augmentation)
        rng = np.random.default_rng(int(self.rng_noise.integers(2**63 - 1)))  # drawn as remote_skill seeds skill_replay
        t = time.perf_counter()
        try:
            for T, g, rec in zip(cmds.targets, cmds.gripper, cmds.recovery):
                sigma = 0.0 if rec else self.cfg.action_noise  # recovery poses are planned, not demonstrated
                self._step(T, float(g), sigma, StepLabel(False, skill.index, j, goal7, bool(rec)), rng)
        finally:
            self._timed("skill", t)


def run_attempt(env: GenerationEnv, source_demos: Sequence[SourceDemo], task: TaskLike, method: str,
                index: int, seed: int, config: GenerationConfig = GenerationConfig(),
                should_abort: Callable[[], str] | None = None) -> AttemptResult:
    """Run attempt `index` of a run seeded `seed`; never raises for in-attempt failures.

    should_abort() returning a reason abandons the attempt at its next step or env call: it raises
    AttemptAborted and nothing of it is returned (the attempt depends only on (seed, index), so
    running the index again later gives what it would have).

    Bad requests (unknown method, no source demos, a demo lacking a skill) raise SkillGenError
    before anything moves; failures while acting come back as `AttemptResult.reason`.
    """
    if method not in METHODS:
        raise InvalidInputError(f"unknown method {method!r}; known: {list(METHODS)}", reason="UNKNOWN_METHOD")
    if not source_demos:
        raise InvalidInputError("no source demos given", reason="NO_SOURCE_DEMOS")
    if method == "replay_noise":
        check_initial_states(source_demos)
    else:
        for d in source_demos:
            for sk in task.skills:
                d.skill(sk.index)  # raises ANNOTATION_MISSING_SKILL naming the demo
        if method == "mimicgen":
            check_subtasks(source_demos, task)
    a = _Attempt(env, source_demos, task, method, index, seed, config, should_abort)
    reason, message = FailureReason.OK, "task succeeded"
    try:
        if method == "replay_noise":
            run_replay_noise(a)
        elif method == "mimicgen":
            run_mimicgen(a)
        else:
            a.run_skill_based()
        t = time.perf_counter()
        ok = a.success_seen or bool(env.task_success())
        a._timed("success", t)
        if not ok:
            reason, message = FailureReason.TASK_FAILED, "all skills ran but the task success check failed"
    except _Fail as f:
        reason, message = f.reason, str(f)
    except NoAnswerError as e:  # a node gone mid-attempt (reset, task_success): this attempt fails, the run goes on
        reason = FailureReason(e.reason) if e.reason in FailureReason._value2member_map_ else FailureReason.TIMEOUT
        message = f"a node did not answer: {e}"
    try:
        a.rec.resolve_from(getattr(env, "true_object_poses", None), getattr(env, "true_object_joints", None))
    except (SkillGenError, TimeoutError) as e:  # the steps cannot be recorded truthfully: keep none of them
        reason, message = FailureReason.TIMEOUT, f"true object poses of the attempt's steps: {e}"
        a.rec = EpisodeRecorder(config.observation_source)
    a.timings["total"] = time.perf_counter() - a.t0
    success = reason is FailureReason.OK
    return AttemptResult(index=index, method=method, success=success, reason=reason, message=message,
                         scene_seed=a.scene_seed,
                         source_demos=tuple(a.chosen), episode=a.rec.episode(success), timings=a.timings,
                         initiation_candidates_used=tuple(a.candidates_used))
