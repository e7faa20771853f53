"""Coffee's shipped source demos (bags/Coffee, made by `skillgen demos make --task Coffee`): ten annotated D0 bags
from ten scenes with a 3-demo subset, skills as the task lists them, and one replayed open loop in the current sim
to success with the lid shut (the full 10-demo replay: bench/source_demos; measured 10/10)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from skillgen_ros.cli.demos import subset_paths
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.skills import bag_demos as B
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.core.tasks import get_task

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


def test_a_shipped_demo_replays_open_loop_to_success_with_the_lid_shut():
    from skillgen_ros.core.sim import SimWorld

    path = subset_paths(BAGS, "all")[0]
    reader = B.open_bag(path)
    scene, arrays = B.read_scene(reader), B.read_demo_arrays(path, reader)
    world = SimWorld()
    try:
        world.reset(scene.task, scene.variant, scene.seed)
        assert not world.task_success()
        for p, q, g in zip(arrays.action_positions, arrays.action_quaternions, arrays.gripper):
            world.step(Pose(p, q), float(g))
        assert world.task_success(), f"{path} no longer replays: `skillgen demos make --task Coffee --force`"
        assert world.object_joints()["coffee_machine/lid"] < C.LID_CLOSED_TOLERANCE
    finally:
        world.close()
