"""Initiation candidates: symmetric object frames, grasp-compatible source demos, and the attempt's
fallback to them when a skill's initiation pose is unreachable (GOAL_IN_COLLISION / IK_FAILED)."""
from dataclasses import dataclass, replace

import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos
from scipy.spatial.transform import Rotation

from skillgen_ros.core.generation.attempt import FailureReason, GenerationConfig, run_attempt
from skillgen_ros.core.generation.initiation import (grasp_in_demo, initiation_candidates, same_grasp,
                                                     symmetry_frames)
from skillgen_ros.core.generation.release import ReleaseConfig

CFG = GenerationConfig(variant="D1")


@dataclass(frozen=True)
class SymObject:
    id: str
    symmetry: str


@pytest.fixture(scope="module")
def demos():
    return make_source_demos(3)


def _yaw(T):
    return Rotation.from_matrix(T[:3, :3]).as_euler("xyz")[2]


def test_symmetry_frames_turn_about_the_object_z():
    T = np.eye(4)
    T[:3, 3] = [0.5, 0.1, 0.05]
    frames = symmetry_frames(T, "z4")
    assert len(frames) == 3 and symmetry_frames(T, "none") == [] and len(symmetry_frames(T, "z_continuous")) == 7
    np.testing.assert_allclose([abs(_yaw(F)) for F in frames], [np.pi / 2, np.pi, np.pi / 2], atol=1e-9)
    for F in frames:  # same origin and z axis: the same physical object
        np.testing.assert_allclose(F[:3, 3], T[:3, 3])
        np.testing.assert_allclose(F[:3, 2], T[:3, 2], atol=1e-12)


def test_candidates_order_and_grasp_compatibility(demos):
    T = np.eye(4)
    task = FakeTask(objects=(SymObject("cube", "none"), SymObject("plate", "z4")))
    place = task.skills[1]
    got = list(initiation_candidates(demos, task, place, 1, T, np.random.default_rng(0), limit=20))
    # the selected demo in the estimated frame first, then its symmetric frames, then the other demos
    assert got[0][0] == 1 and np.allclose(got[0][1], T)
    assert [j for j, _ in got[:4]] == [1, 1, 1, 1] and sorted({j for j, _ in got[4:]}) == [0, 2]
    assert len(got) == 12
    assert len(list(initiation_candidates(demos, task, place, 1, T, np.random.default_rng(0), limit=5))) == 5
    # the scripted demos grasp the cube the same way; a demo holding it turned 90 deg is not offered
    g = grasp_in_demo(demos[0], 1, "cube")
    assert g is not None and same_grasp(g, grasp_in_demo(demos[2], 1, "cube"))
    turned = np.eye(4)
    turned[:3, :3] = Rotation.from_euler("z", np.pi / 2).as_matrix()
    assert not same_grasp(g, g @ turned) and grasp_in_demo(demos[0], 0, "cube") is None
    skill0 = demos[2].skills[0]
    odd = replace(demos[2], skills=(replace(skill0, ee_poses_in_object=skill0.ee_poses_in_object @ turned),)
                  + tuple(demos[2].skills[1:]))
    got = list(initiation_candidates([demos[0], demos[1], odd], task, place, 1, T, np.random.default_rng(0), 20))
    assert {j for j, _ in got} == {0, 1}


class GoalBlockedOnce(FakeWorld):
    """The first transfer target is in collision (nothing moves); any other one is fine."""

    def __init__(self, status="GOAL_IN_COLLISION", **kw):
        super().__init__(**kw)
        self.blocked, self.status, self.targets = True, status, []

    def plan_and_execute(self, target, mode, attached):
        self.targets.append(target.matrix())
        if mode == "transfer" and self.blocked:
            self.blocked = False
            self.calls.append(f"plan:{mode}:{attached}")
            return self.status, []
        return super().plan_and_execute(target, mode, attached)


def test_attempt_falls_back_to_another_source_demo(demos):
    env = GoalBlockedOnce()
    r = run_attempt(env, demos, FakeTask(), "skillgen", 0, 5, CFG)
    assert r.success, r.message
    assert env.calls.count("plan:transfer:cube") == 2
    assert r.source_demos[0] != r.source_demos[1]  # no symmetric frames here: the next candidate is another demo
    lab = r.episode.labels
    place = lab["skill_index"] == 1
    assert (lab["source_demo"][place] == r.source_demos[1]).all()
    assert not np.allclose(env.targets[1], env.targets[2])  # a different initiation pose was tried
    # the paper's behaviour (one candidate) fails the attempt on the first unreachable pose
    r1 = run_attempt(GoalBlockedOnce(), demos, FakeTask(), "skillgen", 0, 5, replace(CFG, initiation_candidates=1))
    assert r1.reason is FailureReason.PLAN_FAILED
    # an IK failure is retried too; a planner timeout (the goal was fine) is not
    assert run_attempt(GoalBlockedOnce("IK_FAILED"), demos, FakeTask(), "skillgen", 0, 5, CFG).success
    r2 = run_attempt(GoalBlockedOnce("PLAN_TIMEOUT"), demos, FakeTask(), "skillgen", 0, 5, CFG)
    assert r2.reason is FailureReason.PLAN_FAILED


def test_fallback_is_deterministic(demos):
    a = run_attempt(GoalBlockedOnce(), demos, FakeTask(), "skillgen", 3, 9, CFG)
    b = run_attempt(GoalBlockedOnce(), demos, FakeTask(), "skillgen", 3, 9, CFG)
    assert a.source_demos == b.source_demos
    np.testing.assert_array_equal(a.episode.actions, b.episode.actions)


def test_config_rejects_zero_candidates():
    from skillgen_ros.core.errors import InvalidInputError

    with pytest.raises(InvalidInputError):
        GenerationConfig(initiation_candidates=0)


class SlowFingers(FakeWorld):
    """The hand starts half closed and opens 1 cm per control period (as after a release)."""

    def reset(self, task, variant, seed):
        out = super().reset(task, variant, seed)
        self.width = 0.03
        return out

    def observe(self):
        obs = super().observe()
        if self.grip < 0:
            obs = replace(obs, gripper=np.full(2, self.width / 2))
        return obs

    def step(self, target, gripper):
        if gripper < 0:
            self.width = min(0.08, self.width + 0.01)
        return super().step(target, gripper)


def test_planned_motion_waits_for_an_opening_gripper(demos):
    r = run_attempt(SlowFingers(), demos, FakeTask(), "skillgen", 0, 5, CFG)
    assert r.success, r.message
    lab = r.episode.labels
    held = np.flatnonzero(lab["mp_step"].astype(bool))[:5]  # 0.03 -> 0.08 m: five hold periods first
    np.testing.assert_allclose(r.episode.obs["robot0_eef_pos"][held], r.episode.obs["robot0_eef_pos"][held[:1]].repeat(5, 0))
    assert (r.episode.actions[held, :6] == 0).all() and (r.episode.actions[held, 6] == -1).all()
    assert r.episode.num_samples == run_attempt(FakeWorld(), demos, FakeTask(), "skillgen", 0, 5, CFG).episode.num_samples + 5
    none = run_attempt(SlowFingers(), demos, FakeTask(), "skillgen", 0, 5, replace(CFG, release=ReleaseConfig(settle_steps=0)))
    assert none.episode.num_samples == r.episode.num_samples - 5


class WedgedFingers(SlowFingers):
    """Open-commanded fingers stuck at 3 cm (as if wedged on an object just released) until the hand
    has slid 8 mm along its -y axis from where the opening began."""

    def reset(self, task, variant, seed):
        out = super().reset(task, variant, seed)
        self.released_at = None
        return out

    def step(self, target, gripper):
        T = target.matrix()
        if gripper < 0 and self.released_at is None:
            self.released_at = T
        free = self.released_at is not None and (self.released_at[:3, 3] - T[:3, 3]) @ self.released_at[:3, 1] >= 0.008
        if gripper < 0 and (free or self.width > 0.031):
            self.width = min(0.08, self.width + 0.02)
        return FakeWorld.step(self, target, gripper)


def test_wedged_fingers_are_freed_before_the_planned_motion(demos):
    r = run_attempt(WedgedFingers(), demos, FakeTask(), "skillgen", 0, 5, CFG)
    assert r.success, r.message
    pos, act = r.episode.obs["robot0_eef_pos"], r.episode.actions
    assert r.episode.labels["mp_step"][:8].all()
    # a hold finds the stall; one 8 mm slide along the hand's -y (world +y for a top-down hand)
    # frees the fingers; held there while they open, then four periods back where it let go
    np.testing.assert_allclose(pos[2] - pos[1], [0, 0.008, 0], atol=1e-12)
    np.testing.assert_allclose(pos[2:5], pos[[2, 2, 2]])
    np.testing.assert_allclose(pos[5:9], pos[[0, 0, 0, 0]])
    assert (act[:8, 6] == -1).all() and (act[:8, 3:6] == 0).all()
    off = run_attempt(WedgedFingers(), demos, FakeTask(), "skillgen", 0, 5, replace(CFG, release=ReleaseConfig().without_moves()))
    assert off.episode.num_samples == r.episode.num_samples - 7  # only the stall-finding hold
