"""The MimicGen baseline (core/generation/mimicgen.py) against values computed by hand from
NVlabs/mimicgen's rules: subtask ends = signal + 1 + U[offset range], nearest_neighbor_object
selection among the nn_k closest, whole-segment transform, 5 interpolation steps from the last
target, success at any step."""
from dataclasses import replace

import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.generation.attempt import FailureReason, GenerationConfig, run_attempt
from skillgen_ros.core.generation.mimicgen import (MIMICGEN_SPECS, draw_offsets, interpolate, spec_for,
                                                   subtask_bounds, subtask_signals)
from skillgen_ros.core.generation.seeds import attempt_rng
from skillgen_ros.core.geometry import Pose

# MimicGen's square config (generate_core_configs.py): nearest_neighbor_object, nn_k 3, ends +U[10, 20]
TASK = replace(FakeTask(), name="Square")
SEED, INDEX = 7, 2


@pytest.fixture(scope="module")
def demos():
    return make_source_demos(5)


def _first_close(demo) -> int:
    return int(np.flatnonzero(np.asarray(demo.gripper) > 0)[0])


def test_configs_as_mimicgen_ships_them():
    sq, nut, thr = spec_for("Square"), spec_for("NutAssembly"), spec_for("Threading")
    assert (sq.selection, sq.nn_k, sq.offset_range) == ("nearest_neighbor_object", 3, (10, 20))
    assert (nut.selection, nut.nn_k, nut.offset_range) == ("nearest_neighbor_object", 3, (10, 20))
    assert (thr.selection, thr.offset_range) == ("random", (5, 10))
    for s in MIMICGEN_SPECS.values():
        assert (s.num_interpolation_steps, s.num_fixed_steps, s.action_noise) == (5, 0, 0.05)
    off = draw_offsets(5, 4, sq, np.random.default_rng(0))
    assert off.shape == (5, 3) and off.min() >= 10 and off.max() <= 20


def test_subtask_boundaries_are_the_signal_plus_the_offset(demos):
    for d in demos:
        close = _first_close(d)  # the grasp's signal: the first closed command
        assert subtask_signals(d, TASK) == [close]
        assert d.skill(0).start_step < close < d.skill(0).end_step
        # subtask 0: from the demo's first step through the grasp and 10 steps of lift; subtask 1: the
        # rest (the carry and the place) -- object-centric segments, not SkillGen's skill segments
        np.testing.assert_array_equal(subtask_bounds(d, TASK, [10]), [[0, close + 11], [close + 11, d.num_steps]])
    with pytest.raises(InvalidInputError) as e:  # an offset past the demo's end leaves the last subtask empty
        subtask_bounds(demos[0], TASK, [demos[0].num_steps])
    assert e.value.reason == "BAD_SUBTASKS"


def test_a_skill_with_several_gripper_events_ends_at_its_last():
    """Coffee Prep's place-mug-and-open-lid (transfer: release the mug, pinch the lid, let it go) ends where
    MimicGen's mug_place fires, after the lid opened; its open-drawer (transit: grasp the bar, pull, let go)
    where drawer_open fires, after the pull; a plain grasp at its close, as before."""
    from types import SimpleNamespace as NS

    spans = [(0, 20), (30, 80), (90, 130), (140, 160)]   # grasp_mug, place+open lid, open drawer, grasp_pod
    g = -np.ones(170)
    g[10:45] = 1.0    # mug grasped at 10, released at 45 (skill 1)
    g[55:70] = 1.0    # lid pinched at 55, let go at 70 (skill 1's last event)
    g[100:120] = 1.0  # bar grasped at 100, let go at 120 after the pull (skill 2)
    g[150:] = 1.0     # pod grasped at 150 (skill 3)
    segs = [NS(start_step=a, end_step=b) for a, b in spans]
    demo = NS(gripper=g, skill=lambda i: segs[i], num_steps=170)
    task = NS(name="CoffeePreparation", skills=[NS(index=i, mode=m) for i, m in
                                                enumerate(("transit", "transfer", "transit", "transit", "transfer"))])
    assert subtask_signals(demo, task) == [10, 70, 120, 150]


def test_interpolation_as_pose_utils():
    T1, T2 = np.eye(4), np.eye(4)
    T2[:3, 3] = [0.6, 0.0, -0.3]
    T2[:3, :3] = Rotation.from_euler("z", 0.6).as_matrix()
    P = interpolate(T1, T2, 5)  # 5 poses strictly between, both ends included
    assert P.shape == (7, 4, 4)
    np.testing.assert_allclose(P[:, 0, 3], np.arange(7) / 6 * 0.6, atol=1e-12)
    np.testing.assert_allclose([Rotation.from_matrix(R).magnitude() for R in P[:, :3, :3]], np.arange(7) / 6 * 0.6,
                               atol=1e-9)
    T2[:3, :3] = Rotation.from_euler("z", 0.03).as_matrix()  # under 0.05 rad: every rotation is T2's
    np.testing.assert_allclose(interpolate(T1, T2, 5)[:, :3, :3], np.repeat(T2[None, :3, :3], 7, 0))


def test_one_mimicgen_attempt_on_a_scripted_scene(demos):
    cfg = GenerationConfig(variant="D0", action_noise=0.0)  # noise-free: targets are exact
    r = run_attempt(FakeWorld(), demos, TASK, "mimicgen", INDEX, SEED, cfg)
    assert r.success, r.message
    ep, lab = r.episode, r.episode.labels
    assert np.abs(ep.actions[:, :6]).max() < 1.0  # no step clipped: the fake reaches every target
    # selection by hand: distance (m + rad) of the cube now to the cube in each source demo; one of
    # the three nearest, drawn uniformly from the attempt's selection stream; kept for subtask 1
    T_cube = Pose.from_array(ep.obs["cube_pose"][0]).matrix()
    dist = [np.linalg.norm(T_cube[:3, 3] - d.skill(0).object_pose[:3, 3])
            + Rotation.from_matrix(T_cube[:3, :3].T @ d.skill(0).object_pose[:3, :3]).magnitude() for d in demos]
    j = int(np.argsort(dist)[:3][attempt_rng(SEED, INDEX, "selection").integers(3)])
    assert r.source_demos == (j, j)
    # boundaries by hand: the drawn offset of demo j from the attempt's subtask stream
    d = demos[j]
    off = int(attempt_rng(SEED, INDEX, "subtasks").integers(10, 21, size=len(demos))[j])
    end0, n = _first_close(d) + 1 + off, d.num_steps
    mp, sk = lab["mp_step"].astype(bool), lab["skill_index"]
    # subtask 0: 5 interpolated poses + the source EE pose at step 0 (moved), then targets 0..end0-1
    assert (sk == 0).sum() == 6 + end0 and mp[sk == 0].sum() == 6 and mp[:6].all()
    # subtask 1: 5 interpolated + its first target, then targets end0+1..n-1
    assert (sk == 1).sum() == 6 + (n - end0) - 1 and mp[sk == 1].sum() == 6
    T_plate = Pose.from_array(ep.obs["plate_pose"][0]).matrix()
    move0 = T_cube @ np.linalg.inv(d.skill(0).object_pose)
    move1 = T_plate @ np.linalg.inv(d.skill(1).object_pose)  # the whole segment into the plate's frame
    place = ~mp & (sk == 1)
    np.testing.assert_allclose(ep.actions_abs[place, :3], (move1 @ d.action_poses[end0 + 1:])[:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(ep.actions_abs[~mp & (sk == 0), :3], (move0 @ d.action_poses[:end0])[:, :3, 3],
                               atol=1e-9)
    # subtask 1's interpolation starts from subtask 0's last target, not where the hand is
    last0, first1 = (move0 @ d.action_poses[end0 - 1])[:3, 3], (move1 @ d.action_poses[end0])[:3, 3]
    k = int(np.flatnonzero(sk == 1)[0])
    np.testing.assert_allclose(ep.actions_abs[k, :3], last0 + (first1 - last0) / 6, atol=1e-9)
    np.testing.assert_allclose(ep.actions_abs[k + 5, :3], first1, atol=1e-9)
    # gripper actions read by waypoint index with the first value prepended (the reference's lag)
    np.testing.assert_array_equal(ep.actions[place, 6], d.gripper[end0:n - 1])


class FleetingSuccess(FakeWorld):
    """The task check reads True at one control step only (a nut that lands on its peg, then is dragged off)."""

    def reset(self, task, variant, seed):
        self.n = 0
        return super().reset(task, variant, seed)

    def step(self, target, gripper):
        self.n += 1
        return super().step(target, gripper)

    def task_success(self):
        return self.n == 40


def test_mimicgen_counts_success_at_any_step(demos):
    mg = run_attempt(FleetingSuccess(), demos, TASK, "mimicgen", INDEX, SEED, GenerationConfig(variant="D0"))
    assert mg.success and mg.reason is FailureReason.OK
    sg = run_attempt(FleetingSuccess(), demos, TASK, "skillgen", INDEX, SEED, GenerationConfig(variant="D0"))
    assert sg.reason is FailureReason.TASK_FAILED  # skillgen checks the task when the episode ends
