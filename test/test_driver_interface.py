"""Interface conformance of sim_driver and mock_driver: the same topics, types, services, actions,
the same answers to bad input, and the driver keeps running with the robot where it was.

The drivers come from the skillgen_ros.testing fixtures (mock_driver, sim_driver), as a user's
tests would start them; the checks talk to them through this file's own Client."""
from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

from skillgen_ros import rosenv  # noqa: F401

import rclpy
from rclpy.action import ActionClient, get_action_names_and_types
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

from conftest import REPO
from geometry_msgs.msg import Point, Pose as PoseMsg, PoseStamped, Quaternion, WrenchStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import String
from skillgen_interfaces.action import ExecuteTrajectory, Gripper
from skillgen_interfaces.msg import ObjectPoseArray, OscTarget
from skillgen_interfaces.srv import CaptureCameras, ResetScene, TaskSuccess
from skillgen_ros.core.robot import ARM_JOINTS, Q_HOME
from skillgen_ros.nodes.convert import trajectory_to_msg

EXPECTED_TOPICS = {
    "/joint_states": "sensor_msgs/msg/JointState",
    "/ee_pose": "geometry_msgs/msg/PoseStamped",
    "/ee_wrench": "geometry_msgs/msg/WrenchStamped",
    "/gripper_state": "skillgen_interfaces/msg/GripperState",
    "/sim/ground_truth/object_poses": "skillgen_interfaces/msg/ObjectPoseArray",
    "/object_joint_states": "sensor_msgs/msg/JointState",
    "/osc_target": "skillgen_interfaces/msg/OscTarget",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/driver/errors": "std_msgs/msg/String",
    **{f"/camera/{c}/{k}": t for c in ("front", "wrist") for k, t in
       (("points", "sensor_msgs/msg/PointCloud2"), ("image", "sensor_msgs/msg/Image"),
        ("depth", "sensor_msgs/msg/Image"), ("camera_info", "sensor_msgs/msg/CameraInfo"),
        ("pose", "geometry_msgs/msg/PoseStamped"))},
}
EXPECTED_SERVICES = {"/reset_scene": "skillgen_interfaces/srv/ResetScene",
                     "/task_success": "skillgen_interfaces/srv/TaskSuccess",
                     "/capture_cameras": "skillgen_interfaces/srv/CaptureCameras"}
EXPECTED_ACTIONS = {"/execute_trajectory": "skillgen_interfaces/action/ExecuteTrajectory",
                    "/gripper_command": "skillgen_interfaces/action/Gripper"}
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Client:
    """A small in-test client of the driver interface."""

    def __init__(self):
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node("driver_test_client", context=self.ctx)
        self.exe = rclpy.executors.SingleThreadedExecutor(context=self.ctx)
        self.exe.add_node(self.node)
        self.last: dict = {}
        self.errors: list[str] = []
        for topic, typ in (("ee_pose", PoseStamped), ("joint_states", JointState), ("/clock", Clock),
                           ("ee_wrench", WrenchStamped)):
            self.node.create_subscription(typ, topic, lambda m, t=topic: self.last.__setitem__(t, m), 10)
        self.node.create_subscription(ObjectPoseArray, "sim/ground_truth/object_poses",
                                      lambda m: self.last.__setitem__("gt", m), LATCHED)
        self.node.create_subscription(String, "driver/errors", lambda m: self.errors.append(m.data), 10)
        self.pub = self.node.create_publisher(OscTarget, "osc_target", 10)
        self.reset_cli = self.node.create_client(ResetScene, "reset_scene")
        self.success_cli = self.node.create_client(TaskSuccess, "task_success")
        self.traj = ActionClient(self.node, ExecuteTrajectory, "execute_trajectory")
        self.grip = ActionClient(self.node, Gripper, "gripper_command")

    def spin_until(self, pred, timeout=10.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.exe.spin_once(timeout_sec=0.02)
            if pred():
                return True
        return bool(pred())

    def call(self, cli, req, timeout=20.0):
        assert cli.wait_for_service(timeout_sec=timeout)
        # The first response can be lost while the server has not yet matched our response reader
        # (wait_for_service only sees the request side): resend the (idempotent) request once.
        for _ in range(2):
            fut = cli.call_async(req)
            if self.spin_until(fut.done, timeout / 2):
                return fut.result()
            cli.remove_pending_request(fut)
        raise AssertionError(f"no answer from {cli.srv_name} in {timeout} s")

    def reset(self, task, variant, seed):
        return self.call(self.reset_cli, ResetScene.Request(task=task, variant=variant, seed=seed))

    def send_goal(self, client, goal, timeout=30.0):
        assert client.wait_for_server(timeout_sec=10.0)
        fut = client.send_goal_async(goal)
        assert self.spin_until(fut.done, timeout)
        gh = fut.result()
        assert gh.accepted
        res = gh.get_result_async()
        assert self.spin_until(res.done, timeout)
        return res.result().result

    def ee(self) -> np.ndarray:
        p = self.last["ee_pose"].pose.position
        return np.array([p.x, p.y, p.z])

    def q(self) -> np.ndarray:
        return np.array(self.last["joint_states"].position[:7])

    def target(self, xyz, quat=(1.0, 0.0, 0.0, 0.0), gripper=-1.0):
        msg = OscTarget(pose=PoseMsg(position=Point(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                                     orientation=Quaternion(x=float(quat[0]), y=float(quat[1]), z=float(quat[2]),
                                                            w=float(quat[3]))), gripper=gripper)
        msg.header.frame_id = "world"
        self.pub.publish(msg)

    def close(self):
        self.exe.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


@pytest.fixture
def client(ros_domain):
    c = Client()
    yield c
    c.close()


def _graph(client):
    n = client.node
    topics = dict((k, v[0]) for k, v in n.get_topic_names_and_types())
    services = dict((k, v[0]) for k, v in n.get_service_names_and_types())
    actions = dict((k, v[0]) for k, v in get_action_names_and_types(n))
    return topics, services, actions


@pytest.mark.parametrize("exe", ["mock_driver", "sim_driver"])
def test_driver_interface_and_bad_input(exe, request, client):
    driver = request.getfixturevalue(exe)  # params/<exe>.yaml, ready: its services and actions answer
    assert driver.name == f"/{exe}" and set(driver.topics.values()) <= set(EXPECTED_TOPICS)
    # --- conformance: names and types
    assert client.spin_until(lambda: all(t in _graph(client)[0] for t in EXPECTED_TOPICS)
                             and all(s in _graph(client)[1] for s in EXPECTED_SERVICES)
                             and all(a in _graph(client)[2] for a in EXPECTED_ACTIONS), 20.0), _graph(client)
    topics, services, actions = _graph(client)
    for name, typ in EXPECTED_TOPICS.items():
        assert topics[name] == typ, name
    for name, typ in EXPECTED_SERVICES.items():
        assert services.get(name) == typ, name
    for name, typ in EXPECTED_ACTIONS.items():
        assert actions.get(name) == typ, name

    # --- reset and ground truth
    res = client.reset("Square", "D0", 0)
    assert res.success and res.reason_code == "OK"
    assert sorted(o.id for o in res.objects) == ["square_nut", "square_peg"]
    assert all(o.mesh_uri.endswith(".obj") and len(o.half_extents) == 3 and o.has_pose for o in res.objects)
    assert client.spin_until(lambda: "gt" in client.last and len(client.last["gt"].objects) == 2)
    assert client.call(client.success_cli, TaskSuccess.Request()).success is False

    # --- bad reset requests: clear reason codes
    for (task, variant, seed), reason in ((("Nope", "D0", 0), "UNKNOWN_TASK"), (("Square", "D9", 0), "UNKNOWN_VARIANT"),
                                          (("Square", "D0", -1), "INVALID_SEED"),
                                          (("Square", "D0", 2**40), "INVALID_SEED")):
        r = client.reset(task, variant, seed)
        assert not r.success and r.reason_code == reason, (task, variant, seed, r.reason_code)

    # --- lockstep: one osc_target advances exactly one control period
    assert client.spin_until(lambda: "ee_pose" in client.last and "joint_states" in client.last)
    ee0 = client.ee()
    client.last.pop("/clock", None)
    client.target(ee0)
    assert client.spin_until(lambda: "/clock" in client.last)
    t1 = client.last["/clock"].clock.sec + client.last["/clock"].clock.nanosec * 1e-9
    client.target(ee0)
    assert client.spin_until(lambda: abs(client.last["/clock"].clock.sec + client.last["/clock"].clock.nanosec * 1e-9
                                         - t1 - 0.05) < 1e-6)

    # --- bad OSC targets: NaN, inf, far outside the workspace -> reported, robot stays
    ee0, q0 = client.ee(), client.q()
    n_err = len(client.errors)
    client.target([np.nan, 0.0, 0.3])
    client.target([0.4, np.inf, 0.3])
    client.target([5.0, 0.0, 0.3])
    assert client.spin_until(lambda: len(client.errors) >= n_err + 3)
    assert "INVALID_INPUT" in client.errors[n_err] and "OUT_OF_WORKSPACE" in client.errors[n_err + 2]
    client.spin_until(lambda: False, 0.6)  # lockstep timeout may advance the world holding its command
    assert np.linalg.norm(client.ee() - ee0) < 2e-3 and np.max(np.abs(client.q() - q0)) < 5e-3

    # --- bad trajectories: wrong joint names, non-monotonic times, over-limit velocities
    q = client.q()
    bad = [
        (trajectory_to_msg(["a", "b", "c", "d", "e", "f", "g"], [0.5], [q]), ExecuteTrajectory.Result.INVALID_JOINTS),
        (trajectory_to_msg(ARM_JOINTS, [0.5, 0.4], [q, q]), ExecuteTrajectory.Result.INVALID_GOAL),
        (trajectory_to_msg(ARM_JOINTS, [0.5], [q], [np.full(7, 10.0)]), ExecuteTrajectory.Result.INVALID_GOAL),
        (trajectory_to_msg(ARM_JOINTS, [0.05], [q + 0.5]), ExecuteTrajectory.Result.INVALID_GOAL),
    ]
    for traj, code in bad:
        r = client.send_goal(client.traj, ExecuteTrajectory.Goal(trajectory=traj))
        assert r.error_code == code, (r.error_code, r.error_string)
    assert np.max(np.abs(client.q() - q0)) < 5e-3  # each was refused before it started: nothing moved

    # --- a valid trajectory and gripper command succeed
    q_goal = np.array(Q_HOME) + np.array([0.1, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0])
    r = client.send_goal(client.traj, ExecuteTrajectory.Goal(trajectory=trajectory_to_msg(ARM_JOINTS, [1.0], [q_goal])))
    assert r.error_code == ExecuteTrajectory.Result.SUCCESSFUL, r.error_string
    assert client.spin_until(lambda: np.max(np.abs(client.q() - q_goal)) < 0.02)
    g = client.send_goal(client.grip, Gripper.Goal(position=0.04, max_effort=20.0))
    assert abs(g.width - 0.04) < 0.005 and g.reached_goal
    assert driver.process.alive, "driver died"


def test_mock_driver_starts_without_pybullet(mock_driver):
    """The mock comes up and never imports pybullet. How fast it starts (goal: under 1 s) is measured
    in bench/sim_driver (`mock_driver_startup`), not here: a timed test fails on a loaded machine."""
    assert "mock_driver up" in mock_driver.output()
    code = ("import sys; from skillgen_ros.nodes import mock_driver, driver_base; from skillgen_ros.core.sim import mock;"
            "mock.MockWorld().reset('Square', 'D0', 0); print('pybullet' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert out.stdout.strip() == "False", out.stdout + out.stderr


def _stamp(t) -> float:
    return t.sec + t.nanosec * 1e-9


@pytest.mark.mock_driver(camera_hz=0.0, lockstep_timeout_s=2.0)  # not 30: the fixture waits for a first idle period
def test_capture_cameras_and_live_camera_rate(mock_driver, client):
    """camera_hz 0: frames only on reset and on capture_cameras (stamped as the answer says);
    camera_hz may be raised and lowered at run time; bad or read-only parameter changes are refused
    with a reason; a driver without cameras answers NO_CAMERAS. The driver keeps running."""
    clouds = []
    client.node.create_subscription(PointCloud2, "camera/front/points", clouds.append, qos_profile_sensor_data)
    capture = client.node.create_client(CaptureCameras, "capture_cameras")
    params = AsyncParameterClient(client.node, "mock_driver")
    assert client.spin_until(lambda: client.node.count_publishers("camera/front/points") > 0, 20.0)
    assert capture.wait_for_service(timeout_sec=20.0) and params.wait_for_services(timeout_sec=20.0)
    assert client.reset("Square", "D0", 0).success
    assert client.spin_until(lambda: len(clouds) >= 1)  # the reset's frame
    assert client.spin_until(lambda: "ee_pose" in client.last)
    n = len(clouds)
    poses = []
    client.node.create_subscription(PoseStamped, "ee_pose", poses.append, 50)

    def step_seen() -> bool:  # one target, one lockstep period: periods observed, not waited out
        client.target(client.ee())
        return len(poses) >= 4
    assert client.spin_until(step_seen, 20.0)
    assert len(clouds) == n, "camera_hz 0 must not publish periodic frames"

    r = client.call(capture, CaptureCameras.Request())
    assert r.success and r.reason_code == "OK"
    assert client.spin_until(lambda: len(clouds) > n and _stamp(clouds[-1].header.stamp) == _stamp(r.stamp))

    def set_param(name, value):
        fut = params.set_parameters([Parameter(name, value=value)])
        assert client.spin_until(fut.done)
        return fut.result().results[0]

    assert set_param("camera_hz", 20.0).successful
    n = len(clouds)
    for _ in range(3):
        client.target(client.ee())
    assert client.spin_until(lambda: len(clouds) >= n + 3), "camera_hz 20 at 20 Hz control: a frame per period"
    bad = set_param("camera_hz", -1.0)
    assert not bad.successful and "camera_hz" in bad.reason
    ro = set_param("control_hz", 50.0)
    assert not ro.successful and "read-only" in ro.reason
    assert set_param("camera_hz", 0.0).successful
    assert mock_driver.process.alive, "driver died"


@pytest.mark.mock_driver(cameras=[""])
def test_capture_without_cameras_says_so(mock_driver, client):
    capture = client.node.create_client(CaptureCameras, "capture_cameras")
    assert capture.wait_for_service(timeout_sec=20.0)
    r = client.call(capture, CaptureCameras.Request())
    assert not r.success and r.reason_code == "NO_CAMERAS"


def _mock_after_reset(start_node, client, *params):
    """A lockstep mock driver (no timeout holds) reset to Square D0: (process, state_history client,
    the joint_states seen so far, a stamp just before the reset's state)."""
    from builtin_interfaces.msg import Time
    from skillgen_interfaces.srv import StateHistory

    proc = start_node("mock_driver", "--ros-args", "--params-file", str(REPO / "params" / "mock_driver.yaml"),
                      "-p", "lockstep_timeout_s:=30.0", *params)
    hist = client.node.create_client(StateHistory, "state_history")
    assert hist.wait_for_service(timeout_sec=20.0)
    seen = []
    client.node.create_subscription(JointState, "joint_states", seen.append, 100)
    assert client.reset("Square", "D0", 0).success
    assert client.spin_until(lambda: len(seen) >= 1)
    t = seen[-1].header.stamp
    before = Time(sec=t.sec, nanosec=t.nanosec - 1) if t.nanosec else Time(sec=t.sec - 1, nanosec=999_999_999)
    return proc, hist, seen, before


def test_state_history_answers_each_published_period(start_node, client):
    """state_history: every published state in order, stamped as its joint_states, with what drove
    it and the world's object poses; an expired start or a span over a reset answers with a reason."""
    from skillgen_interfaces.srv import StateHistory

    proc, hist, seen, before = _mock_after_reset(start_node, client, "-p", "history_periods:=8")
    n0 = len(seen)
    for k in range(3):
        client.target([0.5, 0.0, 0.3])
        assert client.spin_until(lambda: len(seen) >= n0 + k + 1)
    r = client.call(hist, StateHistory.Request(after=before))
    assert r.success, r.message
    assert [_stamp(t) for t in r.stamps] == [_stamp(m.header.stamp) for m in seen[-4:]]
    assert list(r.kinds) == [StateHistory.Response.RESET] + [StateHistory.Response.OSC_TARGET] * 3
    np.testing.assert_array_equal(np.reshape(r.joint_positions, (4, 7)), [m.position[:7] for m in seen[-4:]])
    assert set(r.object_ids) == {"square_nut", "square_peg"} and len(r.object_poses) == 4 * 2 * 7
    assert not r.joint_names and not r.object_joints  # no articulated object (Coffee: test_driver_joint_states)
    one = client.call(hist, StateHistory.Request(after=before, until=seen[-3].header.stamp))
    assert len(one.stamps) == 2  # (after, until]
    n1 = len(seen)
    assert client.reset("Square", "D0", 1).success
    span = client.call(hist, StateHistory.Request(after=before))
    assert not span.success and span.reason_code == "SCENE_CHANGED"
    for _ in range(8):  # the ring keeps 8 periods: the first reset's are gone
        client.target([0.5, 0.0, 0.3])
    assert client.spin_until(lambda: len(seen) >= n1 + 9)
    old = client.call(hist, StateHistory.Request(after=before))
    assert not old.success and old.reason_code == "HISTORY_EXPIRED"
    assert proc.proc.poll() is None, "driver died"


def test_a_resent_osc_target_is_applied_once_and_answered_again(start_node, client):
    """Lockstep: the same osc_target again (same header stamp: graph_calls._await_step's resend when
    no state came) does not step the world twice; the driver publishes that period's state again.
    A new stamp steps as usual."""
    from builtin_interfaces.msg import Time
    from skillgen_interfaces.srv import StateHistory

    _proc, hist, seen, before = _mock_after_reset(start_node, client)
    n0 = len(seen)
    msg = OscTarget(pose=PoseMsg(position=Point(x=0.5, y=0.0, z=0.3), orientation=Quaternion(x=1.0, w=0.0)),
                    gripper=-1.0)
    msg.header.frame_id, msg.header.stamp = "world", Time(sec=7, nanosec=1)
    for k, stamp in enumerate([(7, 1), (7, 1), (7, 2)]):
        msg.header.stamp = Time(sec=stamp[0], nanosec=stamp[1])
        client.pub.publish(msg)
        assert client.spin_until(lambda: len(seen) >= n0 + k + 1)
    assert _stamp(seen[n0].header.stamp) == _stamp(seen[n0 + 1].header.stamp)  # the resend: the same state
    assert seen[n0].position == seen[n0 + 1].position
    assert _stamp(seen[n0 + 2].header.stamp) > _stamp(seen[n0].header.stamp)  # a new target: the next period
    r = client.call(hist, StateHistory.Request(after=before))
    assert list(r.kinds) == [StateHistory.Response.RESET] + [StateHistory.Response.OSC_TARGET] * 2
