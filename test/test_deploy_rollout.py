"""The pure HSP executor (core/deploy) over the scripted kinematic world of the generation tests.

A scripted "oracle" policy replays a source demo's skill segment in the current object frame, so
a correct executor (initiation -> motion -> pi until T -> next skill, success checked each step)
completes the fake pick-and-place; other fakes exercise every failure reason.
"""
import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos

from skillgen_ros.core.deploy import DeployConfig, DeployReason, rollout_seed, run_rollout
from skillgen_ros.core.deploy.evaluate import summarize
from skillgen_ros.core.deploy.goals import skill_goal_reached
from skillgen_ros.core.deploy.loading import check_policy
from skillgen_ros.core.deploy.rollout import policy_target
from skillgen_ros.core.deploy.seeds import HELD_OUT_BIT, is_held_out
from skillgen_ros.core.errors import InvalidInputError, SkillGenError
from skillgen_ros.core.generation.grasp import CLOSE_PERIODS
from skillgen_ros.core.generation.seeds import scene_seed
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.skills.actions import pose_to_delta_action
from skillgen_ros.core.robot import TABLE_Z
from skillgen_ros.core.tasks import get_task
from skillgen_ros.core.tasks.spec import SceneState

TASK = FakeTask()
DEMOS = make_source_demos(3)


def obs_fn(obs):
    return {"obs": obs}


class Config:
    task, method, num_source_demos = "pick_place", "skillgen", 3
    has_termination = has_class = has_reg = True


class OraclePolicy:
    """pi replays demo `demo`'s segment of the current skill in the object's current frame; T
    fires once the segment is done; Class names `demo`; Reg returns its initiation pose."""

    config = Config()

    def __init__(self, world, demo=0, stop_after=None, never_terminate=False):
        self.world, self.demo, self.stop_after, self.never = world, demo, stop_after, never_terminate
        self.skill = None

    def start_skill(self, k):
        seg = DEMOS[self.demo].skill(k)
        self.skill, self.i = k, 0
        T_W_O = self.world.objects[seg.object_id]
        self.targets, self.gripper = seg.actions_in_world(T_W_O), seg.gripper

    def act(self, od):
        i = min(self.i, len(self.targets) - 1)
        self.i += 1
        a = pose_to_delta_action(self.targets[i], od["obs"].ee_matrix())
        return np.concatenate([a, [self.gripper[i]]])

    def terminated(self, od):
        if self.never:
            return False
        return self.i >= (self.stop_after or len(self.targets))

    def initiation_source_demo(self, od):
        return self.demo

    def initiation_pose(self, od):
        k = 0 if self.skill is None else self.skill + 1
        seg = DEMOS[self.demo].skill(k)
        return seg.initiation_in_world(self.world.objects[seg.object_id])


def _run(world=None, mode="class", policy=None, **cfg):
    world = world or FakeWorld()
    policy = policy or OraclePolicy(world)
    stages = []
    res = run_rollout(world, policy, TASK, 7, "D0", DeployConfig(mode=mode, **cfg), DEMOS, obs_fn=obs_fn,
                      on_progress=lambda k, stage, step: stages.append((k, stage, step)))
    return res, stages


@pytest.mark.parametrize("mode", ["class", "reg"])
def test_oracle_policy_completes_the_task_through_every_stage_in_order(mode):
    res, stages = _run(mode=mode)
    assert res.success and res.reason is DeployReason.OK, res.message
    # per skill: initiation, motion, then policy steps; skill 0 ends by T, skill 1 by the task's success
    compact = [(k, s) for i, (k, s, _) in enumerate(stages) if i == 0 or stages[i - 1][:2] != (k, s)]
    assert compact == [(0, "initiation"), (0, "motion"), (0, "policy"), (0, "termination"),
                       (1, "initiation"), (1, "motion"), (1, "policy")], compact
    assert [s.ended for s in res.skills] == ["termination", "task_success"]
    assert [s.motion_steps for s in res.skills] == [10, 10]  # the fake planner's 10 steps per motion
    assert res.steps == 20 + sum(s.policy_steps for s in res.skills)
    assert res.ee_trajectory.shape == (res.steps + 1, 7)
    assert [step for _, _, step in stages] == sorted(step for _, _, step in stages)


def test_same_seed_same_rollout():
    a, _ = _run()
    b, _ = _run()
    assert a.steps == b.steps and np.array_equal(a.ee_trajectory, b.ee_trajectory)


@pytest.mark.parametrize("status, reason", [("IK_FAILED", DeployReason.INITIATION_UNREACHABLE),
                                            ("GOAL_IN_COLLISION", DeployReason.INITIATION_UNREACHABLE),
                                            ("PLAN_TIMEOUT", DeployReason.PLAN_FAILED),
                                            ("EXECUTION_FAILED", DeployReason.PLAN_FAILED)])
def test_planner_failures_map_to_reasons(status, reason):
    res, stages = _run(world=FakeWorld(plan_status=status))
    assert not res.success and res.reason is reason and status in res.message
    assert stages[-1][1] == "motion" and res.steps == 0


def test_collision_during_motion_is_plan_failed():
    res, _ = _run(world=FakeWorld(collide=True))
    assert res.reason is DeployReason.PLAN_FAILED and "collision" in res.message


def test_perception_failure():
    res, _ = _run(world=FakeWorld(perception_fails=True))
    assert res.reason is DeployReason.PERCEPTION_FAILED


def test_a_skill_out_of_budget_goes_on_to_the_next_and_the_rollout_reports_policy_timeout():
    world = FakeWorld()
    res, stages = _run(world=world, policy=OraclePolicy(world, never_terminate=True), skill_max_steps=5)
    assert res.reason is DeployReason.POLICY_TIMEOUT, res.message
    assert [s.ended for s in res.skills] == ["budget", "budget"] and [s.policy_steps for s in res.skills] == [5, 5]
    assert "termination" not in {s for _, s, _ in stages}
    ok, _ = _run()
    summary = summarize("pick_place", "D0", "class", [res, ok])
    assert summary.to_json()["skill_endings"] == {"0": {"budget": 1, "termination": 1},
                                                  "1": {"budget": 1, "task_success": 1}}


def test_a_motion_that_fails_after_a_skill_ran_out_of_budget_says_so():
    """The reason is the motion's; the message names the skill whose budget ran out before it."""

    class FailSecondMotion(FakeWorld):
        def plan_and_execute(self, target, mode, attached):
            self.plan_status = "GOAL_IN_COLLISION" if any(c.startswith("plan:") for c in self.calls) else "OK"
            return super().plan_and_execute(target, mode, attached)

    world = FailSecondMotion()
    res, _ = _run(world=world, policy=OraclePolicy(world, never_terminate=True), skill_max_steps=5)
    assert res.reason is DeployReason.INITIATION_UNREACHABLE, res.message
    assert res.message.endswith("(after skill(s) [0] ran out of their 5-step budget)"), res.message
    ok_world = FailSecondMotion()
    plain, _ = _run(world=ok_world, policy=OraclePolicy(ok_world))  # skill 0 ended by T: no such note
    assert plain.reason is DeployReason.INITIATION_UNREACHABLE and "budget" not in plain.message, plain.message


def test_rollout_step_budget():
    res, _ = _run(max_steps=15)
    assert res.reason is DeployReason.POLICY_TIMEOUT and res.steps == 15


def test_early_termination_fails_the_task():
    world = FakeWorld()
    res, _ = _run(world=world, policy=OraclePolicy(world, stop_after=3))
    assert res.reason is DeployReason.TASK_FAILED and [s.ended for s in res.skills] == ["termination"] * 2


def test_policy_that_rejects_the_observation_is_a_bad_checkpoint():
    world = FakeWorld()

    class Wrong(OraclePolicy):
        def act(self, od):
            raise InvalidInputError("observation lacks 'object'")

    res, _ = _run(world=world, policy=Wrong(world))
    assert res.reason is DeployReason.BAD_CHECKPOINT and "object" in res.message


def test_class_head_out_of_range_is_a_bad_checkpoint():
    world = FakeWorld()
    res, _ = _run(world=world, policy=OraclePolicy(world, demo=7))
    assert res.reason is DeployReason.BAD_CHECKPOINT


def test_bad_requests_raise_with_a_reason():
    with pytest.raises(SkillGenError) as e:
        DeployConfig(mode="teleport")
    assert e.value.reason == "UNKNOWN_MODE"
    with pytest.raises(SkillGenError) as e:
        run_rollout(FakeWorld(), OraclePolicy(FakeWorld()), TASK, 1, "D0", DeployConfig(mode="class"), [], obs_fn=obs_fn)
    assert e.value.reason == "NO_SOURCE_DEMOS"


def test_check_policy_names_each_mismatch():
    p = OraclePolicy(FakeWorld())
    check_policy(p, "pick_place", "class", DEMOS)
    cases = [("Square", "class", DEMOS, "task"), ("pick_place", "class", DEMOS[:2], "3 source demos")]
    for task, mode, demos, words in cases:
        with pytest.raises(SkillGenError) as e:
            check_policy(p, task, mode, demos)
        assert e.value.reason == "BAD_CHECKPOINT" and words in str(e.value)

    class NoHeads(Config):
        has_class = has_reg = has_termination = False

    p.config = NoHeads()
    for mode in ("class", "reg"):
        with pytest.raises(SkillGenError) as e:
            check_policy(p, "pick_place", mode, DEMOS)
        assert e.value.reason == "BAD_CHECKPOINT", mode
    check_policy(p, "pick_place", "bc", DEMOS)  # the BC baseline needs pi only


def test_policy_target_inverts_the_dataset_action():
    cur = Pose([0.5, 0.0, 0.3], [1, 0, 0, 0]).matrix()
    target = Pose([0.52, -0.01, 0.29], [0.9990482, 0.0436194, 0, 0]).matrix()
    a = np.concatenate([pose_to_delta_action(target, cur), [0.3]])
    T, g = policy_target(a, cur)
    assert np.allclose(T, target, atol=1e-9) and g == 1.0
    T, g = policy_target(np.array([5.0, 0, 0, 0, 0, 0, -0.2]), cur)  # clipped to one step's 5 cm
    assert np.isclose(T[0, 3] - cur[0, 3], 0.05) and g == -1.0
    with pytest.raises(SkillGenError):
        policy_target(np.array([np.nan] * 7), cur)


def test_held_out_seeds_never_meet_generation_scene_seeds():
    evals = {rollout_seed(s, i) for s in range(3) for i in range(200)}
    gens = {scene_seed(s, i) for s in range(3) for i in range(200)}
    assert all(is_held_out(x) and x < 2**32 for x in evals) and not any(is_held_out(x) for x in gens)
    assert not evals & gens and len(evals) == 600
    assert rollout_seed(0, 5) == rollout_seed(0, 5) != rollout_seed(1, 5)
    assert HELD_OUT_BIT == 2**31


def test_tamp_goal_checks_on_true_poses():
    task = get_task("Square")
    grasp, place = task.skills
    nut, peg = task.object("square_nut"), task.object("square_peg")
    peg_pose = Pose([0.79, 0.10, TABLE_Z + peg.half_extents[2]], [0, 0, 0, 1])
    resting = Pose([0.48, -0.1, TABLE_Z + nut.half_extents[2]], [0, 0, 0, 1])
    lifted = Pose([0.48, -0.1, TABLE_Z + 0.08], [0, 0, 0, 1])
    handle_ee = np.array([0.48 + 0.05, -0.1, TABLE_Z + 0.08, 1, 0, 0, 0])
    ring = nut.keypoint("ring_center")
    seated = Pose(peg_pose.position + [-ring[0], -ring[1], -peg.half_extents[2] + 0.02], [0, 0, 0, 1])
    at_handle = np.array([0.48 + 0.05, -0.1, TABLE_Z + nut.half_extents[2], 1, 0, 0, 0])
    on_table = {"square_nut": resting, "square_peg": peg_pose}
    # grasped: commanded closed, fingers stopped on the nut; no lift needed (the skill data ends before it)
    assert skill_goal_reached(task, grasp, on_table, at_handle, 0.02, 1.0, None, 0.0)
    assert skill_goal_reached(task, grasp, {"square_nut": lifted, "square_peg": peg_pose}, handle_ee, 0.02, 1.0)
    assert not skill_goal_reached(task, grasp, on_table, at_handle, 0.03, 1.0, None, -0.004)  # still closing
    assert not skill_goal_reached(task, grasp, on_table, at_handle, 0.02, 1.0, None, np.inf)  # no earlier width
    assert not skill_goal_reached(task, grasp, on_table, at_handle, 0.02, 1.0, None, 0.0, CLOSE_PERIODS - 1)
    assert not skill_goal_reached(task, grasp, on_table, at_handle, 0.0, 1.0)  # shut on air
    assert not skill_goal_reached(task, grasp, on_table, at_handle, 0.02, -1.0)  # commanded open
    far_ee = np.array([0.48, -0.1 + 0.4, TABLE_Z + 0.08, 1, 0, 0, 0])
    assert not skill_goal_reached(task, grasp, on_table, far_ee, 0.02, 1.0)  # the nut is not at the hand
    poses = {"square_nut": seated, "square_peg": peg_pose}
    away = np.array([*(peg_pose.position + [0, 0, 0.2]), 1, 0, 0, 0])  # the hand let go and rose
    assert task.is_success(SceneState(poses, away[:3], -1.0))
    assert skill_goal_reached(task, place, poses, away, 0.08, -1.0)
    assert not skill_goal_reached(task, place, poses, away, 0.02, 1.0)  # still holding it
    ring_ee = np.array([*seated.position, 1, 0, 0, 0])  # open, but the hand still at the nut (robosuite r_reach)
    assert not skill_goal_reached(task, place, poses, ring_ee, 0.08, -1.0)
    assert not skill_goal_reached(task, place, {"square_nut": lifted, "square_peg": peg_pose}, away, 0.08, -1.0)


def test_tamp_without_ground_truth_is_perception_failed():
    res, _ = _run(mode="tamp")  # the fake world has no true_object_poses and no sim world
    assert res.reason is DeployReason.PERCEPTION_FAILED and "ground truth" in res.message
