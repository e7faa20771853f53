"""One HSP rollout: the paper's Algorithm 2 ("HSP Deployment") over a GenerationEnv.

For each skill <O, I, pi, T> of the task's sequence: observe; predict the initiation pose with I
(initiation.py: class / reg / tamp); plan and execute a transit or transfer motion to it through
env.plan_and_execute (retreat, approach, collision-checked, as generation's motions); then run pi
at the control rate - its normalized delta-pose action becomes an absolute OSC target, current
EE pose + delta (core/skills/actions.delta_action_to_pose, the inverse of make_action) - until T
fires (5 consecutive positives, inside the policy) or, for HSP-TAMP, the skill's privileged goal
holds (goals.py), or the skill's step budget runs out; then the next skill. The task's success
check runs after every control step, as robomimic's rollouts do, and ends the rollout.

The env is the same one generation uses (core/generation/sim_env.SimGenerationEnv in-process,
nodes/graph_env.RosGraphEnv in the graph), so a rollout in and out of ROS is the same code.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import InvalidInputError, SkillGenError
from ..geometry import Pose
from ..skills.actions import ActionScale, delta_action_to_pose
from ..skills.segment import SourceDemo
from .goals import skill_goal_reached
from .initiation import check_mode, pose7, predict_initiation
from .outcome import DeployReason, motion_reason, status_name
from .seeds import rollout_rng

STAGES = ("initiation", "motion", "policy", "termination")
Progress = Callable[[int, str, int], None]  # (skill index, stage, control steps so far)


@dataclass(frozen=True)
class DeployConfig:
    mode: str = "class"
    max_steps: int = 1500  # control steps of the whole rollout (motion + policy) before POLICY_TIMEOUT
    skill_max_steps: int = 400  # policy steps of one skill before it is ended and the next one starts
    initiation_candidates: int = 6  # tamp only: generation's default (initiation.py); class/reg: one pose
    scale: ActionScale = ActionScale()

    def __post_init__(self):
        check_mode(self.mode)
        if self.max_steps < 1 or self.skill_max_steps < 1 or self.initiation_candidates < 1:
            raise InvalidInputError(f"invalid deploy config {self}", reason="INVALID_PARAMETER")


@dataclass(frozen=True)
class SkillLog:
    """What one skill did: its initiation, the motion's and the policy's steps, how it ended."""

    skill_index: int
    source_demo: int  # the demo whose initiation was used (-1: reg)
    initiation: tuple[float, ...]  # (7,) world pose the motion targeted
    motion_steps: int
    policy_steps: int
    ended: str  # termination | goal | budget | task_success | failed


@dataclass(frozen=True)
class RolloutResult:
    success: bool
    reason: DeployReason
    message: str
    steps: int  # control steps executed (motion + policy)
    reset_seed: int
    skills: tuple[SkillLog, ...]
    ee_trajectory: np.ndarray  # (steps + 1, 7): the EE pose before the first step and after each
    policy_seconds: float = 0.0  # pi + T inference, summed
    policy_steps: int = 0
    timings: dict = field(default_factory=dict)

    @property
    def inference_ms_per_step(self) -> float:
        return 1000.0 * self.policy_seconds / self.policy_steps if self.policy_steps else 0.0


class _Fail(Exception):
    def __init__(self, reason: DeployReason, message: str):
        super().__init__(message)
        self.reason = reason


def gripper_command(a: float) -> float:
    """The dataset's gripper actions are -1 (open) or +1 (closed); pi's continuous output is snapped."""
    return 1.0 if float(a) > 0.0 else -1.0


def policy_target(action: np.ndarray, current: np.ndarray, scale: ActionScale = ActionScale()) -> tuple[np.ndarray, float]:
    """pi's (7,) normalized action -> (absolute (4,4) OSC target, gripper command)."""
    a = np.clip(np.asarray(action, float).reshape(-1), -1.0, 1.0)
    if a.shape != (7,) or not np.all(np.isfinite(a)):
        raise InvalidInputError(f"policy action must be 7 finite values, got {np.asarray(action).shape}")
    return delta_action_to_pose(a, current, scale), gripper_command(a[6])


def true_object_poses(env) -> dict[str, Pose]:
    """Privileged ground truth (HSP-TAMP only): an env's own hook, else the in-process sim's state."""
    fn = getattr(env, "true_object_poses", None)
    if fn is not None:
        return dict(fn())
    world = getattr(env, "world", None)
    if world is None:
        raise SkillGenError("HSP-TAMP needs the true object poses, which this env cannot give",
                            reason="PERCEPTION_FAILED")
    return dict(world.object_poses())


class _Rollout:
    def __init__(self, env, policy, task, demos, config: DeployConfig, seed: int, obs_fn,
                 on_progress: Progress | None):
        self.env, self.policy, self.task, self.demos, self.cfg = env, policy, task, demos, config
        self.obs_fn = obs_fn
        self.progress = on_progress or (lambda *_: None)
        self.rng = rollout_rng(seed, 0, 0)  # from the reset seed alone: the same in the graph and in-process
        self.steps = 0
        self.ee: list[np.ndarray] = []
        self.logs: list[SkillLog] = []
        self.chosen: int | None = None
        self.succeeded = False
        self.gripper = -1.0
        self.width: float | None = None
        self.closed_steps = 0  # policy steps the hand has been commanded closed without a break
        self.policy_s, self.policy_n = 0.0, 0
        self.obs = None

    def ask(self, fn, *args):
        """Call the policy; an observation it was not trained on means a checkpoint for another layout."""
        try:
            return fn(*args)
        except InvalidInputError as e:
            raise _Fail(DeployReason.BAD_CHECKPOINT, f"the checkpoint does not fit this deployment: {e}") from e

    def out_of_budget(self) -> list[int]:
        """The skills so far whose step budget ran out (each ended there and the next one started)."""
        return [s.skill_index for s in self.logs if s.ended == "budget"]

    def _budget(self) -> None:
        if self.steps >= self.cfg.max_steps:
            raise _Fail(DeployReason.POLICY_TIMEOUT, f"rollout exceeded {self.cfg.max_steps} control steps")

    def _record(self, obs) -> None:
        self.obs = obs
        self.ee.append(np.asarray(obs.ee_pose, float))

    def estimate(self, skill) -> dict:
        hint = getattr(self.env, "set_next_skill", None)
        if hint is not None:  # which objects perception requires (TaskSpec.hidden_until)
            hint(skill.index)
        try:
            poses = self.env.estimate_poses()
        except (SkillGenError, TimeoutError) as e:
            raise _Fail(DeployReason.PERCEPTION_FAILED, f"pose estimation failed: {e}") from e
        if skill.object_id not in poses:
            raise _Fail(DeployReason.PERCEPTION_FAILED, f"no pose for skill {skill.index} object {skill.object_id!r}")
        self.obs = self.env.observe()  # observations carry the estimates from here on
        return poses

    def motion(self, skill, goals: Sequence[np.ndarray]) -> tuple[int, int]:
        """Plan + execute to the first reachable goal; returns (goal index, steps executed)."""
        hint = getattr(self.env, "set_skill_object", None)
        if hint is not None:
            hint(skill.object_id)
        for k, goal in enumerate(goals):
            self._budget()
            try:
                status, steps = self.env.plan_and_execute(Pose.from_matrix(goal), skill.mode, skill.attached_object)
            except (SkillGenError, TimeoutError) as e:
                raise _Fail(DeployReason.PLAN_FAILED, f"motion to skill {skill.index}: {e}") from e
            for o in steps:
                self.steps += 1
                self._record(o)
            reason = motion_reason(status, moved=bool(steps))
            if reason is DeployReason.INITIATION_UNREACHABLE and k < len(goals) - 1:
                continue
            if reason is not None:
                raise _Fail(reason, f"motion to skill {skill.index} ({skill.mode}) failed: {status_name(status)}")
            if self.env.collided():
                raise _Fail(DeployReason.PLAN_FAILED, f"collision during the motion to skill {skill.index}")
            if not steps:
                self.obs = self.env.observe()
            return k, len(steps)
        raise AssertionError("unreachable")  # goals is never empty

    def done_by_goal(self, skill, od) -> bool:
        """Termination of this step: T (class/reg, 5 consecutive inside the policy) or the privileged goal (tamp)."""
        t = time.perf_counter()
        if self.cfg.mode != "tamp":
            fired = bool(self.ask(self.policy.terminated, od))
            self.policy_s += time.perf_counter() - t
            return fired
        width = float(np.sum(self.obs.gripper))
        change = width - self.width if self.width is not None else np.inf  # a skill's first step: not known yet
        self.width = width
        return skill_goal_reached(self.task, skill, self.truth(), self.obs.ee_pose, width, self.gripper,
                                  self.obs.object_joints, change, self.closed_steps)

    def truth(self) -> dict:
        try:
            return true_object_poses(self.env)
        except (SkillGenError, TimeoutError) as e:
            raise _Fail(DeployReason.PERCEPTION_FAILED, f"no ground truth for HSP-TAMP: {e}") from e

    def run_policy(self, skill) -> tuple[int, str]:
        self.policy.start_skill(skill.index)
        self.width = None  # the finger width at the previous goal check (tamp)
        for n in range(self.cfg.skill_max_steps):
            od = self.ask(self.obs_fn, self.obs)
            if self.done_by_goal(skill, od):
                self.progress(skill.index, "termination", self.steps)
                return n, "termination" if self.cfg.mode != "tamp" else "goal"
            self.progress(skill.index, "policy", self.steps)
            if self.policy_step(od):
                return n + 1, "task_success"
        return self.cfg.skill_max_steps, "budget"

    def policy_step(self, od) -> bool:
        """a = pi(o), executed as one OSC step; True once the task succeeds."""
        self._budget()
        t = time.perf_counter()
        action = self.ask(self.policy.act, od)
        self.policy_s += time.perf_counter() - t
        self.policy_n += 1
        target, g = policy_target(action, self.obs.ee_matrix(), self.cfg.scale)
        try:
            obs = self.env.step(Pose.from_matrix(target), g)
        except (SkillGenError, TimeoutError) as e:
            raise _Fail(DeployReason.CONTROL_FAILED, f"control step failed: {e}") from e
        self.steps += 1
        self.gripper = g
        self.closed_steps = self.closed_steps + 1 if g > 0 else 0
        self._record(obs)
        self.succeeded = bool(self.env.task_success())
        return self.succeeded

    def whole_episode(self) -> None:
        """The MimicGen BC-RNN baseline: one policy trained on every step runs the episode from the
        reset, robomimic style (no planner, no skills), until success or the step budget."""
        first = min(self.task.skills, key=lambda s: s.index)
        hint = getattr(self.env, "set_skill_object", None)
        if hint is not None:  # the env tracks the first grasped object in the hand (grasp.py)
            hint(first.object_id)
        self.estimate(first)
        self.policy.start_skill(first.index)
        self.progress(first.index, "policy", self.steps)
        while not self.policy_step(self.ask(self.obs_fn, self.obs)):
            self.progress(first.index, "policy", self.steps)

    def skill(self, skill) -> None:
        self.progress(skill.index, "initiation", self.steps)
        poses = self.estimate(skill)
        true = self.truth() if self.cfg.mode == "tamp" else {}
        choice = self.ask(predict_initiation, self.cfg.mode, self.policy, self.ask(self.obs_fn, self.obs), skill,
                          self.task, self.demos, poses[skill.object_id], true.get(skill.object_id), self.chosen,
                          self.rng, self.cfg.initiation_candidates)
        self.progress(skill.index, "motion", self.steps)
        k, moved = self.motion(skill, choice.poses)
        j = choice.demos[k]
        self.chosen = j if j >= 0 else self.chosen
        try:
            n, ended = self.run_policy(skill)
        except _Fail:
            self.logs.append(SkillLog(skill.index, j, tuple(float(v) for v in pose7(choice.poses[k])), moved, -1, "failed"))
            raise
        self.logs.append(SkillLog(skill.index, j, tuple(float(v) for v in pose7(choice.poses[k])), moved, n, ended))


def run_rollout(env, policy, task, reset_seed: int, variant: str | None, config: DeployConfig = DeployConfig(),
                demos: Sequence[SourceDemo] = (), obs_fn=None, on_progress: Progress | None = None) -> RolloutResult:
    """One rollout; never raises for in-rollout failures (they come back as RolloutResult.reason).

    variant None: deploy on the scene the env already holds (no reset). class and tamp need the
    source demos the checkpoint was trained from (the same list generation loaded).
    """
    check_mode(config.mode)
    if config.mode in ("class", "tamp") and not demos:
        raise InvalidInputError(f"initiation mode {config.mode!r} needs the task's source demos",
                                reason="NO_SOURCE_DEMOS")
    if obs_fn is None:
        from ..learning.observation import policy_obs as obs_fn
    r = _Rollout(env, policy, task, demos, config, reset_seed, obs_fn, on_progress)
    t0 = time.perf_counter()
    reason, message = DeployReason.OK, "task succeeded"
    try:
        if variant is not None:
            env.reset(task.name, variant, int(reset_seed))
        r._record(env.observe())
        if config.mode == "bc":
            r.whole_episode()
        for skill in sorted(task.skills, key=lambda s: s.index) if config.mode != "bc" else ():
            r.skill(skill)
            if r.succeeded:
                break
        if not r.succeeded:
            r.succeeded = bool(env.task_success())
        if not r.succeeded:
            late = r.out_of_budget()
            reason = DeployReason.POLICY_TIMEOUT if late else DeployReason.TASK_FAILED
            message = (f"skill(s) {late} ran out of their {config.skill_max_steps}-step budget and the task failed"
                       if late else "every skill terminated but the task success check failed")
    except _Fail as f:
        reason, message = f.reason, str(f)
        late = r.out_of_budget()
        if late:  # the reason names the step that failed; this names the skill that ran out before it
            message += f" (after skill(s) {late} ran out of their {config.skill_max_steps}-step budget)"
    return RolloutResult(success=reason is DeployReason.OK, reason=reason, message=message, steps=r.steps,
                         reset_seed=int(reset_seed), skills=tuple(r.logs),
                         ee_trajectory=np.array(r.ee) if r.ee else np.zeros((0, 7)), policy_seconds=r.policy_s,
                         policy_steps=r.policy_n, timings={"total": time.perf_counter() - t0})
