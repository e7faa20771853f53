"""Test-only node: echoes skillgen_interfaces over a topic, a service and an action.

Started as a separate process by test_interfaces.py to prove the custom interfaces built from
msg_defs/ work across processes over DDS.
"""
import sys
import time

from rclpy.action import ActionServer
from rclpy.node import Node

from skillgen_interfaces.action import Gripper
from skillgen_interfaces.msg import OscTarget
from skillgen_interfaces.srv import TaskSuccess
from skillgen_ros.nodes.runtime import run_node


class InterfaceEcho(Node):
    def __init__(self):
        super().__init__("interface_echo")
        self.pub = self.create_publisher(OscTarget, "echo_out", 10)
        self.create_subscription(OscTarget, "echo_in", self._echo, 10)
        self.create_service(TaskSuccess, "echo_success", self._success)
        self.server = ActionServer(self, Gripper, "echo_gripper", self._execute)

    def _echo(self, msg: OscTarget):
        msg.gripper = msg.gripper * 2.0
        self.pub.publish(msg)

    def _success(self, _req, resp):
        resp.success = True
        resp.task = "echo"
        resp.message = "from another process"
        return resp

    def _execute(self, goal_handle):
        for i in range(3):
            fb = Gripper.Feedback()
            fb.width = goal_handle.request.position * (i + 1) / 3.0
            goal_handle.publish_feedback(fb)
            time.sleep(0.05)
        goal_handle.succeed()
        res = Gripper.Result()
        res.reached_goal = True
        res.width = goal_handle.request.position
        return res


if __name__ == "__main__":
    sys.exit(run_node(InterfaceEcho))
