"""Calls into a running graph for the boundary and fuzz tests: one service call or one action goal,
answered or None after a budget (never a hang). The first call on a fresh client repeats a probe
until the server answers (skillgen_ros/answered.py), so discovery cannot lose a request."""
from __future__ import annotations

import contextlib
import time
from pathlib import Path

from skillgen_ros.answered import detached, first_answer, sleep_until_done

GRAPHS = Path(__file__).parent / "boundary_graphs.yaml"
BAGS = str(Path(__file__).resolve().parents[2] / "bags")


@contextlib.contextmanager
def boundary_graphs(domain: int, artifacts: Path, name: str = "boundary_client"):
    """The `boundaries` graph and datagen alone in /iso (helpers/boundary_graphs.yaml), with a
    spinning client node; yields ({"": Calls, "/iso": Calls}, (graph, datagen graph))."""
    from skillgen_ros.testing.handles import launch_graph, spinning_node

    with spinning_node(domain, name) as node:
        g = launch_graph("boundaries", domain, node, artifacts / "g", graphs_file=GRAPHS, timeout=240,
                         skill_replay={"demos_dir": BAGS}, hsp={"demos_dir": BAGS})
        try:
            d = launch_graph("datagen_alone", domain, node, artifacts / "d", graphs_file=GRAPHS, namespace="/iso",
                             timeout=240, datagen={"demos_dir": BAGS})
            try:
                yield {"": Calls(node), "/iso": Calls(node, "/iso")}, (g, d)
            finally:
                d.stop()
        finally:
            g.stop()


class Calls:
    """Clients created on first use, on a node whose executor spins in another thread."""

    def __init__(self, node, namespace: str = ""):
        self.node, self.ns = node, namespace.rstrip("/")
        self._clients: dict = {}

    def _name(self, name: str) -> str:
        return f"{self.ns}/{name}" if self.ns else name

    def service(self, srv_type, name: str, request, timeout: float = 30.0, probe=None, repeat: bool = False):
        """The response to `request` (None after `timeout`); `probe` (a harmless request) is sent
        until answered the first time the client is used. `repeat`: the request itself is harmless
        to repeat (one the server refuses), so it is resent every 10 s (see goal())."""
        from rclpy.client import Client

        key = (srv_type, name)
        cli: Client | None = self._clients.get(key)
        if cli is None:
            cli = self.node.create_client(srv_type, self._name(name))
            assert cli.wait_for_service(timeout_sec=60.0), f"service {name} never appeared"
            if probe is not None:
                assert first_answer(lambda: cli.call_async(probe), sleep_until_done, 60.0) is not None
            self._clients[key] = cli
        if repeat:
            return first_answer(lambda: cli.call_async(request), sleep_until_done, timeout, each=10.0)
        fut = cli.call_async(request)
        sleep_until_done(fut, timeout)
        return fut.result() if fut.done() else None

    def goal(self, action_type, name: str, goal, timeout: float = 60.0, probe=None, repeat: bool = False):
        """(accepted, result) for one goal; result None if not accepted or not done in `timeout`.
        `repeat`: the goal is harmless to repeat (one the server refuses at once), so it is resent
        every 10 s until answered. Under CI load a goal response was once not seen in 60 s even on
        a matched client (rmw_fastrtps drops a reply it cannot deliver in 100 ms: answered.py).
        SafeActionClient: this node spins in another thread, so a plain ActionClient can drop a goal
        response that arrives before it has recorded the request (rclpy#1123; a fuzz run at load ~6
        lost a gripper goal this way, "Ignoring unexpected goal response")."""
        from skillgen_ros.action_client import SafeActionClient

        key = (action_type, name)
        ac = self._clients.get(key)
        if ac is None:
            ac = SafeActionClient(self.node, action_type, self._name(name))
            assert ac.wait_for_server(timeout_sec=60.0), f"action {name} never appeared"
            if probe is not None:  # an empty-task goal: rejected at once, runs nothing
                assert first_answer(lambda: detached(ac.send_goal_async(probe)), sleep_until_done, 60.0) is not None
            self._clients[key] = ac
        end = time.monotonic() + timeout
        if repeat:
            handle = first_answer(lambda: detached(ac.send_goal_async(goal)), sleep_until_done, timeout, each=10.0)
            if handle is None:
                return None, None
        else:
            fut = ac.send_goal_async(goal)
            sleep_until_done(fut, timeout)
            if not fut.done():
                return None, None
            handle = fut.result()
        if not handle.accepted:
            return False, None
        # get_result is safe to repeat: resent every 5 s, so a lost answer (a result client not yet
        # matched both ways, answered.py) costs a resend, not the whole budget
        got = first_answer(handle.get_result_async, sleep_until_done, max(0.1, end - time.monotonic()), each=5.0)
        return True, (got.result if got is not None else None)
