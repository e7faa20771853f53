"""The pure pieces of HSP learning: termination labels, the 5-consecutive rule, 6D rotations,
[-1, 1] normalization, sequence windows and the initiation samples."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.learning.data import DemoArrays, TrainingSet, initiation_indices
from skillgen_ros.core.learning.normalization import MinMax, ObsStats
from skillgen_ros.core.learning.rotation import (pos_rot6d_to_pose, pose_to_pos_rot6d, quat_to_rotation_6d,
                                                 rotation_6d_to_matrix, rotation_6d_to_quat)
from skillgen_ros.core.learning.termination import (SETTLED_GRIPPER_M, SETTLED_POS_M, TerminationFilter,
                                                    settled_tail, termination_labels)


def test_termination_labels_flip_the_last_half_of_each_motion_segment():
    # motion 6 | skill 3 | motion 5 | skill 2 | motion 1 | skill 1
    mp = np.array([1, 1, 1, 1, 1, 1, 0, 0, 0, 1, 1, 1, 1, 1, 0, 0, 1, 0], np.uint8)
    expected = [1, 1, 1, 0, 0, 0,  # L=6: first 3 terminate, last 3 running
                0, 0, 0,
                1, 1, 1, 0, 0,  # L=5: first ceil(5/2)=3 terminate, last 2 running
                0, 0,
                1,  # L=1: nothing flips
                0]
    np.testing.assert_array_equal(termination_labels(mp), expected)
    np.testing.assert_array_equal(termination_labels(np.zeros(4)), [0, 0, 0, 0])
    np.testing.assert_array_equal(termination_labels(np.ones(4)), [1, 1, 0, 0])
    with pytest.raises(InvalidInputError):
        termination_labels(np.zeros((2, 2)))


def _grasp_then_lift():
    """skill 6 (approach 2, close 1, hold 3) | motion 4 (lift) | skill 3 (the last: never settled)."""
    mp = np.array([0] * 6 + [1] * 4 + [0] * 3, np.uint8)
    z = np.array([0.10, 0.05, 0.0, 0.001, 0.0, 0.001, 0.0, 0.01, 0.03, 0.06, 0.06, 0.06, 0.06])
    pos = np.stack([np.zeros(13), np.zeros(13), z], 1)
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (13, 1))
    fingers = np.array([0.04, 0.04, 0.03, 0.02, 0.0205, 0.02] + [0.02] * 7)
    return mp, pos, quat, np.stack([fingers, fingers], 1)


def test_settled_labels_also_call_the_still_end_of_a_skill_terminate():
    mp, pos, quat, grip = _grasp_then_lift()
    tail = settled_tail(mp, pos, quat, grip)
    # the hold (steps 3-5: within the tolerances of step 5) and nothing else; the closing step 2 is 1 cm and
    # 10 mm of finger travel away; the last skill is followed by no motion
    np.testing.assert_array_equal(np.flatnonzero(tail), [3, 4, 5])
    np.testing.assert_array_equal(termination_labels(mp, tail), [0, 0, 0, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(termination_labels(mp), [0] * 6 + [1, 1, 0, 0, 0, 0, 0])  # the paper's rule
    # each tolerance breaks the tail on its own: a turn of 10 deg, 2 mm of finger travel, a 1 cm move
    turned = quat.copy()
    turned[3] = Rotation.from_euler("z", 10, degrees=True).as_quat()
    assert np.flatnonzero(settled_tail(mp, pos, turned, grip)).tolist() == [4, 5]
    moved = grip.copy()
    moved[4] += 2 * SETTLED_GRIPPER_M
    assert np.flatnonzero(settled_tail(mp, pos, quat, moved)).tolist() == [5]
    far = pos.copy()
    far[4, 0] += 2 * SETTLED_POS_M
    assert np.flatnonzero(settled_tail(mp, far, quat, grip)).tolist() == [5]
    with pytest.raises(InvalidInputError):
        termination_labels(mp, tail[:-1])


def test_termination_needs_five_consecutive_positives():
    f = TerminationFilter()
    seq = [1, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1]
    assert [f.update(bool(x)) for x in seq] == [False] * 9 + [True, True]
    f.reset()
    assert [f.update(True) for _ in range(5)] == [False] * 4 + [True]
    with pytest.raises(InvalidInputError):
        TerminationFilter(0)


def test_rotation_6d_round_trip():
    R = Rotation.random(200, random_state=3)
    q = R.as_quat()
    q6 = quat_to_rotation_6d(q)
    assert q6.shape == (200, 6)
    back = Rotation.from_quat(rotation_6d_to_quat(q6))
    assert np.max((back.inv() * R).magnitude()) < 1e-9
    np.testing.assert_allclose(rotation_6d_to_matrix(q6), R.as_matrix(), atol=1e-12)
    # any 6 numbers (not parallel) give a proper rotation: Gram-Schmidt
    m = rotation_6d_to_matrix(np.random.default_rng(0).normal(size=(50, 6)))
    np.testing.assert_allclose(m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-12)
    pose = np.c_[np.random.default_rng(1).normal(size=(5, 3)), q[:5]]
    out = pos_rot6d_to_pose(pose_to_pos_rot6d(pose))
    np.testing.assert_allclose(out[:, :3], pose[:, :3])
    np.testing.assert_allclose(np.abs(np.sum(out[:, 3:] * pose[:, 3:], 1)), 1.0, atol=1e-12)  # q ~ -q
    with pytest.raises(InvalidInputError):
        rotation_6d_to_matrix(np.array([0, 0, 0, 1, 0, 0.0]))


def test_minmax_maps_onto_minus_one_one_and_back():
    x = np.random.default_rng(2).normal(size=(100, 9)) * [1, 2, 3, 4, 5, 6, 7, 8, 0] + 3
    mm = MinMax.fit(x)
    y = mm.normalize(x)
    np.testing.assert_allclose(y[:, :8].min(0), -1, atol=1e-12)
    np.testing.assert_allclose(y[:, :8].max(0), 1, atol=1e-12)
    np.testing.assert_allclose(y[:, 8], -1)  # a constant dimension maps to -1 (Diffusion Policy)
    np.testing.assert_allclose(mm.unnormalize(y), x, atol=1e-12)
    again = MinMax.from_json(mm.to_json())
    np.testing.assert_allclose(again.unnormalize(again.normalize(x)), x, atol=1e-12)


def _demo(mp):
    n = len(mp)
    return DemoArrays({"a": np.arange(n, dtype=float)[:, None]}, np.arange(n, dtype=np.float32)[:, None].repeat(7, 1),
                      np.array(mp, np.uint8), np.full(n, 4), np.tile([0.1, 0.2, 0.3, 0, 0, 0, 1.0], (n, 1)))


def test_windows_stay_inside_skill_segments_and_pad_at_the_end():
    d = _demo([1, 1, 0, 0, 0, 1, 1, 1, 1, 0, 0])
    stats = ObsStats.fit({"a": d.obs["a"]})
    ts = TrainingSet([d], ["a"], [], stats, 4, False, 5, None)
    w = ts.windows(np.arange(len(ts.win_start)))
    np.testing.assert_array_equal(w, [[2, 3, 4, 4], [3, 4, 4, 4], [4, 4, 4, 4], [9, 10, 10, 10], [10, 10, 10, 10]])
    all_steps = TrainingSet([d], ["a"], [], stats, 4, True, 5, None)
    assert len(all_steps.win_start) == 11 and list(all_steps.windows(np.array([9]))[0]) == [9, 10, 10, 10]
    # initiation samples: the first min(window, ceil(L/2)) steps of each motion segment
    assert initiation_indices(d.mp_step, 5) == [(0, 0), (5, 5), (6, 5)]
    np.testing.assert_array_equal(ts.init_idx, [0, 5, 6])
    np.testing.assert_array_equal(ts.init_cls, [4, 4, 4])
    np.testing.assert_allclose(ts.obs["a"][:, 0], (np.arange(11) - 5) / (d.obs["a"].std() + 1e-3), rtol=1e-6)


def test_reg_target_is_the_initiation_before_augmentation_s_perturbation():
    """HSP-Reg's nominal target: where the recovery segment of an augmented skill ends (the EE pose at
    the skill's first non-augmented step); the stored, perturbed label on request or without recovery."""
    from skillgen_ros.core.errors import ParameterError
    from skillgen_ros.core.learning.data import reg_target

    mp = np.array([1, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0], np.uint8)
    aug = np.array([0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0], np.uint8)  # skill 0 starts with 2 recovery steps
    n = len(mp)
    pos = np.arange(n, dtype=float)[:, None] * [1.0, 0.0, 0.0]
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    label = np.tile([9.0, 9.0, 9.0, 0, 0, 0, 1.0], (n, 1))
    d = DemoArrays({"robot0_eef_pos": pos, "robot0_eef_quat": quat}, np.zeros((n, 7), np.float32), mp,
                   np.zeros(n, int), label, aug)
    np.testing.assert_allclose(reg_target(d, 0), [5.0, 0, 0, 0, 0, 0, 1])  # step 5: the recovery's end
    np.testing.assert_allclose(reg_target(d, 0, "initiation_target"), label[0])
    np.testing.assert_allclose(reg_target(d, 7), label[7])  # skill 1 was not augmented: the label is nominal
    no_labels = DemoArrays(d.obs, d.actions, mp, d.source_demo, label, None)  # a dataset without labels/augmented
    np.testing.assert_allclose(reg_target(no_labels, 0), label[0])
    with pytest.raises(ParameterError):
        reg_target(d, 0, "perturbed")
    stats = ObsStats.fit({k: v for k, v in d.obs.items()})
    ts = TrainingSet([d], ["robot0_eef_pos", "robot0_eef_quat"], [], stats, 4, False, 5, None)
    np.testing.assert_allclose(ts.init_tgt[0, :3], [5.0, 0, 0])  # unnormalized here (no MinMax)


def test_the_training_set_uses_the_chosen_termination_rule():
    from skillgen_ros.core.errors import ParameterError
    from skillgen_ros.core.learning.config import TrainConfig
    from skillgen_ros.core.learning.data import DatasetReadError

    mp, pos, quat, grip = _grasp_then_lift()
    n = len(mp)
    obs = {"robot0_eef_pos": pos, "robot0_eef_quat": quat, "robot0_gripper_qpos": grip}
    d = DemoArrays(obs, np.zeros((n, 7), np.float32), mp, np.zeros(n, int), np.tile([0.0] * 6 + [1.0], (n, 1)), None)
    stats = ObsStats.fit(obs)

    def labels(rule, keys=tuple(obs)):
        return TrainingSet([d], list(keys), [], stats, 4, False, 5, None, term_rule=rule).term

    np.testing.assert_array_equal(labels("paper"), termination_labels(mp))
    np.testing.assert_array_equal(labels("settled"), termination_labels(mp, settled_tail(mp, pos, quat, grip)))
    with pytest.raises(DatasetReadError, match="robot0_gripper_qpos"):
        TrainingSet([DemoArrays({k: v for k, v in obs.items() if k != "robot0_gripper_qpos"}, d.actions, mp,
                                d.source_demo, d.initiation_target, None)],
                    ["robot0_eef_pos"], [], stats, 4, False, 5, None, term_rule="settled")
    with pytest.raises(ParameterError, match="termination_labels"):
        TrainConfig(termination_labels="late")
