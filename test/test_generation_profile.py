"""Algorithm profiles (core/generation/profile.py): `paper` is the paper's Algorithm 1 (one initiation
pose, no release moves, no planner extras, task success only); `skillgen_ros` (default) is ours."""
import json
import os

import h5py
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos
from test_generation_initiation import GoalBlockedOnce, WedgedFingers

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.generation.attempt import FailureReason, run_attempt
from skillgen_ros.core.generation.profile import PROFILES, get_profile
from skillgen_ros.core.generation.release import ReleaseConfig
from skillgen_ros.core.generation.session import RunRequest, run_generation, validate_request


@pytest.fixture(scope="module")
def demos():
    return make_source_demos(3)


def _cfg(profile: str, **kw):
    return RunRequest(variant="D1", profile=profile, **kw).config()


def test_profiles_set_what_the_paper_leaves_out():
    paper, ours = _cfg("paper"), _cfg("skillgen_ros")
    assert paper.initiation_candidates == 1 and ours.initiation_candidates == 6
    assert paper.release == ReleaseConfig().without_moves() and ours.release == ReleaseConfig()
    assert not paper.planner_extras and ours.planner_extras
    assert not paper.check_collisions and ours.check_collisions  # the paper counts task success only
    assert paper.profile == "paper" and RunRequest().config().profile == "skillgen_ros"  # ours is the default
    assert _cfg("skillgen_ros", initiation_candidates=2).initiation_candidates == 2
    assert _cfg("paper", initiation_candidates=1).initiation_candidates == 1
    with pytest.raises(InvalidInputError) as e:  # a paper run that retries is not the paper's
        _cfg("paper", initiation_candidates=6)
    assert e.value.reason == "INVALID_PARAMETER"
    with pytest.raises(InvalidInputError) as e:
        validate_request(RunRequest(profile="fastest"), ["Square"])
    assert e.value.reason == "UNKNOWN_PROFILE" and "paper" in str(e.value)
    assert set(PROFILES) == {"paper", "skillgen_ros"} and get_profile("").name == "skillgen_ros"


class Recording(GoalBlockedOnce):
    """Records the planner-extras switch the attempt sets, and reports a collision on every motion."""

    def set_planner_extras(self, on):
        self.calls.append(f"extras:{on}")

    def collided(self):
        return True


def test_paper_profile_fails_at_the_first_unreachable_initiation(demos):
    paper = run_attempt(Recording(), demos, FakeTask(), "skillgen", 0, 5, _cfg("paper"))
    assert paper.reason is FailureReason.PLAN_FAILED and paper.initiation_candidates_used == (1, 1)
    env = Recording()
    ours = run_attempt(env, demos, FakeTask(), "skillgen", 0, 5, _cfg("skillgen_ros", initiation_candidates=3))
    # ours retries the blocked place (2 candidates), then fails on the collision the env reports
    assert ours.initiation_candidates_used == (1,) and ours.reason is FailureReason.EXECUTION_COLLISION
    assert env.calls[1] == "extras:True"
    env = Recording()
    env.blocked = False
    paper = run_attempt(env, demos, FakeTask(), "skillgen", 0, 5, _cfg("paper"))
    assert env.calls[1] == "extras:False"  # the planner is told, per attempt
    assert paper.success and paper.initiation_candidates_used == (1, 1)  # collisions do not filter


def test_paper_profile_has_no_release_moves(demos):
    ours = run_attempt(WedgedFingers(), demos, FakeTask(), "skillgen", 0, 5, _cfg("skillgen_ros"))
    paper = run_attempt(WedgedFingers(), demos, FakeTask(), "skillgen", 0, 5, _cfg("paper"))
    assert ours.success and paper.success
    assert paper.episode.num_samples == ours.episode.num_samples - 7  # no unjam slide, only the hold


def test_datasets_record_the_profile_and_candidate_counts(demos, tmp_path):
    req = RunRequest(task="pick_place", variant="D1", attempts=2, seed=3, profile="paper",
                     output_dir=str(tmp_path / "run"), video_attempts=0)
    run = run_generation(GoalBlockedOnce(), demos, FakeTask(), req, write_report=False)
    assert [(r.success, r.initiation_candidates_used) for r in run.results] == [(False, (1, 1)), (True, (1, 1))]
    for name in ("demo.hdf5", "failed.hdf5"):
        with h5py.File(tmp_path / "run" / name, "r") as f:
            gen = json.loads(f["data"].attrs["env_args"])["generation"]
            assert gen["profile"] == "paper" and gen["initiation_candidates"] == 1
            assert gen["planner_extras"] is False and gen["release_moves"] is False and gen["check_collisions"] is False
            assert gen["source_demos"] == [os.path.abspath(d.source) for d in demos]  # issue 24
            for d in f["data"].values():
                assert list(d.attrs["initiation_candidates_used"]) == [1, 1]
