"""teleop node driven from a pseudo-terminal against a driver: keys move the EE, space toggles the gripper."""
from __future__ import annotations

import os
import pty
import subprocess
import termios
import threading

import numpy as np
import pytest

from conftest import REPO, VENV_BIN, node_env, wait_for
from skillgen_ros.nodes import teleop as T

STEP = 0.01


def test_apply_key_directions_match_the_docs():
    t0 = T.Target(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    expect = {"w": [1, 0, 0], "s": [-1, 0, 0], "a": [0, 1, 0], "d": [0, -1, 0], "r": [0, 0, 1], "f": [0, 0, -1]}
    for k, d in expect.items():
        np.testing.assert_allclose(T.apply_key(t0, k, STEP, 0.1).position, np.array(d) * STEP)
        assert k in T.HELP
    from scipy.spatial.transform import Rotation

    yaw = Rotation.from_quat(T.apply_key(t0, "j", STEP, 0.1).quaternion).as_euler("xyz")
    np.testing.assert_allclose(yaw, [0, 0, 0.1], atol=1e-12)
    assert T.apply_key(t0, " ", STEP, 0.1).gripper == 1.0
    assert T.apply_key(T.apply_key(t0, " ", 0, 0), " ", 0, 0).gripper == -1.0
    clamped = T.clamp_lead(T.Target(np.array([1.0, 0, 0]), t0.quaternion), np.zeros(3), 0.05)
    np.testing.assert_allclose(clamped.position, [0.05, 0, 0])


def test_escape_sequences_are_not_key_presses():
    assert T._ESCAPES.sub("", "w\x1b[Aa\x1bOBd[") == "wad["  # an arrow key must not halve the step ('[')


def test_spacemouse_events_parse():
    ev = T._EVENT.pack(0, 0, T.EV_REL, 2, -350) + T._EVENT.pack(0, 0, T.EV_KEY, 256, 1)
    axes, presses = T.parse_spacemouse_events(ev, np.zeros(6))
    assert presses == 1 and axes[2] == -1.0
    lin, _ = T.spacemouse_twist(axes, 0.05, 0.2, 1.0)
    assert lin[2] > 0  # pushing the cap down is negative z on the device; the mapping flips it up
    assert T.find_spacemouse("/nonexistent/device") is None


class _Watcher:
    """In-test rclpy node that keeps the latest ee_pose and gripper_state."""

    def __init__(self):
        import rclpy
        from geometry_msgs.msg import PoseStamped
        from rclpy.executors import SingleThreadedExecutor

        from skillgen_interfaces.msg import GripperState, OscTarget

        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node("teleop_test_watcher", context=self.ctx)
        self.ee = None
        self.grip = None
        self.node.create_subscription(PoseStamped, "ee_pose", self._ee, 10)
        self.node.create_subscription(GripperState, "gripper_state", self._grip, 10)
        self.targets = 0  # teleop's osc_target messages: it spins and holds the measured pose
        self.target = None  # the newest one's position
        self.node.create_subscription(OscTarget, "osc_target", self._target, 10)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.th = threading.Thread(target=self.ex.spin, daemon=True)
        self.th.start()

    def _ee(self, m):
        self.ee = np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z])

    def _target(self, m):
        self.targets += 1
        self.target = np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z])

    def _grip(self, m):
        self.grip = (float(m.command), float(m.width))

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()
        self.ctx.try_shutdown()


def _stop(proc, master: int, *watchers: _Watcher) -> None:
    """A test's teardown: Ctrl-C the teleop if it still runs, close its terminal and the watchers."""
    if proc.poll() is None:
        proc.send_signal(2)
        proc.wait(10)
    os.close(master)
    for w in watchers:
        w.close()


@pytest.fixture(params=["mock_driver", "sim_driver"])
def driver(request):
    """The plugin's mock_driver / sim_driver fixture, ready, in the Square scene (markers below)."""
    return request.getfixturevalue(request.param)


@pytest.mark.mock_driver(initial_task="Square", publish_points=False)
@pytest.mark.sim_driver(task="Square", publish_points=False)
def test_keys_move_the_ee_and_toggle_the_gripper(ros_domain, driver):
    w = _Watcher()
    master, slave = pty.openpty()
    proc = subprocess.Popen([str(VENV_BIN / "teleop"), "--ros-args", "--params-file", str(REPO / "params/teleop.yaml"),
                             "-p", f"linear_step:={STEP}", "-p", "task:=Square"], stdin=slave, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, env=node_env(ros_domain), cwd=REPO, text=True)
    os.close(slave)
    try:
        assert wait_for(lambda: w.ee is not None and w.grip is not None, 20), "no ee_pose/gripper_state from driver"
        # teleop is ready once it publishes targets (it has the EE) and has put its terminal in cbreak
        # mode (master and slave share the termios): keys typed before then wait for a newline
        assert wait_for(lambda: w.targets > 0 and not termios.tcgetattr(master)[3] & termios.ICANON, 60), \
            "teleop did not start"

        def press(key: str, axis: int, sign: float, n: int = 4):
            start = w.ee.copy()
            for _ in range(n):  # one key at a time: each is seen in the published target before the next
                before = w.target.copy()
                os.write(master, key.encode())
                assert wait_for(lambda: sign * (w.target[axis] - before[axis]) > 0.5 * STEP, 8), f"key {key!r} unseen"
            moved = lambda: sign * (w.ee[axis] - start[axis]) > 0.6 * n * STEP  # noqa: E731
            assert wait_for(moved, 8), f"key {key!r}: EE moved {w.ee - start}, expected {sign:+} along axis {axis}"
            other = [i for i in range(3) if i != axis]
            assert np.all(np.abs((w.ee - start)[other]) < 0.5 * n * STEP), f"key {key!r} moved sideways {w.ee - start}"

        for key, axis, sign in (("w", 0, 1), ("s", 0, -1), ("a", 1, 1), ("d", 1, -1), ("r", 2, 1), ("f", 2, -1)):
            press(key, axis, sign)
        cmd0, width0 = w.grip
        assert cmd0 <= 0, "the driver starts with the gripper open"
        os.write(master, b" ")
        assert wait_for(lambda: w.grip[0] > 0 and w.grip[1] < width0 - 0.02, 8), f"gripper did not close: {w.grip}"
        os.write(master, b" ")
        assert wait_for(lambda: w.grip[0] < 0 and w.grip[1] > width0 - 0.005, 8), f"gripper did not open: {w.grip}"
        os.write(master, b"q")
        proc.wait(10)
        out = proc.stdout.read()
        assert proc.returncode == 0, out
        # the status line (issue 24): pose, gripper, the next object of the task, the last key
        assert "| EE " in out and "gripper 0.0" in out and "next square_nut handle" in out, out
        assert "key w (+x)" in out and "key f (-z)" in out and "key space (gripper)" in out, out
    finally:
        _stop(proc, master, w)


@pytest.mark.mock_driver(initial_task="Square", publish_points=False)
def test_the_teleop_holds_the_robot_until_osc_target_has_its_subscribers(ros_domain, mock_driver, tmp_path):
    """`demos record` starts the teleop with min_subscribers 2 (driver + recorder): until the recorder
    subscribes, keys are refused with the reason and no target goes out, so the bag misses no command."""
    w = _Watcher()  # with the driver: 2 subscribers of osc_target, one short of 3
    log = tmp_path / "teleop.log"
    master, slave = pty.openpty()
    with open(log, "w") as f:
        proc = subprocess.Popen([str(VENV_BIN / "teleop"), "--ros-args", "--params-file",
                                 str(REPO / "params/teleop.yaml"), "-p", "min_subscribers:=3"],
                                stdin=slave, stdout=f, stderr=subprocess.STDOUT, env=node_env(ros_domain), cwd=REPO,
                                text=True)
    os.close(slave)
    third = None
    try:
        assert wait_for(lambda: w.ee is not None and not termios.tcgetattr(master)[3] & termios.ICANON, 60), \
            "teleop did not start"

        def refused() -> bool:  # a key until it is refused for the subscribers (the EE may arrive first)
            os.write(master, b"w")
            return "fewer than 3 subscribers (is the recorder up?)" in log.read_text()

        assert wait_for(refused, 30), log.read_text()
        assert w.targets == 0, "the teleop drove the robot before osc_target had its subscribers"
        third = _Watcher()  # the third subscriber: now the teleop takes the robot
        assert wait_for(lambda: w.targets > 0, 30), log.read_text()
        os.write(master, b"q")
        proc.wait(10)
        assert proc.returncode == 0, log.read_text()
    finally:
        _stop(proc, master, w, *([third] if third is not None else []))
