"""Coffee Prep's shipped source demos (bags/CoffeePreparation, made by `skillgen demos make --task CoffeePreparation`
with the scripted demonstrator, which runs core/tasks/scripted_coffee_prep.py at each demo's pace): ten annotated
D0 bags from ten scenes with a 3-demo subset, the paper's five skills on their objects, each skill's gripper
events where the skill needs them, the annotations reproduced by `skillgen annotate`'s rules, and two of the
first three replayed open loop in the current sim to success (the full 10-demo replay: bench/source_demos)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from skillgen_ros.cli.annotate import propose, rules_for
from skillgen_ros.cli.demos import subset_paths
from skillgen_ros.core.skills import bag_demos as B
from skillgen_ros.core.tasks import coffee_prep as CP
from skillgen_ros.core.tasks import get_task

from _replay import assert_most_replay

BAGS = Path(__file__).resolve().parents[1] / "bags" / "CoffeePreparation"
TASK = get_task("CoffeePreparation")
SKILLS = [(0, "mug"), (1, "coffee_machine"), (2, "drawer"), (3, "coffee_pod"), (4, "coffee_machine")]


def _edges(g: np.ndarray) -> int:
    return int(np.count_nonzero(np.diff(np.sign(g))))


def test_ten_annotated_demos_from_ten_scenes_with_the_five_skills():
    paths = subset_paths(BAGS, "all")
    assert len(paths) == 10 and len(subset_paths(BAGS, "first3")) == 3
    demos = B.load_source_demos(paths, TASK)
    assert len({d.scene_seed for d in demos}) == 10 and {d.variant for d in demos} == {"D0"}
    assert len({d.num_steps for d in demos}) >= 7   # each demo at its own pace
    for d in demos:
        assert [(s.index, s.object_id) for s in d.skills] == SKILLS
        mug, place, drawer, pod, insert = (np.asarray(s.gripper) for s in d.skills)
        assert mug[-1] > 0 and pod[-1] > 0              # the grasps end closed
        assert place[0] > 0 and _edges(place) == 3      # the mug let go; the lid pinched and let go
        assert _edges(drawer) == 2 and drawer[-1] < 0   # the bar grasped, pulled, let go
        assert insert[0] > 0 and _edges(insert) == 1    # the pod let go; the lid push is open-handed
        assert d.skills[4].end_step == d.num_steps


def test_the_stored_annotations_are_what_the_rules_propose():
    for path in subset_paths(BAGS, "all"):
        stored = B.read_annotation(path)
        assert propose(path, TASK, rules_for(TASK.name)).skills == stored.skills, path


def test_shipped_demos_replay_open_loop_to_success():
    """Two of the first three (test/_replay.py: demo_00 does not replay on an Intel Xeon rocketlake)."""
    assert_most_replay(subset_paths(BAGS, "all"), "CoffeePreparation",
                       lambda world: world.object_joints()["drawer/slide"] < CP.DRAWER_OPEN)
