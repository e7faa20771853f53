"""skillgen_interfaces round trip across two processes: a topic, a service and an action with feedback."""
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rclpy.action import ActionClient

from skillgen_interfaces.action import Gripper
from skillgen_interfaces.msg import OscTarget
from skillgen_interfaces.srv import TaskSuccess

from conftest import client_node, node_env
from skillgen_ros.answered import first_answer

HERE = Path(__file__).parent


@pytest.fixture
def echo_process(ros_domain):
    p = subprocess.Popen([sys.executable, str(HERE / "helpers" / "interface_echo.py")], env=node_env(ros_domain))
    yield p
    p.send_signal(2)
    try:
        p.wait(10)
    except subprocess.TimeoutExpired:
        p.kill()


def test_custom_interfaces_across_processes(echo_process, ros_domain):
    with client_node(ros_domain, "interface_client") as (node, ex):
        got = []
        node.create_subscription(OscTarget, "echo_out", got.append, 10)
        pub = node.create_publisher(OscTarget, "echo_in", 10)
        # topic: keep publishing until the echo comes back (discovery takes a moment)
        msg = OscTarget()
        msg.pose.position.x = 0.5
        msg.gripper = 0.25
        end = time.monotonic() + 20
        while not got and time.monotonic() < end:
            pub.publish(msg)
            ex.spin_once(timeout_sec=0.1)
        assert got, "no echo on the custom topic"
        assert got[0].pose.position.x == 0.5 and got[0].gripper == 0.5

        # service
        cli = node.create_client(TaskSuccess, "echo_success")
        assert cli.wait_for_service(timeout_sec=10)
        echo = first_answer(lambda: cli.call_async(TaskSuccess.Request()),
                            lambda f, s: ex.spin_until_future_complete(f, timeout_sec=s), timeout=20)
        assert echo is not None and echo.success and echo.message == "from another process"

        # action with feedback
        ac = ActionClient(node, Gripper, "echo_gripper")
        assert ac.wait_for_server(timeout_sec=10)
        feedback = []
        goal = Gripper.Goal(position=0.06, max_effort=20.0)
        gfut = ac.send_goal_async(goal, feedback_callback=lambda f: feedback.append(f.feedback.width))
        ex.spin_until_future_complete(gfut, timeout_sec=10)
        handle = gfut.result()
        assert handle.accepted
        rfut = handle.get_result_async()
        ex.spin_until_future_complete(rfut, timeout_sec=10)
        result = rfut.result().result
        assert result.reached_goal and result.width == pytest.approx(0.06)
        assert len(feedback) >= 1 and feedback[-1] == pytest.approx(0.06)
