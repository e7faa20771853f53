"""Articulated obstacles (core/planning/articulated.py): Coffee's lid as a planner box posed by its hinge
value. The planner refuses a goal inside the closed lid and plans to it with the lid open; the path it
finds goes through where the closed lid would be."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.planning.articulated import link_boxes, object_boxes
from skillgen_ros.core.planning.collision import CollisionModel
from skillgen_ros.core.planning.ik import IKSolver
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.planning.planner import Mode, MotionPlanner, PlanStatus
from skillgen_ros.core.robot import Q_HOME, TABLE_Z
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.core.tasks import get_task

M = get_task("Coffee").object("coffee_machine")
LID = "coffee_machine/lid"
# Coffee D0's machine: (0, -0.1) from the table centre, yaw -30 deg (coffee.py _get_initial_placement_bounds)
POSE = Pose([0.56, -0.1, TABLE_Z + M.half_extents[2]], Rotation.from_euler("z", -np.pi / 6).as_quat())


@pytest.fixture(scope="module")
def setup():
    kin = PandaKinematics()
    cm = CollisionModel(kin, table_z=TABLE_Z)
    return kin, cm, MotionPlanner(kin, IKSolver(kin, rng=0), cm, seed=1)


def test_lid_box_follows_the_joint_value():
    closed, = link_boxes(M, POSE, {LID: 0.0})
    assert closed.name == "coffee_machine"
    np.testing.assert_allclose(closed.pose[:3, 3], POSE.rotation.apply(C.LID_POS) + POSE.position, atol=1e-12)
    np.testing.assert_allclose(closed.half_extents, C.LID_HALF)
    opened, = link_boxes(M, POSE, {LID: 2 * np.pi / 3})
    hinge = POSE.rotation.apply(M.joints[0].origin) + POSE.position
    assert opened.pose[2, 3] - hinge[2] == pytest.approx(C.LID_HALF[1] * np.sin(2 * np.pi / 3))
    # no value in the scene: the spec's reset value (open); all boxes = the base's parts + the lid
    assert np.array_equal(link_boxes(M, POSE)[0].pose, opened.pose)
    assert len(object_boxes(M, POSE, {LID: 0.0})) == len(M.parts) + 1


def test_planner_refuses_the_closed_lid_and_plans_through_the_open_one(setup):
    kin, cm, planner = setup
    # the hand pointing down over the pod holder, at the closed lid's mid-height (the insertion's way in)
    down = (POSE.rotation * Rotation.from_euler("z", np.pi / 2) * Rotation.from_euler("x", np.pi)).as_quat()
    goal = Pose(POSE.rotation.apply([C.HOLDER_POS[0], C.HOLDER_POS[1], C.LID_POS[2]]) + POSE.position, down)
    cm.set_point_cloud(np.empty((0, 3)))

    def boxes(angle):
        return object_boxes(M, POSE, {LID: angle})
    cm.set_boxes(boxes(0.0))
    closed = planner.plan(Q_HOME, goal, Mode.TRANSIT, timeout=5.0)
    assert closed.status is PlanStatus.GOAL_IN_COLLISION, closed.message
    cm.set_boxes(boxes(2 * np.pi / 3))
    opened = planner.plan(Q_HOME, goal, Mode.TRANSIT, timeout=5.0)
    assert opened.status is PlanStatus.SUCCESS, opened.message
    np.testing.assert_allclose(kin.fk(opened.joint_path[-1])[:3, 3], goal.position, atol=1e-4)
    assert not cm.in_collision(opened.trajectory.positions).any()
    cm.set_boxes(boxes(0.0))   # the same motion with the lid shut runs into it
    assert cm.in_collision(opened.trajectory.positions).any()
