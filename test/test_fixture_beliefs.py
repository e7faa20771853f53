"""What an attempt believes about fixtures and untouched objects (grasp.LookBeliefs): the hand closing on a link
does not carry the fixture, an object no skill has acted on keeps its most confident estimate until its first
skill (a fixture's is frozen after it), a held object's start support can be a fixture's part, and a look that
misses every required object still passes when each was seen before; one that failed as a whole (no table, an
empty cloud) does not. Both envs (in-process and graph) follow the same rules."""
from __future__ import annotations

import numpy as np
import pytest

from skillgen_ros.core.generation.grasp import LookBeliefs, carriable
from skillgen_ros.core.tasks import get_task
from skillgen_ros.core.planning.articulated import support_below
from skillgen_ros.core.planning.collision import Box


def test_a_fixtures_link_does_not_carry_the_fixture():
    assert carriable("CoffeePreparation", "drawer") is None          # pulled by its handle
    assert carriable("CoffeePreparation", "coffee_machine") is None  # its lid swung open
    assert carriable("CoffeePreparation", "mug") == "mug"
    assert carriable("Square", "square_nut") == "square_nut"
    assert carriable("Square", None) is None and carriable("Square", "") is None


def test_a_fixture_keeps_its_most_confident_estimate_until_its_first_skill():
    """Coffee Prep: the drawer's first skill is 2 (open_drawer), the machine's 1. Looks before skill 0, 1 and 2
    see the drawer shut: the most confident of them wins (a flipped drawer scores lower); from skill 3 on the
    drawer is open and its belief frozen, however confident a look is. The mug (first skill 0) takes every look
    after the one before its grasp."""
    beliefs = LookBeliefs(get_task("CoffeePreparation"))
    assert {k: beliefs.first_skill[k] for k in ("drawer", "coffee_machine")} == {"drawer": 2, "coffee_machine": 1}
    flipped, right, opened = np.eye(4), np.eye(4) + 1, np.eye(4) + 2
    believed = {}
    believed.update(beliefs.update({"drawer": flipped, "mug": flipped}, {"drawer": 0.5, "mug": 0.9}, believed, 0))
    assert believed["drawer"] is flipped                                    # the first look is taken as it is
    got = beliefs.update({"drawer": right, "mug": right}, {"drawer": 0.6, "mug": 0.1}, believed, 1)
    assert got["drawer"] is right and got["mug"] is right                  # more confident; the mug was grasped
    believed.update(got)
    assert "drawer" not in beliefs.update({"drawer": flipped}, {"drawer": 0.55}, believed, 2)   # less confident
    assert "drawer" not in beliefs.update({"drawer": opened}, {"drawer": 0.99}, believed, 3)    # after its skill
    assert "coffee_machine" not in beliefs.update({"coffee_machine": opened}, {"coffee_machine": 0.99},
                                                  {"coffee_machine": right}, 2)
    assert beliefs.update({"coffee_machine": right}, {}, {}, 4) == {"coffee_machine": right}  # first seen: taken


def test_the_support_below_a_held_object_is_the_highest_top_under_it():
    tray = Box("drawer", np.block([[np.eye(3), np.array([[0.7], [0.0], [0.05]])], [np.zeros((1, 3)), np.ones((1, 1))]]),
               np.array([0.1, 0.1, 0.005]))
    shelf = Box("cabinet", np.block([[np.eye(3), np.array([[0.7], [0.0], [0.0]])], [np.zeros((1, 3)), np.ones((1, 1))]]),
                np.array([0.2, 0.2, 0.01]))
    assert support_below([shelf, tray], [0.72, 0.02, 0.08]) == "drawer"      # the tray's top, 2.5 cm below
    assert support_below([shelf, tray], [0.85, 0.0, 0.04]) == "cabinet"      # off the tray, over the shelf
    assert support_below([shelf, tray], [0.72, 0.02, 0.30]) is None          # 25 cm up: rests on nothing
    assert support_below([], [0.0, 0.0, 0.0]) is None


@pytest.fixture()
def graph_env(ros_node):
    from skillgen_interfaces.msg import SceneObject
    from skillgen_interfaces.srv import PlanToPose
    from skillgen_ros.nodes.datagen import TIMEOUTS
    from skillgen_ros.nodes.graph_env import RosGraphEnv

    env = RosGraphEnv(ros_node, TIMEOUTS, collision_source=PlanToPose.Request.SOURCE_SCENE)
    env.task = "CoffeePreparation"
    env.scene_objects = [SceneObject(id=i, type=i, half_extents=[0.05] * 3, has_pose=True)
                         for i in ("drawer", "coffee_machine", "mug", "coffee_pod")]
    return env


def _answer(status: int, ids=()):
    from skillgen_interfaces.msg import ObjectPose
    from skillgen_interfaces.srv import EstimatePoses

    r = EstimatePoses.Response(status=status, poses=[ObjectPose(id=i) for i in ids])
    r.status_name = {0: "OK", 1: "EMPTY_CLOUD", 3: "OBJECT_MISSING"}[status]
    return r


def test_the_graph_env_keeps_beliefs_when_a_look_misses_everything_seen_before(graph_env):
    from skillgen_ros.core.errors import SkillGenError

    answers = iter([_answer(3, ("drawer", "coffee_machine", "mug")), _answer(3), _answer(1)])
    graph_env._call = lambda *a, **k: next(answers)
    graph_env.set_next_skill(0)
    first = graph_env.estimate_poses()
    assert set(first) == {"drawer", "coffee_machine", "mug"}
    graph_env.set_next_skill(1)
    assert graph_env.estimate_poses() == first          # nothing seen now, everything believed: goes on
    with pytest.raises(SkillGenError) as e:             # the look failed as a whole (empty cloud)
        graph_env.estimate_poses()
    assert e.value.reason == "PERCEPTION_FAILED"


def test_an_object_no_skill_has_acted_on_keeps_its_most_confident_look(monkeypatch):
    """Nut Assembly: the round nut's first skill is 2. Looks before skills 0-2 keep the most confident of its
    estimates (the look before skill 2, taken from where the square nut's place left the arm, may not see the
    handle: one octagon step off); from skill 3 on it has been grasped and takes every look. The square nut
    (first skill 0) takes every look after the first; a peg (a fixture) keeps its best, then freezes."""
    task = get_task("NutAssembly")
    beliefs = LookBeliefs(task)
    first = {s.object_id: s.index for s in reversed(task.skills)}
    assert first["round_nut"] == 2 and first["square_nut"] == 0
    good, off, moved = np.eye(4), np.eye(4) + 1, np.eye(4) + 2
    believed = {}
    believed.update(beliefs.update({"round_nut": good, "square_nut": good}, {"round_nut": 0.8, "square_nut": 0.8},
                                   believed, 0))
    assert believed["round_nut"] is good
    got = beliefs.update({"round_nut": off, "square_nut": off}, {"round_nut": 0.6, "square_nut": 0.1}, believed, 1)
    assert "round_nut" not in got and got["square_nut"] is off          # less confident, untouched: kept
    assert "round_nut" not in beliefs.update({"round_nut": off}, {"round_nut": 0.79}, believed, 2)
    assert beliefs.update({"round_nut": off}, {"round_nut": 0.9}, believed, 2) == {"round_nut": off}  # better
    assert beliefs.update({"round_nut": moved}, {"round_nut": 0.1}, believed, 3) == {"round_nut": moved}  # grasped
    monkeypatch.setattr(LookBeliefs, "KEEP_UNTOUCHED", False)          # the old rule: every look
    old = LookBeliefs(task)
    assert old.update({"round_nut": off}, {"round_nut": 0.1}, {"round_nut": good}, 1) == {"round_nut": off}
