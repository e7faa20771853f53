"""SkillGenClient: a small Python API over the `generate` action, in the spirit of nav2_simple_commander.

    from skillgen_ros.client import SkillGenClient
    with SkillGenClient() as sg:
        sg.generate(task="Square", variant="D1", method="skillgen", attempts=50)
        while not sg.is_done():
            print(sg.feedback())
        print(sg.result())

Users script generation without knowing topics; the `skillgen generate` command and the
end-to-end tests use it too.
"""
from __future__ import annotations

import threading
import time

from skillgen_ros import rosenv  # noqa: F401

import rclpy
from skillgen_ros.action_client import SafeActionClient as ActionClient
from rclpy.executors import SingleThreadedExecutor

from skillgen_interfaces.action import Generate
from skillgen_ros.answered import detached, first_answer, sleep_until_done
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.validation import USE_DEFAULT


class SkillGenClient:
    def __init__(self, namespace: str = "", domain_id: int | None = None, node_name: str = "skillgen_client"):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(node_name, namespace=namespace, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.client = ActionClient(self.node, Generate, "generate")
        self._feedback: Generate.Feedback | None = None
        self._goal = None
        self._result_future = None
        self._answering = False
        self._spin = threading.Thread(target=self._spin_loop, daemon=True)
        self._stop = threading.Event()
        self._spin.start()

    def _spin_loop(self):
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def wait_for_server(self, timeout: float = 30.0) -> bool:
        """True once datagen answers: discovered, then a probe goal (empty task, rejected unrun)
        answered, so the first real goal's answer cannot be lost to discovery (see answered.py)."""
        if self._answering:
            return True
        end = time.monotonic() + timeout
        if not self.client.wait_for_server(timeout_sec=timeout):
            return False
        probe = first_answer(lambda: detached(self.client.send_goal_async(Generate.Goal(task=""))), sleep_until_done,
                             max(0.1, end - time.monotonic()))
        self._answering = probe is not None
        return self._answering

    def generate(self, timeout: float = 30.0, **fields) -> bool:
        """Send a Generate goal (fields as in Generate.action); True if accepted."""
        if not self.wait_for_server(timeout):
            raise SkillGenError("the datagen node's 'generate' action is not available", reason="NO_SERVER")
        for k in ("augment_translation", "augment_rotation_deg"):  # unset: the node's default, not 0
            fields.setdefault(k, USE_DEFAULT)
        goal = Generate.Goal(**fields)
        fut = self.client.send_goal_async(goal, feedback_callback=self._on_feedback)
        end = time.monotonic() + timeout
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.01)
        if not fut.done():
            raise SkillGenError("the generate goal was not answered", reason="TIMEOUT")
        self._goal = fut.result()
        if not self._goal.accepted:
            return False
        self._result_future = self._goal.get_result_async()
        return True

    def _on_feedback(self, msg):
        self._feedback = msg.feedback

    def feedback(self) -> Generate.Feedback | None:
        return self._feedback

    def is_done(self) -> bool:
        return self._result_future is not None and self._result_future.done()

    def result(self, timeout: float | None = None) -> Generate.Result:
        end = None if timeout is None else time.monotonic() + timeout
        while not self.is_done():
            if end is not None and time.monotonic() > end:
                raise SkillGenError("no generate result in time", reason="TIMEOUT")
            time.sleep(0.05)
        return self._result_future.result().result

    def cancel(self) -> None:
        if self._goal is not None:
            self._goal.cancel_goal_async()

    def close(self) -> None:
        self._stop.set()
        self._spin.join(timeout=2.0)
        self.client.destroy()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
