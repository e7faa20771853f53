"""SafeActionClient (skillgen_ros/action_client.py): a goal sent from a user thread while another
thread spins is always answered, even when the response arrives before rclpy has recorded the
request (ros2/rclpy#1123, the cause of a lost `generate` goal on a loaded machine)."""
import threading

import rclpy
from rclpy.action import ActionServer, GoalResponse
from rclpy.executors import SingleThreadedExecutor

from conftest import wait_for
from skillgen_interfaces.action import Generate
from skillgen_ros.action_client import SafeActionClient


class _SlowRecordingHandle:
    """Wraps the rcl client handle: after a goal request is sent, hold the sender (the window in
    which rclpy has not yet recorded the request) until the server has answered it and the spin
    thread has had the response ready to take."""

    def __init__(self, handle, answered: threading.Event):
        self._h, self._answered = handle, answered

    def send_goal_request(self, request):
        seq = self._h.send_goal_request(request)
        assert self._answered.wait(60), "the server never saw the goal"
        return seq

    def __getattr__(self, name):
        return getattr(self._h, name)


def test_a_response_arriving_before_the_request_is_recorded_still_completes_the_goal(ros_domain):
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=ros_domain)
    try:
        server_node = rclpy.create_node("server", context=ctx)
        client_node = rclpy.create_node("client", context=ctx)
        answered = threading.Event()

        def on_goal(goal):
            answered.set()
            return GoalResponse.REJECT  # answered at once, nothing to execute

        ActionServer(server_node, Generate, "generate", execute_callback=lambda gh: Generate.Result(),
                     goal_callback=on_goal)
        client = SafeActionClient(client_node, Generate, "generate")
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(server_node)
        ex.add_node(client_node)
        stop = threading.Event()
        spin = threading.Thread(target=lambda: [ex.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)])
        spin.start()
        try:
            assert client.wait_for_server(timeout_sec=60)
            client._client_handle = _SlowRecordingHandle(client._client_handle, answered)
            fut = client.send_goal_async(Generate.Goal(task="Square"))
            assert wait_for(fut.done, 60), "the goal response was dropped (rclpy#1123)"
            assert not fut.result().accepted
        finally:
            stop.set()
            spin.join()
    finally:
        rclpy.shutdown(context=ctx)
