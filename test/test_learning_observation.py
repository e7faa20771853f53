"""policy_obs gives a policy exactly the row the dataset stores for the same Observation."""
import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.generation.episode import EpisodeRecorder, Observation, StepLabel
from skillgen_ros.core.learning.observation import check_obs, policy_obs


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
    for t, o in enumerate(obs):
        row = policy_obs(o)
        assert row.keys() == ep.obs.keys()
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
