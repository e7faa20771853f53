"""policy_obs gives a policy exactly the row the dataset stores for the same Observation."""
import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.generation.episode import EpisodeRecorder, Observation, StepLabel
from skillgen_ros.core.geometry import poses_in_frame
from skillgen_ros.core.learning.observation import DERIVED_KEYS, add_derived, check_obs, object_to_eef, policy_obs


def _obs(rng, images=True):
    q = rng.normal(size=4)
    return Observation(ee_pose=np.r_[rng.normal(size=3), q / np.linalg.norm(q)], gripper=rng.uniform(0, 0.04, 2),
                       joint_positions=rng.normal(size=7),
                       object_poses={"square_peg": np.r_[rng.normal(size=3), 0, 0, 0, 1],
                                     "square_nut": np.r_[rng.normal(size=3), 0, 0, 1, 0]},
                       images={"wrist": rng.integers(0, 255, (84, 84, 3), dtype=np.uint8),
                               "front": rng.integers(0, 255, (84, 84, 3), dtype=np.uint8)} if images else {})


@pytest.mark.parametrize("images", [True, False])
def test_policy_obs_equals_the_recorded_row(images):
    rng = np.random.default_rng(0)
    obs = [_obs(rng, images) for _ in range(4)]
    # policy_obs feeds the robot's belief (object_poses): the row an observation_source "estimate"
    # dataset records; a "ground_truth" dataset records the sim's true poses (docs/hsp.md)
    rec = EpisodeRecorder("estimate")
    for o in obs:
        pose = np.r_[0, 0, 0, 0, 0, 0, 1.0]
        rec.add(o, np.zeros(7), pose, -1.0, StepLabel(False, 0, 0, pose))
    ep = rec.episode(True)
    stored = add_derived(dict(ep.obs))  # what the training reader (data.read_demos) gives the networks
    for t, o in enumerate(obs):
        row = policy_obs(o)
        assert row.keys() - set(DERIVED_KEYS) == ep.obs.keys()
        assert row.keys() == stored.keys()
        for k in DERIVED_KEYS:
            np.testing.assert_allclose(row[k], stored[k][t], atol=1e-12, err_msg=k)
            row.pop(k)
        for k in row:
            assert row[k].dtype == ep.obs[k].dtype, k
            np.testing.assert_array_equal(row[k], ep.obs[k][t], err_msg=k)


def test_check_obs_names_the_bad_key():
    o = policy_obs(_obs(np.random.default_rng(1), images=False))
    shapes = {k: v.shape for k, v in o.items()}
    check_obs(o, shapes)
    with pytest.raises(InvalidInputError, match="lacks 'object'"):
        check_obs({k: v for k, v in o.items() if k != "object"}, shapes)
    with pytest.raises(InvalidInputError, match="shape"):
        check_obs({**o, "object": np.zeros(7)}, shapes)
    with pytest.raises(InvalidInputError, match="not finite"):
        check_obs({**o, "robot0_eef_pos": np.array([np.nan, 0, 0])}, shapes)


def test_object_to_eef_is_each_object_s_pose_in_the_hand_frame():
    s = np.sqrt(0.5)
    ee_pos, ee_quat = np.array([[1.0, 0, 0]]), np.array([[0, 0, s, s]])  # hand yawed +90 deg about z
    objects = np.array([[1.0, 1, 0, 0, 0, 0, 1,  # 1 m along world y = along the hand's x
                         1.0, 0, 0, 0, 0, s, s]])  # at the hand, with the hand's orientation
    rel = object_to_eef(ee_pos, ee_quat, objects)
    np.testing.assert_allclose(rel[0, :3], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rel[0, 3:7], [0, 0, -s, s], atol=1e-12)  # world yaw 0 is -90 in the hand
    np.testing.assert_allclose(rel[0, 7:], [0, 0, 0, 0, 0, 0, 1], atol=1e-12)


def test_poses_in_frame_round_trips_keeps_qw_positive_and_nan_rows():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(50, 4))
    frames = np.c_[rng.normal(size=(50, 3)), q / np.linalg.norm(q, axis=1, keepdims=True)]
    q = rng.normal(size=(50, 4))
    poses = np.c_[rng.normal(size=(50, 3)), q / np.linalg.norm(q, axis=1, keepdims=True)]
    rel = poses_in_frame(frames, poses)
    assert np.all(rel[:, 6] >= 0)
    from scipy.spatial.transform import Rotation as R
    back = R.from_quat(frames[:, 3:]) * R.from_quat(rel[:, 3:])
    np.testing.assert_allclose(R.from_quat(frames[:, 3:]).apply(rel[:, :3]) + frames[:, :3], poses[:, :3], atol=1e-9)
    assert np.all((back.inv() * R.from_quat(poses[:, 3:])).magnitude() < 1e-9)
    poses[3, 0] = np.nan
    rel = poses_in_frame(frames, poses)
    assert np.isnan(rel[3]).all() and np.isfinite(np.delete(rel, 3, axis=0)).all()
