"""Algorithm 1 (run_attempt) over a fake environment, per method; seeds; selection strategies."""
import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos

from skillgen_ros.core.errors import InvalidInputError, SkillGenError
from skillgen_ros.core.generation.attempt import FailureReason, GenerationConfig, motion_failure, run_attempt
from skillgen_ros.core.generation.seeds import attempt_rng, scene_seed, shard_indices
from skillgen_ros.core.generation.selection import NearestNeighborObject, make_strategy, pose_distance
from skillgen_ros.core.skills.augmentation import AugmentationConfig

TASK = FakeTask()
CFG = GenerationConfig(variant="D1")


@pytest.fixture(scope="module")
def demos():
    return make_source_demos(3)


@pytest.mark.parametrize("method", ["skillgen", "mimicgen", "replay_noise"])
def test_methods_succeed_on_fake_world(demos, method):
    results = [run_attempt(FakeWorld(), demos, TASK, method, i, 11, CFG) for i in range(4)]
    assert all(r.success and r.reason is FailureReason.OK for r in results), [r.message for r in results]
    for r in results:
        ep = r.episode
        T = ep.num_samples
        assert ep.actions.shape == (T, 7) and ep.actions_abs.shape == (T, 8) and ep.states.shape[0] == T
        assert np.abs(ep.actions[:, :6]).max() <= 1.0
        assert ep.rewards[-1] == 1.0 and ep.dones[-1] == 1 and ep.dones[:-1].sum() == 0
        # replay_noise labels the motion after the last skill -1 (it leads to no skill)
        assert {0, 1} <= set(np.unique(ep.labels["skill_index"]).tolist()) <= {-1, 0, 1}
        assert {"robot0_eef_pos", "robot0_eef_quat", "object", "cube_pose", "plate_pose"} <= set(ep.obs)
        assert r.timings["total"] > 0
    assert len({r.scene_seed for r in results}) > 1 or method == "replay_noise"


def test_skillgen_labels_and_env_calls(demos):
    env = FakeWorld()
    r = run_attempt(env, demos, TASK, "skillgen", 0, 5, CFG)
    lab = r.episode.labels
    # mp steps (10 per planned motion in the fake) precede each skill's replay
    mp = lab["mp_step"].astype(bool)
    assert mp.sum() == 20 and mp[:10].all() and not mp[10]
    assert env.calls[0] == f"reset:D1:{scene_seed(5, 0)}"
    assert env.calls[1:] == ["estimate", "plan:transit:None", "estimate", "plan:transfer:cube"]
    # random-per-episode: one source demo for the whole episode
    assert len(set(r.source_demos)) == 1 and (lab["source_demo"] == r.source_demos[0]).all()
    # the initiation target label is where the planned motion ended (the fake tracks exactly)
    first_skill = np.flatnonzero(~mp)[0]
    np.testing.assert_allclose(lab["initiation_target"][first_skill][:3], r.episode.obs["robot0_eef_pos"][first_skill],
                               atol=1e-9)
    # skill steps replay the source gripper actions unchanged
    d = demos[r.source_demos[0]]
    skill0 = ~mp & (lab["skill_index"] == 0)
    np.testing.assert_array_equal(r.episode.actions[skill0, 6], d.skills[0].gripper)
    np.testing.assert_array_equal(r.episode.actions_abs[:, 7], r.episode.actions[:, 6])


def test_noise_changes_pose_dims_only(demos):
    quiet = run_attempt(FakeWorld(), demos, TASK, "skillgen", 3, 5, GenerationConfig(variant="D1", action_noise=0.0))
    noisy = run_attempt(FakeWorld(), demos, TASK, "skillgen", 3, 5, CFG)
    assert quiet.source_demos == noisy.source_demos and quiet.episode.num_samples == noisy.episode.num_samples
    skill = noisy.episode.labels["mp_step"] == 0
    np.testing.assert_array_equal(quiet.episode.actions[:, 6], noisy.episode.actions[:, 6])
    diff = noisy.episode.actions[skill, :6] - quiet.episode.actions[skill, :6]
    assert 0.02 < diff.std() < 0.1


def test_augmentation_adds_recovery(demos):
    cfg = GenerationConfig(variant="D1", augment=True, augmentation=AugmentationConfig(0.03, 30.0))
    r = run_attempt(FakeWorld(), demos, TASK, "skillgen", 1, 5, cfg)
    assert r.success, r.message
    aug = r.episode.labels["augmented"].astype(bool)
    assert aug.any() and not (aug & r.episode.labels["mp_step"].astype(bool)).any()
    # the recovery starts at the perturbed target (the label) and ends at the source initiation pose
    first = np.flatnonzero(aug)[0]
    np.testing.assert_allclose(r.episode.obs["robot0_eef_pos"][first], r.episode.labels["initiation_target"][first][:3],
                               atol=1e-9)


def test_replay_noise_uses_source_initial_state(demos):
    env = FakeWorld()
    r = run_attempt(env, demos, TASK, "replay_noise", 0, 5, CFG)
    j = r.source_demos[0]
    assert env.calls == [f"reset:D0:{demos[j].scene_seed}"] and r.scene_seed == demos[j].scene_seed
    assert r.episode.num_samples == demos[j].num_steps


@pytest.mark.parametrize("world,reason", [
    (dict(plan_status="PLAN_FAILED"), FailureReason.PLAN_FAILED),
    (dict(plan_status="IK_FAILED"), FailureReason.IK_FAILED),
    (dict(plan_status="TIMEOUT"), FailureReason.TIMEOUT),
    (dict(plan_status="NO_PATH_FOUND"), FailureReason.PLAN_FAILED),
    (dict(collide=True), FailureReason.EXECUTION_COLLISION),
    (dict(perception_fails=True), FailureReason.PERCEPTION_FAILED),
])
def test_failure_reasons(demos, world, reason):
    r = run_attempt(FakeWorld(**world), demos, TASK, "skillgen", 0, 5, CFG)
    assert not r.success and r.reason is reason and r.message


def test_timeout_task_failed_skill_failed(demos):
    r = run_attempt(FakeWorld(), demos, TASK, "skillgen", 0, 5, GenerationConfig(variant="D1", max_steps=15))
    assert r.reason is FailureReason.TIMEOUT and r.episode.num_samples == 15

    class NoSuccess(FakeWorld):
        def task_success(self):
            return False

    assert run_attempt(NoSuccess(), demos, TASK, "mimicgen", 0, 5, CFG).reason is FailureReason.TASK_FAILED

    class SkillCheck(FakeWorld):
        def skill_succeeded(self, i):
            return i != 1

    assert run_attempt(SkillCheck(), demos, TASK, "skillgen", 0, 5, CFG).reason is FailureReason.SKILL_FAILED

    class Crashes(FakeWorld):
        def estimate_poses(self):
            raise SkillGenError("perception node gone", reason="SERVICE_UNAVAILABLE")

    assert run_attempt(Crashes(), demos, TASK, "skillgen", 0, 5, CFG).reason is FailureReason.PERCEPTION_FAILED


def test_bad_requests(demos):
    with pytest.raises(InvalidInputError) as e:
        run_attempt(FakeWorld(), demos, TASK, "teleport", 0, 5, CFG)
    assert e.value.reason == "UNKNOWN_METHOD"
    with pytest.raises(InvalidInputError) as e:
        run_attempt(FakeWorld(), [], TASK, "skillgen", 0, 5, CFG)
    assert e.value.reason == "NO_SOURCE_DEMOS"
    with pytest.raises(InvalidInputError) as e:
        run_attempt(FakeWorld(), demos, TASK, "skillgen", 0, 5, GenerationConfig(selection="best"))
    assert e.value.reason == "UNKNOWN_SELECTION"
    with pytest.raises(InvalidInputError):
        run_attempt(FakeWorld(), demos, TASK, "skillgen", -1, 5, CFG)
    import dataclasses
    no_seed = [dataclasses.replace(demos[0], scene_seed=None)]
    with pytest.raises(InvalidInputError) as e:
        run_attempt(FakeWorld(), no_seed, TASK, "replay_noise", 0, 5, CFG)
    assert e.value.reason == "NO_INITIAL_STATE"


def test_same_seed_same_attempt(demos):
    a = run_attempt(FakeWorld(), demos, TASK, "skillgen", 2, 9, CFG)
    b = run_attempt(FakeWorld(), demos, TASK, "skillgen", 2, 9, CFG)
    c = run_attempt(FakeWorld(), demos, TASK, "skillgen", 2, 10, CFG)
    np.testing.assert_array_equal(a.episode.actions, b.episode.actions)
    np.testing.assert_array_equal(a.episode.states, b.episode.states)
    assert a.scene_seed == b.scene_seed != c.scene_seed


def test_seeds_independent_and_shardable():
    assert scene_seed(1, 5) == scene_seed(1, 5) and scene_seed(1, 5) != scene_seed(1, 6)
    assert 0 <= scene_seed(2**40, 3) < 2**31
    x = attempt_rng(1, 5, "noise").standard_normal(3)
    np.testing.assert_array_equal(x, attempt_rng(1, 5, "noise").standard_normal(3))
    assert not np.allclose(x, attempt_rng(1, 5, "selection").standard_normal(3))
    shards = [list(shard_indices(10, 7, s, 3)) for s in range(3)]
    assert sorted(sum(shards, [])) == list(range(10, 17))
    with pytest.raises(InvalidInputError):
        attempt_rng(1, 5, "bogus")


def test_motion_status_mapping():
    import enum

    class S(enum.Enum):
        SUCCESS = 0
        IK_FAILED = 1

    assert motion_failure(S.SUCCESS) is None and motion_failure(S.IK_FAILED) is FailureReason.IK_FAILED
    assert motion_failure("collision") is FailureReason.EXECUTION_COLLISION
    PlanStatus = pytest.importorskip("skillgen_ros.core.planning.planner").PlanStatus
    assert motion_failure(PlanStatus.SUCCESS) is None
    assert motion_failure(PlanStatus.PLAN_TIMEOUT) is FailureReason.PLAN_FAILED  # no plan in budget, not an attempt timeout
    assert motion_failure(PlanStatus.IK_FAILED) is FailureReason.IK_FAILED
    assert motion_failure("EXECUTION_FAILED") is FailureReason.EXECUTION_COLLISION


def test_selection_strategies(demos):
    rng = np.random.default_rng(0)
    rnd = make_strategy("random")
    assert rnd.select(demos, 1, np.eye(4), 2, rng) == 2
    picks = {rnd.select(demos, 0, np.eye(4), None, rng) for _ in range(50)}
    assert picks == {0, 1, 2}
    nn = make_strategy("nearest_neighbor", nn_k=1)
    for j, d in enumerate(demos):
        assert nn.select(demos, 0, d.skills[0].object_pose, None, rng) == j
    nn2 = NearestNeighborObject(nn_k=2)
    target = demos[0].skills[0].object_pose
    dist = [pose_distance(d.skills[0].object_pose, target) for d in demos]
    allowed = set(np.argsort(dist)[:2].tolist())
    assert {nn2.select(demos, 0, target, None, rng) for _ in range(30)} <= allowed
    with pytest.raises(InvalidInputError) as e:
        make_strategy("nearest_neighbor", k=3)
    assert e.value.reason == "INVALID_PARAMETER"


@pytest.mark.parametrize("method", ["skillgen", "mimicgen", "replay_noise"])
def test_a_node_gone_at_reset_or_success_check_fails_the_attempt_not_the_run(demos, method):
    """A node of the graph that stops answering (killed: issue 19's chaos) fails the attempt in
    flight with a reason; a request error from the same call (an unknown variant) still raises."""
    from skillgen_ros.core.errors import NoAnswerError

    class DeadDriver(FakeWorld):
        def reset(self, task, variant, seed):
            raise NoAnswerError("reset_scene: no answer from reset_scene within 30.0 s")

    class DeadAtTheEnd(FakeWorld):
        def task_success(self):
            raise NoAnswerError("task_success: service task_success is not available")

    class LostPerception(FakeWorld):  # a stage's reason comes through as it is
        def reset(self, task, variant, seed):
            raise NoAnswerError("no answer", reason="PERCEPTION_FAILED")

    for world, reason in ((DeadDriver(), FailureReason.TIMEOUT), (DeadAtTheEnd(), FailureReason.TIMEOUT),
                          (LostPerception(), FailureReason.PERCEPTION_FAILED)):
        r = run_attempt(world, demos, TASK, method, 0, 5, CFG)
        assert not r.success and r.reason is reason and "did not answer" in r.message, (world, r.message)

    class BadVariant(FakeWorld):
        def reset(self, task, variant, seed):
            raise SkillGenError("reset_scene: unknown variant", reason="UNKNOWN_VARIANT")

    with pytest.raises(SkillGenError, match="UNKNOWN_VARIANT"):
        run_attempt(BadVariant(), demos, TASK, method, 0, 5, CFG)


def test_a_run_keeps_no_episode_after_writing_it(demos, tmp_path):
    """issue 19's soak: RunResult held every attempt's arrays (+0.3 MiB per attempt in datagen)."""
    import h5py

    from skillgen_ros.core.generation.session import RunRequest, run_generation

    req = RunRequest(task="pick_place", variant="D1", attempts=3, seed=3, output_dir=str(tmp_path / "run"),
                     video_attempts=0)
    run = run_generation(FakeWorld(), demos, TASK, req, write_report=False)
    assert run.attempts == 3 and run.successes == 3 and all(r.episode is None for r in run.results)
    with h5py.File(tmp_path / "run" / "demo.hdf5", "r") as f:
        assert len(f["data"]) == 3 and all(f["data"][k]["actions"].shape[0] > 0 for k in f["data"])
    kept = run_generation(FakeWorld(), demos, TASK, RunRequest(**{**req.__dict__, "output_dir": str(tmp_path / "k")}),
                          write_report=False, keep_episodes=True)
    assert all(r.episode.num_samples > 0 for r in kept.results)


def test_a_stop_mid_attempt_abandons_it_and_its_index_runs_the_same_later(demos, tmp_path):
    """issue 21: a cancel ends the run at the running attempt's next step, not after the attempt;
    the abandoned attempt is not written, and running its index later gives the serial run's attempt."""
    import h5py

    from skillgen_ros.core.generation.session import RunRequest, run_generation

    req = RunRequest(task="pick_place", variant="D1", attempts=3, seed=3, output_dir=str(tmp_path / "serial"),
                     video_attempts=0)
    serial = run_generation(FakeWorld(), demos, TASK, req, write_report=False, keep_episodes=True)
    asked: list[int] = []  # stop requests are checked before every step and env call: count them

    def stop() -> str:
        asked.append(len(asked))
        return "CANCELED" if len(asked) > per_attempt + 5 else ""  # a few steps into attempt 1

    per_attempt = 10 ** 9
    run_generation(FakeWorld(), demos, TASK, RunRequest(**{**req.__dict__, "output_dir": str(tmp_path / "count"),
                                                            "attempts": 1}),
                   write_report=False, should_stop=stop)
    per_attempt, asked = len(asked), []  # checks in one whole attempt (+1: the run's own before it)
    assert per_attempt > 10
    env = FakeWorld()
    run = run_generation(env, demos, TASK, RunRequest(**{**req.__dict__, "output_dir": str(tmp_path / "stopped")}),
                         write_report=False, should_stop=stop)
    assert run.stopped_early == "CANCELED" and run.attempts == 1, "attempt 1 was abandoned, not finished"
    assert len(asked) == per_attempt + 6, "the stop took effect at the first check after it was asked"
    with h5py.File(tmp_path / "stopped" / "demo.hdf5", "r") as f:
        assert [int(f["data"][k].attrs["index"]) for k in f["data"]] == [0]
    again = run_generation(env, demos, TASK, RunRequest(**{**req.__dict__, "output_dir": str(tmp_path / "again"),
                                                           "first_index": 1, "attempts": 2}),
                           write_report=False, keep_episodes=True)  # the same env, left mid-attempt
    for a, b in zip(again.results, serial.results[1:]):
        assert a.index == b.index
        np.testing.assert_array_equal(a.episode.actions, b.episode.actions)
