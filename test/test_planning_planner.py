"""MotionPlanner: around a wall, transfer clearance, straight retreat/approach, status codes."""

from dataclasses import replace

import numpy as np
import pytest

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.planning.collision import LINKS, AllowedContacts, AttachedObject, Box, CollisionModel
from skillgen_ros.core.planning.ik import IKSolver
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.planning.phases import line_deviation, orientation_deviation
from skillgen_ros.core.planning.planner import Mode, MotionPlanner, PlanStatus
from skillgen_ros.core.robot import A_MAX, Q_HOME, V_MAX

DOWN = np.array([1.0, 0.0, 0.0, 0.0])  # gripper z pointing down


def _box(name, xyz, half):
    T = np.eye(4)
    T[:3, 3] = xyz
    return Box(name, T, np.asarray(half, float))


@pytest.fixture(scope="module")
def setup():
    kin = PandaKinematics()
    cm = CollisionModel(kin, table_z=0.0)  # these scenes stand on a table whose top is z = 0 (the sim's: TABLE_Z)
    return kin, cm, MotionPlanner(kin, IKSolver(kin, rng=0), cm, seed=1)


def _box_points(box: Box, n: int = 7) -> np.ndarray:
    """Dense samples of a box's volume (for ground-truth checks independent of the spheres)."""
    g = np.linspace(-1, 1, n)
    P = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) * box.half_extents
    return P @ box.pose[:3, :3].T + box.pose[:3, 3]


def test_plans_around_a_wall(setup):
    kin, cm, planner = setup
    wall = _box("wall", [0.5, 0.0, 0.25], [0.12, 0.015, 0.25])
    cm.set_boxes([wall])
    cm.set_point_cloud(np.empty((0, 3)))
    start = planner.ik.solve(Pose([0.5, -0.25, 0.15], DOWN).matrix(), seed_q=Q_HOME, timeout=0.5).solutions[0]
    res = planner.plan(start, Pose([0.5, 0.25, 0.15], DOWN), Mode.TRANSIT, timeout=5.0)
    assert res.status is PlanStatus.SUCCESS, res.message
    # a straight joint-space move would hit the wall: the planner had to go around
    assert cm.in_collision(start + np.linspace(0, 1, 50)[:, None] * (res.joint_path[-1] - start)).any()
    # dense check of the timed trajectory with a finer resolution than the planner used
    dense = np.vstack([a + np.linspace(0, 1, 40)[:, None] * (b - a)
                       for a, b in zip(res.trajectory.positions[:-1], res.trajectory.positions[1:])])
    assert not cm.in_collision(dense).any()
    # the EE itself never enters the (unpadded) wall
    ee = kin.fk_batch(dense)[:, :3, 3]
    assert not wall.contains(ee).any()
    np.testing.assert_allclose(kin.fk(res.joint_path[-1])[:3, 3], [0.5, 0.25, 0.15], atol=1e-4)
    # within the Panda's limits
    assert np.all(np.abs(res.trajectory.velocities) <= V_MAX + 1e-6)
    assert np.all(np.abs(res.trajectory.accelerations) <= A_MAX + 1e-6)
    assert {"ik", "retreat", "transit", "approach", "parameterize", "total"} <= res.timings.keys()


def test_retreat_and_approach_are_straight_5cm_moves_along_gripper_z(setup):
    kin, cm, planner = setup
    cm.set_boxes([])
    start = planner.ik.solve(Pose([0.45, -0.2, 0.1], DOWN).matrix(), seed_q=Q_HOME, timeout=0.5).solutions[0]
    target = Pose([0.4, 0.2, 0.12], DOWN)
    res = planner.plan(start, target, Mode.TRANSIT, timeout=5.0)
    assert res.ok, res.message
    seg = {name: (a, b) for name, a, b in res.segments}
    for phase, sign in (("retreat", -1.0), ("approach", +1.0)):
        a, b = seg[phase]
        Q = res.joint_path[a:b + 1]
        dense = np.vstack([p + np.linspace(0, 1, 25)[:, None] * (q - p) for p, q in zip(Q[:-1], Q[1:])])
        T0, T1 = kin.fk(Q[0]), kin.fk(Q[-1])
        assert line_deviation(kin, T0, dense).max() < 1.5e-3  # straight within 1.5 mm
        step = T1[:3, 3] - T0[:3, 3]
        np.testing.assert_allclose(step, sign * 0.05 * T0[:3, 2], atol=1e-4)  # 5 cm along z
        assert orientation_deviation(kin, T0, dense).max() < 1.5e-3  # orientation held
    np.testing.assert_allclose(kin.fk(res.joint_path[-1])[:3, 3], target.position, atol=1e-4)


def test_transfer_keeps_the_attached_object_clear(setup):
    kin, cm, planner = setup
    block = _box("block", [0.5, 0.0, 0.15], [0.1, 0.04, 0.15])
    cm.set_boxes([block])
    start = planner.ik.solve(Pose([0.5, -0.25, 0.25], DOWN).matrix(), seed_q=Q_HOME, timeout=0.5).solutions[0]
    below = np.eye(4)
    below[2, 3] = 0.08  # a 10 cm tall object hanging below the fingers
    obj = AttachedObject.from_box("bar", [0.02, 0.02, 0.05], below)
    res = planner.plan(start, Pose([0.5, 0.25, 0.25], DOWN), Mode.TRANSFER, attached=obj,
                       timeout=5.0)
    assert res.ok, res.message
    assert "transfer" in res.timings
    dense = np.vstack([a + np.linspace(0, 1, 20)[:, None] * (b - a)
                       for a, b in zip(res.trajectory.positions[:-1], res.trajectory.positions[1:])])
    local = _box_points(Box("bar", below, [0.02, 0.02, 0.05]))
    for T in kin.fk_batch(dense):
        pts = local @ T[:3, :3].T + T[:3, 3]
        assert not block.contains(pts).any()
        assert np.all(pts[:, 2] > 0.0)  # and above the table
    cm.set_boxes([])


def test_bad_requests_get_codes_fast(setup):
    kin, cm, planner = setup
    cube = _box("cube", [0.5, 0.0, 0.05], [0.05, 0.05, 0.05])
    cm.set_boxes([cube])
    cases = [
        (Pose([2.0, 0.0, 0.5], DOWN), PlanStatus.IK_FAILED),
        (Pose([0.5, 0.0, 0.05], DOWN), PlanStatus.GOAL_IN_COLLISION),  # inside the cube
        (Pose([np.nan, 0.0, 0.3], DOWN), PlanStatus.INVALID_REQUEST),
        (Pose([0.5, 0.0, 0.3], [0.0, 0.0, 0.0, 2.0]), PlanStatus.INVALID_REQUEST),
    ]
    for target, expected in cases:
        res = planner.plan(Q_HOME, target, Mode.TRANSIT, timeout=5.0)
        assert res.status is expected, (target, res.message)
        assert "transit" not in res.timings, res.timings  # failed before any search (was: < 1 s wall)
    assert planner.plan(Q_HOME, Pose([0.5, 0, 0.3], DOWN), Mode.TRANSFER).status is PlanStatus.INVALID_REQUEST
    # a start inside an obstacle
    cm.set_boxes([_box("blob", kin.link_poses(Q_HOME)["panda_link4"][:3, 3], [0.05] * 3)])
    assert planner.plan(Q_HOME, Pose([0.4, 0.2, 0.3], DOWN)).status is PlanStatus.START_IN_COLLISION
    cm.set_boxes([])
    # an empty cloud means no obstacles
    cm.set_point_cloud(np.empty((0, 3)))
    assert planner.plan(Q_HOME, Pose([0.4, 0.2, 0.3], DOWN)).ok


def test_grasp_approach_may_touch_only_the_manipulated_object(setup):
    kin, cm, planner = setup
    cube = _box("cube", [0.5, 0.1, 0.025], [0.025, 0.025, 0.025])
    other = _box("other", [0.5, -0.2, 0.05], [0.03, 0.03, 0.05])
    cm.set_boxes([cube, other])
    cm.set_point_cloud(np.empty((0, 3)))
    grasp = Pose([0.5, 0.1, 0.03], DOWN)  # EE between the fingertips, inside the cube's box
    assert planner.plan(Q_HOME, grasp).status is PlanStatus.GOAL_IN_COLLISION
    res = planner.plan(Q_HOME, grasp, manipulated="cube", timeout=5.0)
    assert res.ok, res.message
    # contact was tolerated on the approach only: the transit never touches the cube
    a, b = next((a, b) for name, a, b in res.segments if name == "transit")
    Q = np.vstack([cm.motion_samples(p, q) for p, q in zip(res.joint_path[a:b], res.joint_path[a + 1:b + 1])])
    assert not cm.in_collision(Q).any()
    # another object is never allowed
    inside_other = Pose([0.5, -0.2, 0.06], DOWN)
    assert planner.plan(Q_HOME, inside_other, manipulated="cube").status is PlanStatus.GOAL_IN_COLLISION
    cm.set_boxes([])


def test_transfer_lifts_off_and_places_onto_supports(setup):
    """Pick a cube resting on the table, place it on top of a block: the held cube may touch the
    table while lifting and the block while placing, nothing else."""
    kin, cm, planner = setup
    cube_T = np.eye(4)
    cube_T[:3, 3] = (0.45, -0.2, 0.025)
    block = _box("block", [0.45, 0.2, 0.05], [0.04, 0.04, 0.05])
    cm.set_boxes([block])
    grasp = Pose(cube_T[:3, 3], DOWN)
    q0 = planner.ik.solve(grasp.matrix(), seed_q=Q_HOME, timeout=0.5).solutions[0]
    T_ee_obj = np.linalg.inv(kin.fk(q0)) @ cube_T
    cube = AttachedObject.from_box("cube", [0.025] * 3, T_ee_obj)
    place = Pose([0.45, 0.2, 0.1 + 0.025], DOWN)  # cube centre on the block's top
    # without the allowance the cube resting on the table is a collision at the start
    strict = planner.plan(q0, place, Mode.TRANSFER, attached=cube, start_support=None, goal_support=None)
    assert strict.status is PlanStatus.START_IN_COLLISION, strict.message
    res = planner.plan(q0, place, Mode.TRANSFER, attached=cube, start_support="table",
                       goal_support="block", timeout=5.0)
    assert res.ok, res.message
    np.testing.assert_allclose((kin.fk(res.joint_path[-1]) @ T_ee_obj)[:3, 3], [0.45, 0.2, 0.125], atol=1e-4)
    a, b = next((a, b) for name, a, b in res.segments if name == "transfer")
    Q = np.vstack([cm.motion_samples(p, q, cube) for p, q in zip(res.joint_path[a:b], res.joint_path[a + 1:b + 1])])
    assert not cm.in_collision(Q, attached=cube).any()  # in transfer: no contact at all
    cm.set_boxes([])


def test_the_papers_rule_lets_retreat_and_approach_touch_manipulated_objects_only(setup):
    """The paper (Appendix, Motion Planning) ignores robot/manipulated-object and manipulated-object/
    environment contacts on the retreat and approach: a cube grasped with the hand against a second
    movable block starts in collision without `movable` and plans with it; the same block as a
    fixture (not in `movable`) still stops it; the transfer itself stays contact-free."""
    kin, cm, planner = setup
    cube_T = np.eye(4)
    cube_T[:3, 3] = (0.45, -0.2, 0.025)
    block = _box("block", [0.45, -0.2 + 0.025 + 0.011, 0.015], [0.01, 0.01, 0.015])  # beside the cube
    cm.set_boxes([block])
    q0 = planner.ik.solve(Pose(cube_T[:3, 3], DOWN).matrix(), seed_q=Q_HOME, timeout=0.5).solutions[0]
    assert cm.in_collision(q0[None])[0]  # the hand itself touches the block
    cube = AttachedObject.from_box("cube", [0.025] * 3, np.linalg.inv(kin.fk(q0)) @ cube_T)
    place = Pose([0.45, 0.2, 0.025], DOWN)
    kw = dict(attached=cube, timeout=5.0, extras=False)
    for movable in (None, (), ("cube",)):  # named supports only; the block a fixture
        res = planner.plan(q0, place, Mode.TRANSFER, movable=movable, **kw)
        assert res.status is PlanStatus.START_IN_COLLISION, (movable, res.message)
    paper = planner.plan(q0, place, Mode.TRANSFER, movable=("block", "cube"), **kw)
    assert paper.ok, paper.message
    a, b = next((a, b) for name, a, b in paper.segments if name == "transfer")
    Q = np.vstack([cm.motion_samples(p, q, cube) for p, q in zip(paper.joint_path[a:b], paper.joint_path[a + 1:b + 1])])
    assert not cm.in_collision(Q, attached=cube).any()
    # the held object may touch anything (a fixture's low ledge beside it) under the rule, only its support without
    ledge_T = np.eye(4)
    ledge_T[:3, 3] = (0.45 + 0.029, -0.2, 0.005)
    cm.set_boxes([Box("ledge", ledge_T, np.array([0.003, 0.02, 0.005]))])
    assert not cm.in_collision(q0[None])[0]
    assert cm.in_collision(q0[None], cube, AllowedContacts("table", support="table"))[0]
    assert not cm.in_collision(q0[None], cube, AllowedContacts("table", support="table", held_free=True))[0]
    # a transit whose goal (the grasp) puts the hand against the movable block
    cm.set_boxes([block, _box("cube", cube_T[:3, 3], [0.025] * 3)])
    goal = Pose(cube_T[:3, 3], DOWN)
    assert planner.plan(Q_HOME, goal, manipulated="cube", extras=False).status is PlanStatus.GOAL_IN_COLLISION
    assert planner.plan(Q_HOME, goal, manipulated="cube", extras=False, movable=("block", "cube")).ok
    cm.set_boxes([])


def test_start_with_the_hand_against_a_fixture_backs_out_along_the_retreat(setup):
    """A replayed skill can leave the fingertips touching a fixture; the straight retreat may pass
    through that contact, but must end clear, and nothing else is tolerated."""
    kin, cm, planner = setup
    q0 = planner.ik.solve(Pose([0.5, 0.0, 0.12], DOWN).matrix(), seed_q=Q_HOME, timeout=0.5).solutions[0]
    S = cm.sphere_world(q0)
    hand = cm.robot.group == LINKS.index("panda_hand")
    low = float((S[hand, 2] - S[hand, 3]).min())
    block = _box("block", [0.5, 0.0, (low + 0.004) / 2], [0.06, 0.06, (low + 0.004) / 2])  # 4 mm into the fingertips
    cm.set_boxes([block])
    try:
        assert cm.in_collision(q0[None])[0]
        target = Pose([0.4, 0.3, 0.3], DOWN)
        res = planner.plan(q0, target, timeout=5.0)
        assert res.ok, res.message
        assert "touches block" in res.message
        off = planner.plan(q0, target, timeout=2.0, extras=False)  # the paper profile: no back-out
        assert off.status is PlanStatus.START_IN_COLLISION and "extras off" in off.message
        a, b = next((a, b) for name, a, b in res.segments if name == "retreat")
        rise = kin.fk(res.joint_path[b])[2, 3] - kin.fk(q0)[2, 3]
        assert rise == pytest.approx(planner.retreat_distance, abs=2e-3)  # straight up, 5 cm
        assert res.retreat_length == pytest.approx(rise, abs=1e-3)  # what the execution check allows
        assert not cm.in_collision(res.joint_path[b:]).any()
        # the arm inside the block is not a hand contact: still refused
        cm.set_boxes([block, _box("pillar", kin.link_poses(q0)["panda_link4"][:3, 3], [0.03, 0.03, 0.03])])
        assert planner.plan(q0, target, timeout=2.0).status is PlanStatus.START_IN_COLLISION
    finally:
        cm.set_boxes([])


def test_a_wrist_beside_the_released_objects_support_backs_out_along_the_retreat(setup):
    """After a place that pushed a nut down its peg, the wrist (panda_link7) can sit inside the
    spheres' padding of the peg's top. No self-motion moves link7 (it is rigid with the hand), so
    the null-space escape cannot help: the wrist may touch what was just released and its support
    on the retreat, as the hand may, and nothing else."""
    kin, cm, planner = setup
    q0 = planner.ik.solve(Pose([0.5, 0.0, 0.12], DOWN).matrix(), seed_q=Q_HOME, timeout=5.0).solutions[0]
    S = cm.sphere_world(q0)
    d = kin.fk(q0)[:3, 0]  # across the fingers' axis: the hand is narrow there
    wrist = np.flatnonzero(cm.robot.group == LINKS.index("panda_link7"))
    i = wrist[np.argmax(S[wrist, :3] @ d + S[wrist, 3])]
    half = 0.01
    top = _box("peg", S[i, :3] + d * (S[i, 3] + cm.margin - 0.0028 + half), [half] * 3)  # 2.2 mm from the sphere
    cm.set_boxes([top])
    try:
        hand_only = AllowedContacts(hand_object=("nut", "peg"))
        assert cm.in_collision(q0[None], allow=hand_only)[0]
        assert not cm.in_collision(q0[None], allow=replace(hand_only, wrist=True))[0]
        target = Pose([0.4, 0.3, 0.3], DOWN)
        res = planner.plan(q0, target, Mode.TRANSIT, released="nut", released_support="peg", timeout=5.0)
        assert res.ok, res.message
        assert "wrist touches nut, peg" in res.message
        a, b = next((a, b) for name, a, b in res.segments if name == "retreat")
        np.testing.assert_allclose(res.joint_path[a], q0, atol=1e-9)  # no self-motion first
        rise = kin.fk(res.joint_path[b])[2, 3] - kin.fk(q0)[2, 3]
        assert rise == pytest.approx(planner.retreat_distance, abs=2e-3)
        assert not cm.in_collision(res.joint_path[b:]).any()
        # the peg is not what was released, nor its support: refused; so is the paper profile
        other = planner.plan(q0, target, Mode.TRANSIT, released="nut", timeout=2.0)
        assert other.status is PlanStatus.START_IN_COLLISION
        off = planner.plan(q0, target, Mode.TRANSIT, released="nut", released_support="peg", timeout=2.0, extras=False)
        assert off.status is PlanStatus.START_IN_COLLISION and "extras off" in off.message
        # point-cloud mode: the box only localises the peg's points, which the wrist may then touch
        cm.set_boxes([top], as_obstacles=False)
        assert cm.set_point_cloud(_box_points(top)) > 0
        assert cm.in_collision(q0[None], allow=hand_only)[0]
        assert not cm.in_collision(q0[None], allow=replace(hand_only, wrist=True))[0]
        assert cm.in_collision(q0[None], allow=AllowedContacts(wrist=True))[0]  # nothing named: still a hit
    finally:
        cm.set_point_cloud(np.zeros((0, 3)))
        cm.set_boxes([])


def test_start_with_the_elbow_grazing_an_obstacle_escapes_in_the_null_space(setup):
    """The arm's self-motion (7 joints, 6-D pose) moves the elbow off an obstacle it grazes while
    the hand, and anything it holds, stays where it is."""
    kin, cm, planner = setup
    q0 = np.array(Q_HOME, float)
    S = cm.sphere_world(q0)
    i = int(np.argmax(S[:, 1] + S[:, 3]))  # the robot's outermost point towards +y
    assert cm.robot.group[i] < LINKS.index("panda_hand")  # an arm link, not the hand
    c, r = S[i, :3], S[i, 3]
    nick = _box("post", c + [0.0, r - 0.003 + 0.005, 0.0], [0.005, 0.005, 0.005])  # 3 mm into it
    cm.set_boxes([nick])
    try:
        assert cm.in_collision(q0[None])[0]
        res = planner.plan(q0, Pose([0.45, -0.25, 0.3], DOWN), timeout=5.0)
        assert res.ok, res.message
        assert "null space" in res.message
        off = planner.plan(q0, Pose([0.45, -0.25, 0.3], DOWN), timeout=2.0, extras=False)
        assert off.status is PlanStatus.START_IN_COLLISION and "extras off" in off.message
        k = next(i for i, q in enumerate(res.joint_path) if not cm.in_collision(q[None])[0])
        assert k >= 1 and np.abs(res.joint_path[k] - q0).max() <= 0.5
        T0 = kin.fk(q0)
        for q in res.joint_path[: k + 1]:  # the hand stays put while the elbow moves away
            np.testing.assert_allclose(kin.fk(q)[:3, 3], T0[:3, 3], atol=1e-3)
    finally:
        cm.set_boxes([])


def test_a_wrist_at_its_limit_moves_in_the_null_space_before_the_retreat(setup):
    """After a low grasp the wrist can sit at joint 7's limit, where IK loses the straight retreat
    within 1.5 cm -- too little to lift the held object off the table. The arm first moves along
    its self-motion (the hand and the object stay put), then retreats the full 5 cm from there."""
    kin, cm, planner = setup
    cm.set_boxes([])
    q0 = np.array([0.1788, 0.6052, -0.4054, -2.2257, 0.7057, 2.7423, kin.upper[6]])
    T0 = kin.fk(q0)
    assert T0[2, 3] == pytest.approx(0.015, abs=1e-3) and T0[2, 2] < -0.99  # low, pointing down
    plate = AttachedObject.from_box("plate", [0.03, 0.03, 0.012], np.eye(4), spacing=0.02)
    assert cm.in_collision(q0[None], plate)[0]  # resting on the table
    target = Pose([0.59, 0.037, 0.18], [0.7147, 0.6994, 0.0, 0.0])
    res = planner.plan(q0, target, Mode.TRANSFER, attached=plate, start_support="table", timeout=5.0)
    assert res.ok, res.message
    assert "null space first" in res.message
    off = planner.plan(q0, target, Mode.TRANSFER, attached=plate, start_support="table", timeout=2.0, extras=False)
    assert off.status is PlanStatus.START_IN_COLLISION and "extras off" in off.message
    a, b = next((a, b) for name, a, b in res.segments if name == "retreat")
    ee = kin.fk_batch(res.joint_path[a:b + 1])[:, :3, 3]
    k = int(np.argmax(np.linalg.norm(ee - T0[:3, 3], axis=1) > 1e-3))  # where the line starts
    assert k >= 2 and np.abs(res.joint_path[k - 1] - q0).max() <= 0.5
    np.testing.assert_allclose(ee[:k], np.repeat(T0[None, :3, 3], k, 0), atol=1e-3)  # self-motion
    assert ee[-1, 2] - T0[2, 3] == pytest.approx(planner.retreat_distance, abs=3e-3)  # then 5 cm back
    assert not cm.in_collision(res.joint_path[b:b + 1], plate)[0]


def test_a_goal_ik_cannot_back_out_of_straight_gets_a_dropped_approach_with_extras_only(setup):
    """issue 19's planning bench: IK_FAILED goals (seed 1 #19) are reachable, but IK loses the 5 cm
    line back from every goal solution. With extras the transit ends at the goal itself."""
    kin, cm, _ = setup
    cm.set_boxes([])
    cm.set_point_cloud(np.empty((0, 3)))
    start = np.array([0.2162, -0.3319, -0.3331, -2.2596, -0.3379, 2.0187, -2.1888])
    goal = Pose(np.array([0.62168, 0.12312, 0.32122]), np.array([0.65664, -0.69719, -0.17697, 0.22680]))
    paper = MotionPlanner(kin, IKSolver(kin, rng=0), cm, seed=1).plan(start, goal, Mode.TRANSIT, extras=False)
    assert paper.status is PlanStatus.IK_FAILED and "straight approach" in paper.message
    r = MotionPlanner(kin, IKSolver(kin, rng=0), cm, seed=1).plan(start, goal, Mode.TRANSIT)
    assert r.ok, r.message
    assert "approach dropped" in r.message or "approach shortened" in r.message
    T = kin.fk(r.joint_path[-1])
    assert np.linalg.norm(T[:3, 3] - goal.position) < 2e-3
    assert not cm.in_collision(r.joint_path[-1])[0]
