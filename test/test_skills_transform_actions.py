"""Object-frame transforms and MimicGen delta-pose actions against hand-computed cases."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.skills.actions import (ActionScale, add_action_noise, delta_action_to_pose, make_action,
                                              pose_to_delta_action)
from skillgen_ros.core.skills.transform import matrix_to_array, to_object_frame, to_world


def T(pos, rotvec=(0, 0, 0)):
    M = np.eye(4)
    M[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    M[:3, 3] = pos
    return M


def test_object_frame_hand_computed():
    # object at (1, 2, 0) rotated 90 deg about z; a world point 1 m further along world +y
    # lies 1 m along the object's +x axis.
    T_W_O = T([1, 2, 0], [0, 0, np.pi / 2])
    T_W_A = T([1, 3, 0.5], [0, 0, np.pi / 2])
    T_O_A = to_object_frame(T_W_O, T_W_A)
    np.testing.assert_allclose(T_O_A[:3, 3], [1, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(T_O_A[:3, :3], np.eye(3), atol=1e-12)
    # the same object-frame pose replayed at a new object pose moves with the object
    T_W_O2 = T([0, 0, 0], [0, 0, np.pi])
    np.testing.assert_allclose(to_world(T_W_O2, T_O_A)[:3, 3], [-1, 0, 0.5], atol=1e-12)


def test_round_trip_stack_1e9():
    rng = np.random.default_rng(0)
    T_W_O = T(rng.normal(size=3), rng.normal(size=3))
    stack = np.stack([T(rng.normal(size=3), rng.normal(size=3)) for _ in range(50)])
    back = to_world(T_W_O, to_object_frame(T_W_O, stack))
    assert np.abs(back - stack).max() < 1e-9
    # Pose and (7,) inputs are accepted too
    p = Pose.from_matrix(T_W_O)
    np.testing.assert_allclose(to_object_frame(p, stack), to_object_frame(p.as_array(), stack), atol=1e-12)
    np.testing.assert_allclose(matrix_to_array(stack)[:, :3], stack[:, :3, 3])
    with pytest.raises(InvalidInputError):
        to_world(np.zeros(5), stack)


def test_delta_action_hand_computed():
    cur = T([0.5, 0.0, 0.3], [np.pi, 0, 0])
    # 1 cm along +x and a 0.1 rad world-z rotation: a = (0.2, 0, 0, 0, 0, 0.2)
    target = T([0.51, 0.0, 0.3])
    target[:3, :3] = Rotation.from_rotvec([0, 0, 0.1]).as_matrix() @ cur[:3, :3]
    a = pose_to_delta_action(target, cur)
    np.testing.assert_allclose(a, [0.2, 0, 0, 0, 0, 0.2], atol=1e-12)
    np.testing.assert_allclose(delta_action_to_pose(a, cur), target, atol=1e-12)
    # beyond the bounds: clipped to [-1, 1] (10 cm = 2 x max_dpos)
    far = T([0.4, 0.0, 0.3], [np.pi, 0, 0])
    np.testing.assert_allclose(pose_to_delta_action(far, cur), [-1, 0, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pose_to_delta_action(far, cur, clip=False)[0], -2.0)
    # other scales
    np.testing.assert_allclose(pose_to_delta_action(target, cur, ActionScale(0.01, 0.1))[[0, 5]], [1.0, 1.0])


def test_delta_round_trip_random():
    rng = np.random.default_rng(1)
    for _ in range(100):
        cur = T(rng.normal(size=3), rng.normal(size=3))
        a = rng.uniform(-1, 1, 6)
        np.testing.assert_allclose(pose_to_delta_action(delta_action_to_pose(a, cur), cur), a, atol=1e-9)


def test_noise_only_on_pose_dims():
    rng = np.random.default_rng(2)
    a = np.tile([0.1, -0.2, 0.3, 0.0, 0.5, -0.5, 0.7], (1000, 1))
    noisy = add_action_noise(a, 0.05, rng)
    assert np.all(noisy[:, 6] == 0.7)
    d = noisy[:, :6] - a[:, :6]
    assert 0.045 < d.std() < 0.055 and abs(d.mean()) < 0.01
    assert np.all(a[:, 0] == 0.1)  # input untouched
    assert np.abs(add_action_noise(np.full(7, 0.99), 5.0, rng)[:6]).max() <= 1.0  # clipped
    np.testing.assert_array_equal(add_action_noise(a[0], 0.0, rng), a[0])
    with pytest.raises(InvalidInputError):
        add_action_noise(a[0], -1.0, rng)


def test_make_action_consistent_with_command():
    rng = np.random.default_rng(3)
    cur = T([0.5, 0.1, 0.2], [np.pi, 0, 0])
    target = T([0.52, 0.1, 0.19], [np.pi, 0, 0.1])
    a, commanded = make_action(target, cur, 1.0, 0.05, rng)
    assert a.shape == (7,) and a[6] == 1.0
    np.testing.assert_allclose(pose_to_delta_action(commanded, cur), a[:6], atol=1e-9)
    a0, c0 = make_action(target, cur, -1.0, 0.0, None)
    np.testing.assert_allclose(c0, target, atol=1e-9)
