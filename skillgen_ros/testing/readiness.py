"""Readiness by answered requests (answered.py), for nodes a test starts.

A node is ready when it answers, not when discovery lists it: its parameter service
(`<node>/list_parameters`, which every rclpy node serves once it spins, after its constructor made
all its other servers) answers, each named service answers a harmless request, and each named
action answers a cancel request for a goal that does not exist. Every wait has a budget and stops
at once, naming the process and the end of its log, if a node process exits meanwhile.
"""
from __future__ import annotations

import time
import uuid
from typing import Callable, Iterable

from skillgen_ros.core.errors import SkillGenError


class NotReadyError(SkillGenError):
    reason = "NOT_READY"


def _tail(text: str, lines: int = 25) -> str:
    return "\n".join(text.rstrip().splitlines()[-lines:])


def check_alive(processes: Iterable) -> None:
    """NOT_READY naming the first process that has exited, with the end of its log."""
    for p in processes:
        if not p.alive:
            raise NotReadyError(f"{p.label} exited with code {p.returncode} while the test waited for it; "
                                f"its log ({p.log_path}) ends:\n{_tail(p.output())}")


def answered(node, srv_type, name: str, make_request: Callable[[], object], end: float, processes=(),
             each: float = 2.0):
    """The answer to the first of repeated requests to service `name` (resolved by `node`),
    waiting until monotonic time `end`; the node's executor must spin in another thread."""
    from skillgen_ros.nodes.latest import wait_future

    cli = node.create_client(srv_type, name)
    try:
        while True:
            check_alive(processes)
            fut = cli.call_async(make_request())
            if wait_future(fut, max(0.05, min(each, end - time.monotonic()))):
                return fut.result()
            cli.remove_pending_request(fut)
            if time.monotonic() >= end:
                check_alive(processes)
                raise NotReadyError(f"no answer from {cli.srv_name} within the readiness budget")
    finally:
        node.destroy_client(cli)


def node_answers(node, fq_name: str, end: float, processes=()) -> None:
    from rcl_interfaces.srv import ListParameters

    answered(node, ListParameters, f"{fq_name}/list_parameters", lambda: ListParameters.Request(depth=1), end,
             processes)


def action_answers(node, action: str, end: float, processes=()) -> None:
    """An action server answers: a cancel request for a random (unknown) goal ID cancels nothing."""
    from action_msgs.srv import CancelGoal

    def request():
        req = CancelGoal.Request()
        req.goal_info.goal_id.uuid = list(uuid.uuid4().bytes)
        return req

    answered(node, CancelGoal, f"{node.resolve_topic_name(action)}/_action/cancel_goal", request, end, processes)


def first_message(reader, end: float, processes=()):
    """The newest message of a LatestMessage reader once one has come, else NOT_READY."""
    while True:
        check_alive(processes)
        msg = reader.latest(timeout=max(0.0, min(0.5, end - time.monotonic())))
        if msg is not None:
            return msg
        if time.monotonic() >= end:
            raise NotReadyError(f"no message on {reader.topic} within the readiness budget")
