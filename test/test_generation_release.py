"""release.py: settle while the fingers open; unjam fingers wedged on the released object."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.generation.release import OPEN_WIDTH, Feedback, ReleaseConfig, release_targets

HOLD = np.eye(4)
HOLD[:3, :3] = Rotation.from_euler("xz", [180, 30], degrees=True).as_matrix()  # top-down, yawed
HOLD[:3, 3] = [0.6, 0.1, 0.05]


def drive(gen, fingers, hand=lambda target: target[:3, 3], wrench=lambda target: None):
    """Run the generator against a finger model fingers(target, width) -> width, a hand model
    hand(target) -> EE position (default: the OSC reaches every target) and a force model
    wrench(target) -> the external wrench on the hand (default: none reported)."""
    targets, width = [], None
    try:
        target = next(gen)
        while True:
            targets.append(target)
            width = fingers(target, width)
            target = gen.send(Feedback(width, hand(target), wrench(target)))
    except StopIteration:
        return targets


def opening(rate=0.01, start=0.03):
    state = {"w": start}

    def f(target, _):
        state["w"] = min(0.08, state["w"] + rate)
        return state["w"]
    return f


def test_open_gripper_needs_no_release_steps():
    assert drive(release_targets(HOLD, 0.079), opening()) == []
    assert drive(release_targets(HOLD, 0.03, ReleaseConfig(settle_steps=0)), opening()) == []


def test_settle_holds_the_pose_until_open():
    targets = drive(release_targets(HOLD, 0.03), opening(0.01, 0.03))
    assert len(targets) == 5  # 0.04 .. 0.08: open (>= OPEN_WIDTH) on the fifth period
    for T in targets:
        np.testing.assert_array_equal(T, HOLD)


def test_still_opening_after_settle_steps_lets_the_motion_start():
    targets = drive(release_targets(HOLD, 0.0, ReleaseConfig(settle_steps=3)), opening(0.005, 0.0))
    assert len(targets) == 3


def wedged(free_side, free_after=0.016):
    """Fingers stuck at 2.3 cm until the hand has slid `free_after` m along `free_side` (world)."""
    state = {"w": 0.023}

    def f(target, _):
        d = (target[:3, 3] - HOLD[:3, 3]) @ free_side
        if d >= free_after - 1e-9 or state["w"] > 0.024:
            state["w"] = min(0.08, state["w"] + 0.02)
        return state["w"]
    return f


def test_wedged_fingers_are_freed_by_sliding_along_the_finger_axis_and_recentred():
    y = HOLD[:3, 1]
    targets = drive(release_targets(HOLD, 0.023), wedged(+y))
    moves = np.array([T[:3, 3] - HOLD[:3, 3] for T in targets])
    along_y = moves @ y
    # one settle period finds the stall; -y for 5 periods (8 mm each, 4 cm), back; +y until free
    assert np.allclose(moves[0], 0)
    np.testing.assert_allclose(along_y[1:6], -0.008 * np.arange(1, 6))
    np.testing.assert_allclose(moves[6], 0, atol=1e-12)
    np.testing.assert_allclose(along_y[7:9], [0.008, 0.016])
    # freed at +16 mm: held there until open, then 4 periods back at the release pose
    assert np.allclose(along_y[9:-4], 0.016)
    for T in targets[-4:]:
        np.testing.assert_array_equal(T, HOLD)
    for T in targets:  # only the position moves, in the hand's plane, at most 4 cm
        np.testing.assert_allclose(T[:3, :3], HOLD[:3, :3])
        assert abs((T[:3, 3] - HOLD[:3, 3]) @ HOLD[:3, 2]) < 1e-12
        assert np.linalg.norm(T[:3, 3] - HOLD[:3, 3]) <= 0.04 + 1e-12


def test_the_palm_axis_is_tried_after_the_finger_axis():
    targets = drive(release_targets(HOLD, 0.023), wedged(-HOLD[:3, 0], 0.008))
    moves = np.array([T[:3, 3] - HOLD[:3, 3] for T in targets])
    first_x = next(i for i, m in enumerate(moves) if abs(m @ HOLD[:3, 0]) > 1e-9)
    assert first_x == 1 + 2 * 6  # settle, then -y and +y (5 slides + back each)
    assert moves[first_x] @ HOLD[:3, 0] == pytest.approx(-0.008)


def test_never_freed_ends_back_at_the_release_pose_after_bounded_moves():
    targets = drive(release_targets(HOLD, 0.023), lambda T, w: 0.023)
    assert len(targets) == 1 + 4 * 6
    np.testing.assert_array_equal(targets[-1], HOLD)
    assert drive(release_targets(HOLD, 0.023, ReleaseConfig(unjam_max=0.0)), lambda T, w: 0.023) == [HOLD]


def test_open_width_is_below_the_panda_hand_maximum():
    assert 0.07 <= OPEN_WIDTH < 0.08


def test_a_finger_stalling_again_after_some_progress_does_not_end_the_unjam():
    state = {"w": 0.023, "n": 0}

    def fingers(target, _):  # the first slide gains 3 mm then sticks; the +y side frees them
        state["n"] += 1
        d = (target[:3, 3] - HOLD[:3, 3]) @ HOLD[:3, 1]
        if d > 0.0159 or state["w"] > 0.03:
            state["w"] = min(0.08, state["w"] + 0.02)
        elif state["n"] == 2:
            state["w"] = 0.026
        return state["w"]
    targets = drive(release_targets(HOLD, 0.023), fingers)
    assert max((T[:3, 3] - HOLD[:3, 3]) @ HOLD[:3, 1] for T in targets) == pytest.approx(0.016)
    np.testing.assert_array_equal(targets[-1], HOLD)
    assert state["w"] >= OPEN_WIDTH


def test_a_hand_pushed_off_its_last_target_moves_on_along_the_push():
    reference = HOLD.copy()
    pushed = HOLD.copy()
    pushed[:3, 3] += [0.0, 0.012, 0.0]  # an open finger pressing the object: 12 mm off target
    targets = drive(release_targets(pushed, 0.078, reference=reference), lambda T, w: 0.078,
                    hand=lambda T: pushed[:3, 3])
    assert len(targets) == ReleaseConfig().follow_steps
    for T in targets:
        np.testing.assert_allclose(T[:3, 3] - reference[:3, 3], [0.0, 0.027, 0.0], atol=1e-12)
        np.testing.assert_allclose(T[:3, :3], reference[:3, :3])
    near = HOLD.copy()
    near[:3, 3] += [0.005, 0.0, 0.0]  # within the tracking error: nothing to do
    assert drive(release_targets(near, 0.078, reference=reference), lambda T, w: 0.078) == []
    assert drive(release_targets(pushed, 0.078, ReleaseConfig(follow=0.0), reference), lambda T, w: 0.078) == []


def touching(normal, clear_after):
    """A finger on the object: the hand feels 3 N along `normal` (world) until it has moved
    `clear_after` m along it from HOLD."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)

    def wrench(target):
        w = np.zeros(6)
        if (target[:3, 3] - HOLD[:3, 3]) @ normal < clear_after - 1e-9:
            w[:3] = 3.0 * normal + [0.0, 0.0, -0.5]  # the push and some of the object's weight
        return w
    return wrench


def drive_wrench(gen, wrench):
    """drive() with open fingers that stay open."""
    return drive(gen, lambda T, w: 0.078, wrench=wrench)


def test_a_finger_still_on_the_object_clears_along_the_sideways_force():
    push = touching([1.0, -1.0, 0.0], clear_after=0.010)
    cfg = ReleaseConfig()
    targets = drive_wrench(release_targets(HOLD, 0.078, cfg, HOLD, push(HOLD)), push)
    steps = (targets[0][:3, 3] - HOLD[:3, 3], targets[2][:3, 3] - HOLD[:3, 3])
    np.testing.assert_allclose(steps[0], cfg.clear_step * np.array([1, -1, 0]) / np.sqrt(2), atol=1e-12)
    np.testing.assert_allclose(steps[1], 3 * cfg.clear_step * np.array([1, -1, 0]) / np.sqrt(2), atol=1e-12)
    # three steps reach 12 mm (force gone at 10 mm), then the margin, held for 3 periods
    assert len(targets) == 3 + 3
    for T in targets[3:]:
        np.testing.assert_allclose(np.linalg.norm(T[:3, 3] - HOLD[:3, 3]), 3 * cfg.clear_step + cfg.clear_margin)
    for T in targets:
        np.testing.assert_array_equal(T[:3, :3], HOLD[:3, :3])  # the hand only translates, level
        assert T[2, 3] == HOLD[2, 3]


def test_clear_stops_at_clear_max_and_ignores_what_it_cannot_steer_by():
    stuck = touching([0.0, 1.0, 0.0], clear_after=1.0)  # never comes free
    cfg = ReleaseConfig(clear_max=0.02)
    targets = drive_wrench(release_targets(HOLD, 0.078, cfg, HOLD, stuck(HOLD)), stuck)
    assert max(np.linalg.norm(T[:3, 3] - HOLD[:3, 3]) for T in targets) == pytest.approx(0.02 + cfg.clear_margin)
    free = lambda T: np.zeros(6)  # noqa: E731
    assert drive_wrench(release_targets(HOLD, 0.078, cfg, HOLD, free(HOLD)), free) == []
    down = lambda T: np.array([0.01, 0.0, -0.5, 0.0, 0.0, 0.0])  # noqa: E731 - weight on a finger, no sideways push
    assert drive_wrench(release_targets(HOLD, 0.078, cfg, HOLD, down(HOLD)), down) == []
    assert drive_wrench(release_targets(HOLD, 0.078, cfg, HOLD, None), lambda T: None) == []  # no wrench reported
    assert drive_wrench(release_targets(HOLD, 0.078, cfg.without_moves(), HOLD, stuck(HOLD)), stuck) == []
    assert drive_wrench(release_targets(HOLD, 0.078, cfg, None, stuck(HOLD)), stuck) == []  # no reference


def test_bad_clear_settings_are_invalid_parameters():
    from skillgen_ros.core.errors import InvalidInputError
    for bad in ({"clear_step": 0.0}, {"clear_max": -0.01}, {"contact_force": float("nan")}):
        with pytest.raises(InvalidInputError) as e:
            ReleaseConfig(**bad)
        assert e.value.reason == "INVALID_PARAMETER"
