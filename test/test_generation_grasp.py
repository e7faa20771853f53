"""The grasped object: rigid-attachment tracking and the transfer skills' in-hand correction."""
import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos
from scipy.spatial.transform import Rotation

from skillgen_ros.core.generation.attempt import GenerationConfig, run_attempt
from skillgen_ros.core.generation.grasp import (MAX_CORRECTION_M, GraspTracker, demo_object_in_hand, grasp_step,
                                                in_hand_correction, object_in_hand)
from skillgen_ros.core.skills.replay import plan_replay

TASK = FakeTask()
QUIET = GenerationConfig(variant="D1", action_noise=0.0)


def _T(xyz=(0.0, 0.0, 0.0), rotvec=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


MISS = _T([0.008, -0.004, 0.0], [0.0, 0.0, 0.12])  # where the open hand lands, in the frame it was sent to


class MissingWorld(FakeWorld):
    """The fake world whose open hand lands MISS off every commanded pose (as action noise would
    leave it), so it closes on the cube -- which stays put -- off the demo's grasp."""

    def _move(self, T):
        super()._move(np.asarray(T, float) @ MISS if self.grip <= 0 else T)


@pytest.fixture(scope="module")
def demos():
    return make_source_demos(3)


def test_grasp_tracker_keeps_the_object_rigid_in_the_hand():
    tracker = GraspTracker()
    T_W_O, T_W_E = _T([0.5, 0.1, 0.02], [0, 0, 0.3]), _T([0.5, 0.1, 0.05], [np.pi, 0, 0])
    tracker.grasped("cube", T_W_O, T_W_E)
    assert tracker.holding() == "cube"
    moved = _T([0.3, -0.2, 0.3]) @ T_W_E
    np.testing.assert_allclose(tracker.pose_now("cube", moved).matrix(), _T([0.3, -0.2, 0.3]) @ T_W_O, atol=1e-12)
    tracker.released()
    assert tracker.holding() is None and tracker.pose_now("cube", moved) is None
    assert grasp_step([-1, -1, 1, 1]) == 2 and grasp_step([1, 1]) == 0
    assert grasp_step([-1, 1, -1]) is None and grasp_step([]) is None


def test_the_correction_puts_the_held_object_where_the_demo_had_it():
    """T_W^A C T_E^H_now = T_W^A T_E^H_demo for any target; beyond the limits it is the identity."""
    demo_in_hand, now = _T([0.0, 0.0, 0.004], [np.pi, 0, 0]), _T([0.006, 0.003, 0.004], [np.pi, 0.05, 0.1])
    C = in_hand_correction(demo_in_hand, now)
    for target in (_T([0.5, 0.2, 0.1], [np.pi, 0, 0.4]), _T([0.3, -0.1, 0.4], [2.5, 0.3, -1.0])):
        np.testing.assert_allclose(target @ C @ now, target @ demo_in_hand, atol=1e-12)
    far = _T([MAX_CORRECTION_M + 0.005, 0, 0.004], [np.pi, 0, 0])
    np.testing.assert_array_equal(in_hand_correction(demo_in_hand, far), np.eye(4))
    np.testing.assert_array_equal(in_hand_correction(demo_in_hand, demo_in_hand @ _T(rotvec=[0, 0, 0.5])), np.eye(4))
    assert not np.allclose(in_hand_correction(demo_in_hand, demo_in_hand @ _T(rotvec=[0, 0, 0.3])), np.eye(4))
    np.testing.assert_array_equal(in_hand_correction(None, now), np.eye(4))
    np.testing.assert_array_equal(in_hand_correction(demo_in_hand, None), np.eye(4))


def test_the_demos_object_in_hand_comes_from_its_grasp_skill(demos):
    d = demos[0]
    grasp = d.skill(0)
    k = grasp_step(grasp.gripper)
    T = demo_object_in_hand(d, TASK, 1)
    np.testing.assert_allclose(T, np.linalg.inv(grasp.ee_poses_in_object[k]), atol=1e-12)
    # the scripted demo grasps the cube at its centre, gripper pointing down
    np.testing.assert_allclose(T[:3, 3], 0.0, atol=1e-9)
    assert demo_object_in_hand(d, TASK, 0) is None  # a transit skill carries nothing


def test_plan_replay_applies_the_correction_to_targets_and_initiation(demos):
    seg, T_W_O, C = demos[0].skill(1), _T([0.5, 0.15, 0.0], [0, 0, 0.2]), _T([0.01, 0, 0], [0, 0, 0.1])
    plain, corrected = plan_replay(seg, T_W_O), plan_replay(seg, T_W_O, correction=C)
    np.testing.assert_allclose(corrected.targets, plain.targets @ C, atol=1e-12)
    np.testing.assert_allclose(corrected.initiation, plain.initiation @ C, atol=1e-12)
    np.testing.assert_array_equal(corrected.gripper, plain.gripper)


def _placement_error(world) -> float:
    """How far the cube's centre ended from the plate's (the scripted demos place it dead centre)."""
    cube, plate = world.objects["cube"], world.objects["plate"]
    return float(np.linalg.norm(cube[:2, 3] - plate[:2, 3]))


def test_a_cube_grasped_off_the_demos_grasp_is_still_placed_where_the_demo_placed_it(demos):
    """With the correction the transfer skill carries the cube, not the hand, along the demo; the
    paper's replay (and MimicGen's) puts it off by the miss."""
    errors = {}
    for name, method, cfg in (("corrected", "skillgen", QUIET),
                              ("paper", "skillgen", GenerationConfig(variant="D1", action_noise=0.0,
                                                                     in_hand_correction=False)),
                              ("mimicgen", "mimicgen", QUIET)):
        world = MissingWorld()
        r = run_attempt(world, demos, TASK, method, 2, 7, cfg)
        assert world.attached is None and r.episode.num_samples > 0, r.message
        errors[name] = _placement_error(world)
    miss = float(np.linalg.norm(MISS[:2, 3]))
    assert errors["corrected"] < 1e-6
    assert errors["paper"] > 0.5 * miss and errors["mimicgen"] > 0.5 * miss


def test_the_attempts_object_in_hand_is_measured_like_the_demos(demos):
    """Both sides take the object's pose before the grasp skill in the hand's frame at the close
    command, so a perfect replay (no noise, exact tracking) needs no correction at all."""
    d = demos[0]
    grasp = d.skill(0)
    k = grasp_step(grasp.gripper)
    T_W_O = _T([0.45, -0.1, 0.02], [0, 0, 0.4])
    T_W_E_close = T_W_O @ grasp.ee_poses_in_object[k]
    np.testing.assert_allclose(in_hand_correction(demo_object_in_hand(d, TASK, 1), object_in_hand(T_W_E_close, T_W_O)),
                               np.eye(4), atol=1e-12)
