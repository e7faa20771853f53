"""SimWorld (pybullet): OSC step tracking, determinism, state round trip, trajectories, cameras,
contacts and bad input (the robot stays where it was)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose, rotation_angle
from skillgen_ros.core.robot import ARM_JOINTS, TABLE_Z, V_MAX
from skillgen_ros.core.sim import SimWorld, TrajectoryCode, TrajectoryError
from skillgen_ros.core.sim.camera import CameraConfig
from skillgen_ros.core.tasks import scripted


@pytest.fixture(scope="module")
def world():
    w = SimWorld(cameras=(CameraConfig("front", 96, 96), CameraConfig("wrist", 64, 64)))
    yield w
    w.close()


def test_osc_step_target_reached_within_tolerance_and_time(world):
    """A 10 cm / 10 cm / -10 cm + 30 deg yaw step: within 1.0 s (20 periods) the EE is within 5 mm and 2 deg."""
    world.reset("Square", "D0", 0)
    ee0 = world.ee_pose()
    goal = Pose(ee0.position + [0.10, 0.10, -0.10],
                (Rotation.from_euler("z", np.radians(30)) * ee0.rotation).as_quat())
    for _ in range(20):
        world.step(goal, -1.0)
    ee = world.ee_pose()
    assert np.linalg.norm(ee.position - goal.position) < 0.005
    assert np.degrees(rotation_angle(ee.rotation.as_matrix(), goal.rotation.as_matrix())) < 2.0
    # and it stays there (no drift, no oscillation)
    for _ in range(10):
        world.step(goal, -1.0)
    assert np.linalg.norm(world.ee_pose().position - goal.position) < 0.002


def test_same_seed_same_commands_identical_states():
    runs = []
    for _ in range(2):
        w = SimWorld()
        w.reset("PickPlace", "D1", 5)
        ee = w.ee_pose()
        states = [w.get_state()]
        for k in range(30):
            w.step(Pose(ee.position + [0.004 * k, -0.003 * k, -0.005 * k], ee.quaternion), 1.0 if k > 20 else -1.0)
            states.append(w.get_state())
        runs.append(np.array(states))
        w.close()
    assert np.array_equal(runs[0], runs[1])


def test_state_round_trip(world):
    world.reset("Threading", "D1", 3)
    ee = world.ee_pose()
    for _ in range(5):
        world.step(Pose(ee.position + [0.05, 0.0, 0.0], ee.quaternion), -1.0)
    s = world.get_state()
    world.reset("Threading", "D1", 3)
    world.set_state(s)
    np.testing.assert_allclose(world.get_state(), s, atol=1e-9)
    np.testing.assert_allclose(world.object_poses()["needle"].position, s[19:22], atol=1e-9)
    with pytest.raises(InvalidInputError):
        world.set_state(s[:-1])


def test_a_restored_state_keeps_the_hand_grasping():
    """The state carries the finger motors' mode: restored mid-grasp into a world whose hand was
    since opened, the fingers keep closing at the grasp's force, as the original run did."""
    w = SimWorld()
    try:
        w.reset("Square", "D0", 0)
        ee = w.ee_pose()
        for _ in range(2):
            w.step(ee, 1.0)  # closing on nothing
        s = w.get_state()
        for _ in range(6):
            w.step(ee, 1.0)
        closed = w.get_state()
        w.reset("Square", "D0", 0)
        w.step(ee, -1.0)  # a different hand mode: opening
        w.set_state(s)
        assert w.gripper_command == 1.0
        for _ in range(6):
            w.idle()
        np.testing.assert_allclose(w.finger_positions(), closed[8:10], atol=2e-4)
        assert w.gripper_width() < 0.01
        bad = s.copy()
        bad[-4] = -1.0  # a negative finger target
        with pytest.raises(InvalidInputError):
            w.set_state(bad)
        np.testing.assert_allclose(w.finger_positions(), closed[8:10], atol=2e-4)  # nothing moved
    finally:
        w.close()


def test_bad_osc_targets_rejected_robot_stays(world):
    world.reset("Square", "D0", 0)
    ee0, q0 = world.ee_pose(), world.joint_positions()
    for pos, quat, reason in (([np.nan, 0, 0.3], [1, 0, 0, 0], "INVALID_INPUT"),
                              ([0.4, np.inf, 0.3], [1, 0, 0, 0], "INVALID_INPUT"),
                              ([0.4, 0.0, 0.3], [0, 0, 0, 0.5], "INVALID_INPUT"),
                              ([3.0, 0.0, 0.3], [1, 0, 0, 0], "OUT_OF_WORKSPACE")):
        with pytest.raises(InvalidInputError) as e:
            world.step(Pose(pos, quat), -1.0)
        assert e.value.reason == reason
    with pytest.raises(InvalidInputError):
        world.step(ee0, float("nan"))
    world.idle(5)
    assert np.linalg.norm(world.ee_pose().position - ee0.position) < 1e-3
    assert np.max(np.abs(world.joint_positions() - q0)) < 1e-3
    # slightly outside the workspace box (below the table top): clamped, not rejected
    world.step(Pose([0.5, 0.0, TABLE_Z - 0.05], ee0.quaternion), -1.0)


def test_trajectory_tracking_and_rejections(world):
    world.reset("Square", "D0", 0)
    q0 = world.joint_positions()
    q1 = q0 + np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.4])
    t = np.linspace(0.0, 2.0, 21)
    s = 0.5 - 0.5 * np.cos(np.pi * t / 2.0)
    pos = q0 + s[:, None] * (q1 - q0)
    vel = (np.pi / 4.0) * np.sin(np.pi * t / 2.0)[:, None] * (q1 - q0)
    res = world.execute_joint_trajectory(t, pos, vel, goal_tolerance=0.01)
    assert res.code == TrajectoryCode.SUCCESSFUL and res.final_error < 0.01
    q_here = world.joint_positions()
    cases = [
        (dict(joint_names=list(ARM_JOINTS[:6]) + ["panda_finger_joint1"]), TrajectoryCode.INVALID_JOINTS),
        (dict(times=[0.0, 1.0, 0.5]), TrajectoryCode.INVALID_GOAL),
        (dict(velocities=np.tile(V_MAX * 1.5, (3, 1))), TrajectoryCode.INVALID_GOAL),
        (dict(positions=np.tile(q_here + 2.0, (3, 1))), TrajectoryCode.INVALID_GOAL),
    ]
    for override, code in cases:
        kw = dict(joint_names=ARM_JOINTS, times=[0.5, 1.0, 1.5], positions=np.tile(q_here, (3, 1)), velocities=None)
        kw.update(override)
        with pytest.raises(TrajectoryError) as e:
            world.start_trajectory(kw["joint_names"], kw["times"], kw["positions"], kw["velocities"])
        assert e.value.code == code
    world.idle(5)
    assert np.max(np.abs(world.joint_positions() - q_here)) < 2e-3


def test_cameras_see_the_objects(world):
    scene = world.reset("PickPlace", "D0", 2)
    for name in ("front", "wrist"):
        f = world.render(name)
        h, w = f.depth.shape
        assert f.rgb.shape == (h, w, 3) and f.points_world.shape == (h, w, 3)
        assert np.allclose(f.K[0, 2], w / 2) and np.allclose(f.K[1, 2], h / 2 - 1) and np.allclose(f.T_world_camera[3], [0, 0, 0, 1])
    pts = world.render("front").valid_points()
    for oid, p in scene.poses.items():  # some point lies on each object's bounding box
        o = next(o for o in scene.objects if o.id == oid)
        local = p.rotation.inv().apply(pts - p.position)
        assert np.any(np.all(np.abs(local) <= np.asarray(o.half_extents) + 0.005, axis=1)), oid
    # the table top is at z = TABLE_Z in the front camera's cloud
    table = pts[(np.abs(pts[:, 1]) < 0.1) & (np.abs(pts[:, 0] - 0.75) < 0.05)]
    assert len(table) and np.median(np.abs(table[:, 2] - TABLE_Z)) < 0.001


def test_depth_noise_model():
    noisy = SimWorld(cameras=(CameraConfig("front", 64, 64, noise_base=0.002, noise_quadratic=0.002, dropout=0.1),))
    clean = SimWorld(cameras=(CameraConfig("front", 64, 64),))
    for w in (noisy, clean):
        w.reset("Square", "D0", 1)
    a, b = noisy.render("front").depth, clean.render("front").depth
    both = np.isfinite(a) & np.isfinite(b)
    # dropout (10%) among the pixels that have a return (robosuite's 0.8 m table leaves some without one)
    assert 0.05 < np.mean(np.isnan(a[np.isfinite(b)])) < 0.15
    assert 0.001 < np.std(a[both] - b[both]) < 0.02
    noisy.close(), clean.close()


def test_contact_queries(world):
    world.reset("Square", "D0", 0)
    peg = world.object_poses()["square_peg"]
    assert not world.robot_in_collision_with(["square_peg", "square_nut"])
    top = world.ee_pose()
    peg_top = peg.position[2] + world.task.object("square_peg").half_extents[2]
    above = Pose([*peg.position[:2], peg_top + 0.1], top.quaternion)
    into = Pose([*peg.position[:2], peg_top - 0.03], top.quaternion)
    for _ in range(25):
        world.step(above, 1.0)
    for _ in range(25):
        world.step(into, 1.0)
    assert world.robot_in_collision_with(["square_peg"])
    assert any(c.body == "square_peg" for c in world.robot_contacts())


def test_the_hand_feels_what_it_presses_on(world):
    """ee_wrench: zero in free space; pressing down on the peg top, an upward force near the
    OSC's downward push and little torque about the EE (the contact is below it)."""
    world.reset("Square", "D0", 0)
    np.testing.assert_array_equal(world.ee_wrench(), np.zeros(6))
    peg = world.object_poses()["square_peg"]
    top = world.ee_pose()
    peg_top = peg.position[2] + world.task.object("square_peg").half_extents[2]
    for z in (peg_top + 0.1, peg_top - 0.03):
        for _ in range(25):
            world.step(Pose([*peg.position[:2], z], top.quaternion), 1.0)
    w = world.ee_wrench()
    assert w[2] > 5.0 and w[2] > 2 * np.linalg.norm(w[:2])  # the peg pushes the hand up
    assert np.linalg.norm(w[3:]) < 0.1 * w[2]  # the contact is nearly on the EE axis


def test_scripted_actions_replay_open_loop_to_success():
    """The recorded OSC stream of a scripted solution, replayed open-loop on a fresh world, succeeds."""
    w = SimWorld()
    w.reset("PickPlace", "D0", 0)
    assert not w.task_success()
    res = scripted.solve(w)
    assert res.success
    w.reset("PickPlace", "D0", 0)
    for pose, g in res.actions:
        w.step(pose, g)
    assert w.task_success()
    w.close()


def _push_fingers(world, newtons: float, periods: int, command: float) -> list[float]:
    """Step holding the EE with `command`, pushing both fingers towards (+) or away from (-) each
    other with `newtons` each (as an object wedged against them would); the width after each period."""
    step, ee, widths = world.p.stepSimulation, world.ee_pose(), []

    def pushed():
        for f, sign in zip(world.fingers, (1.0, -1.0)):  # finger joint axes: left +y, right -y (hand frame)
            world.p.applyExternalForce(world.robot, f, [0.0, -sign * newtons, 0.0], [0.0, 0.0, 0.0],
                                       world.p.LINK_FRAME)
        step()
    world.p.stepSimulation = pushed
    try:
        for _ in range(periods):
            world.step(ee, command)
            widths.append(world.gripper_width())
    finally:
        world.p.stepSimulation = step
    return widths


def test_gripper_open_is_a_move_close_is_a_grasp(world):
    """As on the Franka hand: a closing grasp keeps its force and a blocked opening move keeps
    pushing, but once open the fingers only hold lightly, so an object pressing on an open finger is
    not squeezed at full force (and dragged along by friction)."""
    world.reset("Square", "D0", 0)
    closed = _push_fingers(world, 0.0, 15, 1.0)[-1]
    assert max(_push_fingers(world, -10.0, 10, 1.0)) < closed + 0.002   # a grasp resists 10 N outwards
    assert max(_push_fingers(world, 30.0, 15, -1.0)) < 0.01             # an opening move held by 30 N stalls
    widths = _push_fingers(world, 10.0, 20, -1.0)                         # against 10 N it still opens
    assert max(widths) > 0.078 and widths[-1] < 0.06                     # then yields to the same 10 N
    _push_fingers(world, 10.0, 5, 1.0)                                    # a new command restarts the motor:
    assert max(_push_fingers(world, 10.0, 20, -1.0)) > 0.078             # open against 10 N again


@pytest.mark.parametrize("forces", [(20.0, -1.0), (20.0, 30.0), (np.inf, 2.0), (np.nan, 2.0)])
def test_bad_gripper_forces_rejected(forces):
    with pytest.raises(InvalidInputError, match="gripper_hold_force"):
        SimWorld(gripper_force=forces[0], gripper_hold_force=forces[1])


def test_an_active_trajectory_decides_at_its_end_and_waits_settle_limit_for_the_goal():
    """control.ActiveTrajectory (SimWorld.step_trajectory's verdict): undecided before the end, SUCCESSFUL
    within goal_tolerance, GOAL_TOLERANCE_VIOLATED only once settle_limit has passed without it."""
    from skillgen_ros.core.sim.commands import validate_trajectory
    from skillgen_ros.core.sim.control import ActiveTrajectory, TrajectorySampler

    from skillgen_ros.core.robot import Q_HOME

    q0 = np.array(Q_HOME)
    q1 = q0 + 0.1
    traj = validate_trajectory(ARM_JOINTS, [1.0], q1[None], q_now=q0)
    tr = ActiveTrajectory(TrajectorySampler(traj), goal_tolerance=0.01, settle_limit=0.5)
    tr.t = 0.5
    assert tr.check_goal(q1) is None and tr.progress == pytest.approx(0.5)  # not at the end yet
    tr.t = 1.2
    assert tr.check_goal(q1 + 0.05) is None  # 0.05 rad off, still settling
    done = tr.check_goal(q1 + 0.005)
    assert done.code == TrajectoryCode.SUCCESSFUL and done.final_error == pytest.approx(0.005)
    late = ActiveTrajectory(TrajectorySampler(traj), goal_tolerance=0.01, settle_limit=0.5)
    late.t = 1.5
    res = late.check_goal(q1 + 0.05)
    assert res.code == TrajectoryCode.GOAL_TOLERANCE_VIOLATED and late.progress == 1.0
