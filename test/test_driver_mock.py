"""MockWorld (the mock driver's core): kinematic (joint_states and the EE pose agree), instant, same
validation as the sim."""
from __future__ import annotations

import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import ARM_JOINTS, Q_HOME
from skillgen_ros.core.sim import TrajectoryCode, TrajectoryError
from skillgen_ros.core.sim.camera import CameraConfig
from skillgen_ros.core.sim.mock import HOME_EE_POSE, MockWorld
from skillgen_ros.core.tasks import get_task


def test_mock_follows_targets_exactly_and_keeps_reset_poses():
    w = MockWorld(cameras=(CameraConfig("front", 32, 32),))
    scene = w.reset("Square", "D1", 11)
    expected = get_task("Square").sample_reset("D1", np.random.default_rng(11))
    assert all(np.array_equal(scene.poses[k].as_array(), expected[k].as_array()) for k in expected)
    assert np.allclose(w.ee_pose().as_array(), HOME_EE_POSE.as_array()) and not w.task_success()
    goal = Pose([0.5, 0.1, 0.2], [1.0, 0.0, 0.0, 0.0])
    w.step(goal, 1.0)
    assert np.allclose(w.ee_pose().position, goal.position, atol=1e-4) and w.gripper_width() == 0.0
    assert w.time == pytest.approx(0.05)
    assert all(np.array_equal(w.object_poses()[k].as_array(), expected[k].as_array()) for k in expected)
    pts = w.render("front").valid_points()
    nut = scene.poses["square_nut"]
    assert np.min(np.linalg.norm(pts - nut.position, axis=1)) < 0.03


def test_mock_trajectory_is_instant_and_validated():
    w = MockWorld()
    w.reset("PickPlace", "D0", 0)
    q1 = np.array(Q_HOME) + 0.1
    w.start_trajectory(ARM_JOINTS, [1.0], [q1])
    progress, _, done = w.step_trajectory()
    assert progress == 1.0 and done.code == TrajectoryCode.SUCCESSFUL and np.allclose(w.joint_positions(), q1)
    with pytest.raises(TrajectoryError) as e:
        w.start_trajectory(list(reversed(ARM_JOINTS))[:6], [1.0], [q1[:6]])
    assert e.value.code == TrajectoryCode.INVALID_JOINTS
    with pytest.raises(InvalidInputError):
        w.step(Pose([np.nan, 0, 0], [0, 0, 0, 1]), 0.0)
    with pytest.raises(InvalidInputError) as e:
        w.step(Pose([0.5, 0, 2.0], [0, 0, 0, 1]), 0.0)
    assert e.value.reason == "OUT_OF_WORKSPACE"
    assert np.allclose(w.joint_positions(), q1)


def test_mock_joint_states_agree_with_its_end_effector():
    """What skill_replay relies on: FK of the mock's joint_states is its EE pose, after OSC steps
    and after trajectories; a target out of the arm's reach leaves it where it was."""
    from skillgen_ros.core.planning.kinematics import PandaKinematics

    kin = PandaKinematics()
    w = MockWorld()
    w.reset("Square", "D0", 0)
    for target in (Pose([0.55, -0.12, 0.15], [1.0, 0.0, 0.0, 0.0]), Pose([0.40, 0.20, 0.30], [0.92388, 0.38268, 0, 0])):
        q0 = w.joint_positions()
        w.step(target, -1.0)
        assert np.abs(w.joint_positions() - q0).max() > 0.05  # the joints moved
        np.testing.assert_allclose(kin.fk(w.joint_positions()), w.ee_pose().matrix(), atol=1e-9)
        np.testing.assert_allclose(w.ee_pose().position, target.position, atol=1e-4)
    q1 = np.array(Q_HOME) + 0.1
    w.start_trajectory(ARM_JOINTS, [1.0], [q1])
    w.step_trajectory()
    np.testing.assert_allclose(w.ee_pose().matrix(), kin.fk(q1), atol=1e-9)
    far = Pose([0.9, 0.65, 0.9], [1.0, 0.0, 0.0, 0.0])  # in the workspace box, beyond the Panda's reach
    ee0 = w.ee_pose()
    w.step(far, -1.0)
    assert np.allclose(w.joint_positions(), q1) and np.allclose(w.ee_pose().as_array(), ee0.as_array())
