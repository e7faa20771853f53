"""What a dataset's object observations hold: the recorder's sources (ground truth vs the robot's
belief), perception's estimates as events, the estimates/ layout, and attempts that ask for ground
truth from a robot that has none (issue 25, item 7)."""
import h5py
import numpy as np
import pytest

from _generation_fakes import FakeTask, FakeWorld, make_source_demos
from skillgen_ros.core.dataset.hdf5 import DatasetError, DatasetWriter, read_episode, validate_dataset
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.generation.attempt import GenerationConfig, run_attempt
from skillgen_ros.core.generation.episode import EpisodeRecorder, Observation, StepLabel

DEMOS = make_source_demos()
LABEL = StepLabel(True, 0, 0, np.array([0, 0, 0, 0, 0, 0, 1.0]))


def _pose(x):
    return np.array([x, 0, 0, 0, 0, 0, 1.0])


def _obs(t, belief_x, true_x=None, stamp=None):
    return Observation(ee_pose=_pose(t), gripper=[0.04, 0.04], joint_positions=np.zeros(7),
                       object_poses={"cube": _pose(belief_x)},
                       true_object_poses=None if true_x is None else {"cube": _pose(true_x), "plate": _pose(9.0)},
                       stamp_ns=stamp)


def _record(rec, observations):
    for o in observations:
        rec.add(o, np.zeros(7), o.ee_pose, -1.0, LABEL)


def test_ground_truth_source_records_true_poses_and_estimates_apart():
    rec = EpisodeRecorder("ground_truth")
    rec.add_estimate(1_000_000_000, {"cube": _pose(0.5)})  # perception at the first state
    _record(rec, [_obs(0, 0.5, 0.51, 1_000_000_000), _obs(1, 0.5, 0.60, 1_050_000_000)])
    rec.add_estimate(1_100_000_000, {"plate": _pose(9.1)})  # a second look that saw only the plate
    _record(rec, [_obs(2, 0.5, 0.70, 1_100_000_000)])
    ep = rec.episode(True)
    assert ep.object_ids == ("cube", "plate")  # every object the sim knows, not only the estimated ones
    np.testing.assert_allclose(ep.obs["cube_pose"][:, 0], [0.51, 0.60, 0.70])  # the truth, not the stale belief
    np.testing.assert_allclose(ep.obs["object"][:, 7], 9.0)
    assert ep.estimates["step"].tolist() == [0, 2]
    np.testing.assert_allclose(ep.estimates["stamp"], [0.0, 0.1])  # seconds since step 0's state
    np.testing.assert_allclose(ep.estimates["cube_pose"][0], _pose(0.5))
    assert np.isnan(ep.estimates["cube_pose"][1]).all() and np.isnan(ep.estimates["plate_pose"][0]).all()


def test_estimate_source_records_the_belief():
    rec = EpisodeRecorder("estimate")
    _record(rec, [_obs(0, 0.5, 0.51), _obs(1, 0.55)])  # a real robot: no truth at all
    ep = rec.episode(False)
    assert ep.object_ids == ("cube",)
    np.testing.assert_allclose(ep.obs["cube_pose"][:, 0], [0.5, 0.55])
    assert ep.estimates["step"].shape == (0,)


def test_steps_with_only_a_stamp_are_resolved_in_one_lookup():
    rec = EpisodeRecorder("ground_truth")
    _record(rec, [_obs(0, 0.5, 0.51, 10), _obs(1, 0.5, None, 20), _obs(2, 0.5, None, 30)])
    assert rec.unresolved_stamps() == [20, 30]
    asked = []

    def lookup(stamps):
        asked.append(list(stamps))
        return {t: {"cube": _pose(t / 100), "plate": _pose(9.0)} for t in stamps}

    rec.resolve_from(lookup)
    assert asked == [[20, 30]] and rec.unresolved_stamps() == []
    np.testing.assert_allclose(rec.episode(True).obs["cube_pose"][:, 0], [0.51, 0.2, 0.3])
    rec.resolve_from(None)  # nothing left to look up: no call, no error


def test_missing_truth_is_an_error_with_a_reason_never_a_silent_fallback():
    rec = EpisodeRecorder("ground_truth")
    _record(rec, [_obs(0, 0.5, 0.51, 10), _obs(1, 0.5, None, 20)])
    with pytest.raises(SkillGenError) as e:
        rec.episode(True)
    assert e.value.reason == "NO_GROUND_TRUTH"
    with pytest.raises(SkillGenError) as e:
        rec.resolve_from(None)
    assert e.value.reason == "NO_GROUND_TRUTH"
    with pytest.raises(SkillGenError) as e:
        EpisodeRecorder("perception")
    assert e.value.reason == "INVALID_PARAMETER"
    with pytest.raises(SkillGenError) as e:
        GenerationConfig(observation_source="oracle")
    assert e.value.reason == "INVALID_PARAMETER"


def test_require_ground_truth_tells_no_truth_from_a_slow_lookup():
    rec = EpisodeRecorder("ground_truth")
    rec.require_ground_truth(_obs(0, 0.5, 0.5), None)  # has its truth already
    rec.require_ground_truth(_obs(0, 0.5, None, 10), lambda s: {10: {}})  # can look it up
    for obs, lookup in ((_obs(0, 0.5), None), (_obs(0, 0.5, None, 10), None)):
        with pytest.raises(SkillGenError) as e:
            rec.require_ground_truth(obs, lookup)
        assert e.value.reason == "NO_GROUND_TRUTH"

    def slow(_stamps):
        raise SkillGenError("no answer", reason="TIMEOUT")
    with pytest.raises(SkillGenError) as e:
        rec.require_ground_truth(_obs(0, 0.5, None, 10), slow)
    assert e.value.reason == "TIMEOUT"
    EpisodeRecorder("estimate").require_ground_truth(_obs(0, 0.5), None)  # a real robot needs none


def test_an_attempt_asking_a_robot_without_ground_truth_fails_before_moving():
    env = FakeWorld()
    env.no_truth = True
    with pytest.raises(SkillGenError) as e:
        run_attempt(env, DEMOS, FakeTask(), "skillgen", 0, 1)
    assert e.value.reason == "NO_GROUND_TRUTH"
    assert not any(c.startswith("plan") for c in env.calls), env.calls
    r = run_attempt(env, DEMOS, FakeTask(), "skillgen", 0, 1, GenerationConfig(observation_source="estimate"))
    assert r.episode.num_samples > 0 and r.episode.estimates["step"][0] == 0


def test_the_fake_attempt_records_truth_that_follows_the_hand():
    """The fake env moves the cube with the hand once grasped: the recorded pose does too."""
    r = run_attempt(FakeWorld(), DEMOS, FakeTask(), "skillgen", 0, 1)
    ep = r.episode
    held = ep.actions_abs[:, 7] > 0
    rel = ep.obs["cube_pose"][held, :3] - ep.obs["robot0_eef_pos"][held]
    assert held.sum() > 5 and np.ptp(rel, axis=0).max() < 0.01


def _write(tmp_path, estimates):
    rec = EpisodeRecorder("ground_truth")
    rec.add_estimate(10, {"cube": _pose(0.5)})
    _record(rec, [_obs(0, 0.5, 0.51, 10), _obs(1, 0.5, 0.6, 20)])
    ep = rec.episode(True)
    if estimates is not None:
        ep = type(ep)(**{**ep.__dict__, "estimates": estimates(dict(ep.estimates))})
    path = tmp_path / "d.hdf5"
    with DatasetWriter(str(path), {"env_name": "Fake"}) as w:
        w.append(ep, {"index": 0})
    return path, ep


def test_estimates_are_written_read_back_and_validated(tmp_path):
    path, ep = _write(tmp_path, None)
    assert validate_dataset(str(path)).num_demos == 1
    back, _ = read_episode(str(path), "demo_0")
    assert back.estimates.keys() == ep.estimates.keys()
    for k in ep.estimates:
        np.testing.assert_array_equal(back.estimates[k], ep.estimates[k])
    with h5py.File(path, "r") as f:  # robomimic-style readers by key see T rows under obs/
        assert f["data/demo_0/obs/cube_pose"].shape == (2, 7) and f["data/demo_0/estimates/step"].shape == (1,)


@pytest.mark.parametrize("corrupt, why", [
    (lambda e: {**e, "step": np.array([5])}, "step"),  # after the last step
    (lambda e: {**e, "step": np.array([0.5])}, "step"),  # not an integer
    (lambda e: {**e, "cube_pose": np.zeros((1, 3))}, "cube_pose"),
    (lambda e: {**e, "stamp": np.zeros(3)}, "stamp"),
    (lambda e: {k: v for k, v in e.items() if k != "stamp"}, "stamp"),
    (lambda e: {**e, "junk": np.zeros((1, 7))}, "junk"),
])
def test_malformed_estimates_are_rejected_naming_the_field(tmp_path, corrupt, why):
    path, _ = _write(tmp_path, corrupt)
    with pytest.raises(DatasetError) as e:
        validate_dataset(str(path))
    assert why in str(e.value) and "demo_0" in str(e.value)


def test_beliefs_along_a_skill_follow_the_hand_and_stay_where_released():
    """The graph's belief for estimate datasets (grasp.beliefs_along), as SimGenerationEnv tracks it."""
    from skillgen_ros.core.generation.grasp import CLOSE_PERIODS, beliefs_along
    from skillgen_ros.core.geometry import Pose

    def ee(x):
        T = np.eye(4)
        T[0, 3] = x
        return T

    # place: the peg-side object is held 5 cm below the hand, the hand moves +x, opens at step 3
    T_E_O = np.eye(4)
    T_E_O[2, 3] = -0.05
    out = beliefs_along({"cube": Pose(np.zeros(3), [0, 0, 0, 1])}, ("cube", T_E_O), None,
                        [ee(0.1 * k) for k in range(6)], [1, 1, 1, -1, -1, -1])
    xs = [b["cube"].position[0] for b in out]
    np.testing.assert_allclose(xs, [0.0, 0.1, 0.2, 0.3, 0.4, 0.4])  # follows until the open command took effect
    assert out[-1]["cube"].position[2] == pytest.approx(-0.05)
    # grasp: the skill's object stays at its estimate until CLOSE_PERIODS after the close command
    n = CLOSE_PERIODS + 4
    out = beliefs_along({"cube": Pose([0.0, 0, 0], [0, 0, 0, 1])}, None, "cube", [ee(0.01 * k) for k in range(n)],
                        [-1] + [1] * (n - 1))
    xs = np.array([b["cube"].position[0] for b in out])
    assert np.all(xs[:CLOSE_PERIODS + 1] == 0.0) and np.all(np.diff(xs[CLOSE_PERIODS + 1:]) > 0.009)


def test_after_a_skill_the_graph_holds_what_the_hand_closed_on_and_drops_what_it_opened_on():
    """GraspTracker.after_skill (RosGraphEnv after each replay_skill): the grasp is taken CLOSE_PERIODS
    after the close command; an open ending lets go where the opening command led."""
    from skillgen_ros.core.generation.grasp import CLOSE_PERIODS, GraspTracker
    from skillgen_ros.core.geometry import Pose

    n = CLOSE_PERIODS + 4
    ee = np.array([[0.01 * k, 0, 0.2, 0, 0, 0, 1] for k in range(n)])
    t = GraspTracker()
    cube = {"cube": Pose([0.0, 0, 0], [0, 0, 0, 1])}
    assert t.after_skill([-1, -1] + [1] * (n - 2), ee, "cube", cube) == {} and t.holding() == "cube"
    # held from ee[2 + CLOSE_PERIODS]: the cube is that far behind the hand, 0.2 m below it
    np.testing.assert_allclose(t.object_in_ee("cube")[:3, 3], [-0.01 * (2 + CLOSE_PERIODS), 0, -0.2], atol=1e-12)
    assert t.after_skill([1] * n, ee, "other", cube) == {} and t.holding() == "cube"  # still closed: kept
    left = t.after_skill([1, 1, -1] + [-1] * (n - 3), ee, "cube", cube)
    assert t.holding() is None  # let go where the opening command (step 2) led: ee[3]
    np.testing.assert_allclose(left["cube"].position, [0.03 - 0.01 * (2 + CLOSE_PERIODS), 0, 0.0], atol=1e-12)
    assert t.after_skill([1] * n, ee, "unseen", cube) == {} and t.holding() is None  # no estimate: nothing held


def test_articulated_joint_values_are_recorded_per_object(tmp_path):
    """obs/<id>_joints: the lid angle at every step (NaN where a step had none); no key without joints."""
    from dataclasses import replace

    rec = EpisodeRecorder("ground_truth")
    lid = "coffee_machine/lid"
    _record(rec, [replace(_obs(0, 0.5, 0.51, 10), object_joints={lid: 2.09}), _obs(1, 0.5, 0.6, 20),
                  replace(_obs(2, 0.5, 0.7, 30), object_joints={lid: 0.01})])
    ep = rec.episode(True)
    np.testing.assert_allclose(ep.obs["coffee_machine_joints"], [[2.09], [np.nan], [0.01]])
    path = tmp_path / "j.hdf5"
    with DatasetWriter(str(path), {"env_name": "Fake"}) as w:
        w.append(ep, {"index": 0})
    assert validate_dataset(str(path)).num_demos == 1
    back, _ = read_episode(str(path), "demo_0")
    np.testing.assert_array_equal(back.obs["coffee_machine_joints"], ep.obs["coffee_machine_joints"])
    plain = EpisodeRecorder("ground_truth")
    _record(plain, [_obs(0, 0.5, 0.51, 10)])
    assert not any(k.endswith("_joints") for k in plain.episode(True).obs)


def test_joint_values_are_resolved_by_stamp_as_the_true_poses_are():
    """The graph's observed steps carry only a stamp: their lid angle comes from one joints lookup (the
    driver's history), in either observation source; a step the lookup does not know stays NaN, and
    without a joints lookup (a robot with no history) nothing is asked and no key is written."""
    from dataclasses import replace

    lid = "coffee_machine/lid"
    for source in ("ground_truth", "estimate"):
        rec = EpisodeRecorder(source)
        _record(rec, [replace(_obs(0, 0.5, 0.51, 10), object_joints={lid: 2.09}), _obs(1, 0.5, None, 20),
                      _obs(2, 0.5, None, 30), _obs(3, 0.5, None, 40)])
        assert rec.unresolved_joint_stamps() == [20, 30, 40]
        asked = []

        def joints(stamps):
            asked.append(list(stamps))
            return {t: {lid: t / 100} for t in stamps if t != 30}

        rec.resolve_from(lambda stamps: {t: {"cube": _pose(t / 100), "plate": _pose(9.0)} for t in stamps}, joints)
        assert asked == [[20, 30, 40]] and rec.unresolved_joint_stamps() == [30]
        np.testing.assert_allclose(rec.episode(True).obs["coffee_machine_joints"], [[2.09], [0.2], [np.nan], [0.4]])
    blind = EpisodeRecorder("estimate")
    _record(blind, [_obs(0, 0.5, None, 10)])
    blind.resolve_from(None, None)
    assert blind.unresolved_joint_stamps() == [10] and not any(k.endswith("_joints") for k in blind.episode(True).obs)
    none = EpisodeRecorder("estimate")  # a scene without articulated objects: {} per stamp, no key
    _record(none, [_obs(0, 0.5, None, 10)])
    none.resolve_from(None, lambda stamps: {t: {} for t in stamps})
    assert none.unresolved_joint_stamps() == [] and not any(k.endswith("_joints") for k in none.episode(True).obs)
