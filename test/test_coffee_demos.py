"""Coffee's shipped source demos (bags/Coffee, made by `skillgen demos make --task Coffee`): ten annotated D0 bags
from ten scenes with a 3-demo subset, skills as the task lists them, two of the first three replayed open loop in
the current sim to success with the lid shut (the full 10-demo replay: bench/source_demos; measured 10/10), and the
lid push at the pod grasp's yaw (no wrist turn after the release; bench/datagen/coffee_lid_push.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from skillgen_ros.cli.demos import subset_paths
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.skills import bag_demos as B
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.core.tasks import get_task

from _replay import assert_most_replay

BAGS = Path(__file__).resolve().parents[1] / "bags" / "Coffee"
TASK = get_task("Coffee")


def test_ten_annotated_demos_from_ten_scenes():
    paths = subset_paths(BAGS, "all")
    assert len(paths) == 10 and len(subset_paths(BAGS, "first3")) == 3
    demos = B.load_source_demos(paths, TASK)
    assert len({d.scene_seed for d in demos}) == 10 and {d.variant for d in demos} == {"D0"}
    assert len({d.num_steps for d in demos}) >= 7   # human-like: no two alike
    for d in demos:
        assert [(s.index, s.object_id) for s in d.skills] == [(0, "coffee_pod"), (1, "coffee_machine")]
        assert d.skills[1].end_step == d.num_steps   # the insertion runs through the lid push to the end
        # the grasp closes on the pod; the insertion opens the hand once (the push is open-handed)
        g = d.skills[1].gripper
        assert g[0] > 0 and np.count_nonzero(np.diff(np.sign(g))) == 1


def test_shipped_demos_replay_open_loop_to_success_with_the_lid_shut():
    """Two of the first three (test/_replay.py: an open-loop replay is not bit-exact across CPUs)."""
    assert_most_replay(subset_paths(BAGS, "all"), "Coffee",
                       lambda world: world.object_joints()["coffee_machine/lid"] < C.LID_CLOSED_TOLERANCE)


def _largest_turn_deg(yaws) -> float:
    """How far (degrees) the hand's yaw gets from its first value, each difference wrapped to [-180, 180)."""
    from skillgen_ros.core.demonstrator.motion import wrap

    return float(np.degrees(max(abs(wrap(y - yaws[0])) for y in yaws)))


def test_the_shipped_demos_push_the_lid_without_turning_the_wrist():
    """After the pod's release the hand keeps its yaw through the lid push (the demonstrator's
    LID_PUSH_TURNS = False); the earlier demos turned it 90 deg, which SkillGen replays rigidly (Coffee D2)."""
    for d in B.load_source_demos(subset_paths(BAGS, "all"), TASK):
        s = d.skills[1]
        released = int(np.flatnonzero(np.diff(np.sign(s.gripper)))[0]) + 1
        x_axes = d.ee_poses[s.start_step + released:s.end_step, :3, 0]   # the EE x axis, as motion.ee_yaw
        assert _largest_turn_deg(np.arctan2(x_axes[:, 1], x_axes[:, 0])) < 20, d.name


def test_the_no_turn_lid_push_keeps_the_grasp_yaw_and_still_shuts_the_lid(monkeypatch):
    """bench/datagen/coffee_lid_push.py's demonstrator: with LID_PUSH_TURNS off the hand pushes the lid at the
    pod grasp's yaw (no 90 deg wrist turn between the release and the push) and the demo still succeeds."""
    from skillgen_ros.core.demonstrator import ScriptedDemonstrator
    from skillgen_ros.core.demonstrator.motion import ee_yaw
    from skillgen_ros.core.sim import SimWorld

    world = SimWorld()
    try:
        yaw_turn = {}
        for turns in (True, False):
            monkeypatch.setattr(ScriptedDemonstrator, "LID_PUSH_TURNS", turns)
            run = ScriptedDemonstrator("Coffee", 100000).run(world, "D0", 1000)
            assert run.success and world.object_joints()["coffee_machine/lid"] < C.LID_CLOSED_TOLERANCE
            opened = next(i for i, s in enumerate(run.steps) if s.gripper_command < 0 and i > 0
                          and run.steps[i - 1].gripper_command > 0)
            yaws = [ee_yaw(Pose(s.target[:3], s.target[3:])) for s in run.steps[opened:]]
            yaw_turn[turns] = _largest_turn_deg(yaws)
        assert yaw_turn[True] > 60 and yaw_turn[False] < 20, yaw_turn
    finally:
        world.close()
