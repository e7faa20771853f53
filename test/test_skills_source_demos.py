"""Source-demo loader: segments in object frames, bad input errors, initiation augmentation."""
import dataclasses

import numpy as np
import pytest
from _generation_fakes import FakeTask, annotate, scripted_demo
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import AnnotationError, InvalidInputError
from skillgen_ros.core.geometry import pose_arrays_to_matrices
from skillgen_ros.core.skills.augmentation import (AugmentationConfig, interpolate_poses, perturb_initiation,
                                                   recovery_segment)
from skillgen_ros.core.skills.source_demos import sample_and_hold, source_demo_from_arrays

TASK = FakeTask()


@pytest.fixture(scope="module")
def arrays():
    return scripted_demo(100)


def test_segments_round_trip_to_recorded_world_poses(arrays):
    demo = source_demo_from_arrays(arrays, annotate(arrays), TASK)
    ee = pose_arrays_to_matrices(arrays.ee_positions, arrays.ee_quaternions)
    act = pose_arrays_to_matrices(arrays.action_positions, arrays.action_quaternions)
    assert [s.name for s in demo.skills] == ["pick", "place"] and demo.skills[1].mode == "transfer"
    for seg in demo.skills:
        span = slice(seg.start_step, seg.end_step)
        assert np.abs(seg.actions_in_world(seg.object_pose) - act[span]).max() < 1e-9
        np.testing.assert_allclose(seg.initiation_in_world(seg.object_pose), ee[seg.start_step], atol=1e-9)
        np.testing.assert_allclose(seg.object_pose @ seg.termination, ee[seg.end_step - 1], atol=1e-9)
        np.testing.assert_array_equal(seg.gripper, arrays.gripper[span])
        assert seg.actions_in_object.flags.writeable is False
    # pick initiation relative to the cube: about 5 cm above it, pointing down
    assert 0.0 < demo.skills[0].initiation[2, 3] < 0.07
    assert demo.scene_seed == 100 and demo.num_steps == len(arrays.timestamps)


def test_without_action_arrays_next_pose_stands_in(arrays):
    a = dataclasses.replace(arrays, action_positions=None, action_quaternions=None)
    demo = source_demo_from_arrays(a, annotate(a), TASK)
    ee = pose_arrays_to_matrices(arrays.ee_positions, arrays.ee_quaternions)
    np.testing.assert_allclose(demo.action_poses[:-1], ee[1:], atol=1e-12)


@pytest.mark.parametrize("field,reason", [("ee_positions", "NAN_POSE"), ("object_positions", "NAN_POSE"),
                                          ("ee_quaternions", "NAN_POSE")])
def test_nan_poses_name_file_and_demo(arrays, field, reason):
    if field == "object_positions":
        cube = arrays.object_positions["cube"].copy()
        cube[7, 1] = np.nan
        bad = dataclasses.replace(arrays, object_positions={**arrays.object_positions, "cube": cube})
    else:
        v = getattr(arrays, field).copy()
        v[7, 0] = np.nan
        bad = dataclasses.replace(arrays, **{field: v})
    with pytest.raises(InvalidInputError) as e:
        source_demo_from_arrays(bad, annotate(arrays), TASK)
    assert e.value.reason == reason
    assert "fake.mcap" in str(e.value) and "demo_0" in str(e.value) and "step 7" in str(e.value)


def test_bad_inputs(arrays):
    ann = annotate(arrays)
    with pytest.raises(AnnotationError) as e:
        source_demo_from_arrays(arrays, None, TASK)
    assert e.value.reason == "ANNOTATION_NOT_FOUND" and "demo_0" in str(e.value)
    with pytest.raises(InvalidInputError) as e:
        source_demo_from_arrays(dataclasses.replace(arrays, gripper=arrays.gripper[:-1]), ann, TASK)
    assert e.value.reason == "BAD_DEMO"
    q = arrays.ee_quaternions * 2.0
    with pytest.raises(InvalidInputError) as e:
        source_demo_from_arrays(dataclasses.replace(arrays, ee_quaternions=q), ann, TASK)
    assert "unit quaternion" in str(e.value)
    short = dataclasses.replace(ann, num_steps=ann.num_steps - 1)
    with pytest.raises(AnnotationError) as e:
        source_demo_from_arrays(arrays, short, TASK)
    assert e.value.reason == "ANNOTATION_OUT_OF_RANGE" and "fake.mcap" in str(e.value)
    with pytest.raises(AnnotationError) as e:
        source_demo_from_arrays(arrays, dataclasses.replace(ann, demo="demo_9"), TASK)
    assert e.value.reason == "ANNOTATION_WRONG_DEMO"
    demo = source_demo_from_arrays(arrays, ann, TASK)
    with pytest.raises(AnnotationError):
        demo.skill(5)


def test_sample_and_hold():
    out = sample_and_hold([0.0, 0.5, 1.0, 2.5], [0.2, 1.0, 2.0], np.array([[1.0], [2.0], [3.0]]))
    np.testing.assert_array_equal(out[:, 0], [1, 1, 2, 3])


def test_perturbation_bounds_and_recovery():
    rng = np.random.default_rng(0)
    T0 = np.eye(4)
    T0[:3, 3] = [0.5, 0.0, 0.2]
    T0[:3, :3] = Rotation.from_euler("x", np.pi).as_matrix()
    cfg = AugmentationConfig(0.08, 80.0)
    angles = []
    for _ in range(300):
        T1 = perturb_initiation(T0, cfg, rng)
        assert np.abs(T1[:3, 3] - T0[:3, 3]).max() <= 0.08
        angles.append(Rotation.from_matrix(T1[:3, :3] @ T0[:3, :3].T).magnitude())
        rec = recovery_segment(T1, T0, cfg)
        np.testing.assert_allclose(rec[-1], T0, atol=1e-12)
        prev = T1
        for R in rec:  # each step within the configured step sizes
            assert np.linalg.norm(R[:3, 3] - prev[:3, 3]) <= cfg.recovery_step_pos + 1e-9
            assert Rotation.from_matrix(R[:3, :3] @ prev[:3, :3].T).magnitude() <= cfg.recovery_step_rot + 1e-9
            prev = R
    angles = np.degrees(angles)
    assert angles.max() <= 80.0 + 1e-9 and angles.max() > 70.0 and angles.min() < 10.0
    none = AugmentationConfig(0.0, 0.0)
    np.testing.assert_allclose(perturb_initiation(T0, none, rng), T0, atol=1e-12)
    assert len(interpolate_poses(T0, T0, 3)) == 3
    with pytest.raises(InvalidInputError):
        AugmentationConfig(rotation_deg=-1)


def test_build_source_demos_and_replay_plan(arrays):
    from skillgen_ros.core.skills.replay import plan_replay
    from skillgen_ros.core.skills.source_demos import build_source_demos

    with pytest.raises(InvalidInputError) as e:
        build_source_demos([], TASK)
    assert e.value.reason == "NO_SOURCE_DEMOS"
    with pytest.raises(AnnotationError) as e:
        build_source_demos([(arrays, None)], TASK)
    assert e.value.reason == "ANNOTATION_NOT_FOUND"
    (demo,) = build_source_demos([(arrays, annotate(arrays))], TASK)
    seg = demo.skills[1]
    T_new = seg.object_pose.copy()
    T_new[:3, 3] += [0.1, -0.05, 0.0]
    plain = plan_replay(seg, T_new)
    np.testing.assert_allclose(plain.initiation[:3, 3], seg.initiation_in_world(seg.object_pose)[:3, 3] + [0.1, -0.05, 0.0])
    assert len(plain.targets) == seg.num_steps and not plain.recovery.any()
    cfg = AugmentationConfig(0.05, 45.0)
    goal = perturb_initiation(plain.initiation, cfg, np.random.default_rng(0))
    cmds = plan_replay(seg, T_new, goal, True, cfg)
    k = int(cmds.recovery.sum())
    assert k > 0 and cmds.recovery[:k].all() and len(cmds.targets) == k + seg.num_steps
    np.testing.assert_allclose(cmds.targets[k - 1], plain.initiation, atol=1e-12)
    np.testing.assert_array_equal(cmds.gripper[:k], seg.gripper[0])
    np.testing.assert_allclose(cmds.targets[k:], plain.targets)
