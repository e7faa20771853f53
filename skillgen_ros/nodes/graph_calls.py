"""The calls RosGraphEnv makes into the graph, and what it does when one goes unanswered.

Every call has a timeout; a node that does not answer becomes a GraphCallError whose reason names
the attempt's stage (PERCEPTION_FAILED, PLAN_FAILED, SKILL_FAILED, TIMEOUT), so the attempt fails
with that reason and the run goes on. Before each attempt a server seen before that has gone (a
node killed and being respawned) is waited for up to timeout_recover s (issue 19, chaos), and a
driver that restarted during an attempt fails it rather than judging a fresh world.
"""
from __future__ import annotations

import time

from skillgen_ros.answered import first_answer
from skillgen_ros.core.errors import NoAnswerError
from skillgen_ros.nodes.latest import wait_future
from skillgen_ros.nodes.state_history import ns

# GraphCalls._await_step / skill_replay: an osc_target without a new state this long is sent again
RESEND_AFTER_S = 1.0

# A server that has gone: the reason the attempt fails with if it does not come back in time.
_GONE_REASON = {"reset_scene": "TIMEOUT", "task_success": "TIMEOUT", "estimate_poses": "PERCEPTION_FAILED",
                "plan_to_pose": "PLAN_FAILED", "replay_skill": "SKILL_FAILED"}


class GraphCallError(NoAnswerError):
    """A call of the graph that went unanswered; its reason names the stage (PERCEPTION_FAILED, ...)."""


class GraphCalls:
    """Mixin of RosGraphEnv: expects node, t (timeouts), the clients of _servers(), _joints, _seen, _reset_ns."""

    def _call(self, client, request, timeout: float, what: str, reason: str, idempotent: bool = True):
        """Call a service with a timeout. The first response on a fresh connection can be lost (the
        server may not have matched our response reader yet), so requests that are safe to repeat
        are resent every few seconds until answered (answered.first_answer); one that moves the
        robot is sent once."""
        if not client.wait_for_service(timeout_sec=min(timeout, 5.0)):
            raise GraphCallError(f"{what}: service {client.srv_name} is not available", reason=reason)
        try:
            if idempotent:
                res = first_answer(lambda: client.call_async(request), wait_future, timeout,
                                   each=min(5.0, timeout / 2))
            else:
                fut = client.call_async(request)
                res = fut.result() if wait_future(fut, timeout) else None
                if res is None:
                    client.remove_pending_request(fut)
        except Exception as e:  # noqa: BLE001 -- the future's exception, e.g. the service's error
            raise GraphCallError(f"{what}: {e}", reason=reason) from e
        if res is None:
            raise GraphCallError(f"{what}: no answer from {client.srv_name} within {timeout:.1f} s", reason=reason)
        return res

    def _await_graph(self) -> None:
        """Before an attempt: a server seen before that has gone (its node killed, and restarted by
        `skillgen launch --respawn`) is waited for up to timeout_recover s, so the run's attempts are
        not spent while it comes back; still gone, this attempt fails with its stage's reason (issue 19)."""
        wait = float(self.t.get("recover", 0.0))
        ready = {name for name, cli in self._servers().items()
                 if (cli.server_is_ready() if hasattr(cli, "server_is_ready") else cli.service_is_ready())}
        gone = sorted(self._seen - ready)
        self._seen |= ready
        if wait <= 0 or not gone:
            return
        self.node.get_logger().warning(f"{', '.join(gone)} gone; waiting up to {wait:.0f} s for it to come back")
        end = time.monotonic() + wait
        for name in gone:
            cli = self._servers()[name]
            left = max(0.1, end - time.monotonic())
            back = cli.wait_for_server(timeout_sec=left) if hasattr(cli, "wait_for_server") else \
                cli.wait_for_service(timeout_sec=left)
            if not back:  # the reason its stage's call would have failed with
                raise GraphCallError(f"{name} gone and not back within {wait:.0f} s", reason=_GONE_REASON[name])
        self.node.get_logger().info(f"{', '.join(gone)} back")

    def _servers(self) -> dict:
        return {"reset_scene": self.reset_cli, "task_success": self.success_cli, "estimate_poses": self.estimate_cli,
                "plan_to_pose": self.plan_cli, "replay_skill": self.replay_ac}

    def _wait_action(self, send_future, timeout: float):
        end = time.monotonic() + timeout
        if not wait_future(send_future, timeout):
            raise GraphCallError("replay_skill goal was not answered", reason="SKILL_FAILED")
        handle = send_future.result()
        if not handle.accepted:
            raise GraphCallError("replay_skill goal rejected (busy?)", reason="SKILL_FAILED")
        rf = handle.get_result_async()
        if not wait_future(rf, max(0.0, end - time.monotonic())):
            handle.cancel_goal_async()
            raise GraphCallError(f"replay_skill did not finish within {timeout:.0f} s", reason="TIMEOUT")
        return rf.result()

    def _check_driver(self) -> None:
        """A sim driver that restarted during the attempt (killed and respawned: its clock starts
        again, so its states are stamped before this attempt's reset) holds a fresh world, not this
        attempt's: the attempt fails with TIMEOUT saying so, rather than as a failed task or motion."""
        m = self._joints.latest()
        if m is not None and self._reset_ns is not None and ns(m.header.stamp) < self._reset_ns:
            raise GraphCallError("the driver restarted during the attempt (its clock went back); its world is "
                                 "not this attempt's", reason="TIMEOUT")

    def _await_step(self, msg, snap, count: int) -> bool:
        """Publish the osc_target `msg` and take the driver's next joint_states: after the `count`-th
        message and not stamped as `snap`, the newest state taken before sending.

        Both ends read these topics best effort (driver_base.COMMANDS, graph_env's joint_states):
        a lost message is not repaired by DDS, so this resends. A target the driver has not applied
        is harmless to resend and one it has applied must not be applied twice, so after each quiet
        RESEND_AFTER_S this sends the same message again (same header stamp): the driver applies a
        stamp once and answers a repeat with that period's state again (driver_base._on_target).
        With reliable readers, one lost sample held every later one back (in-order delivery) until
        DDS repaired it, 10 s later: the deploy graph stall of docs/hsp.md "Known problems"."""
        before = ns(snap.header.stamp) if snap is not None else -1
        end, sent = time.monotonic() + float(self.t["state"]), 0
        while True:
            self.osc_pub.publish(msg)
            sent += 1
            left = end - time.monotonic()
            # not the state we had again (the driver answers a resend it already applied with it)
            m = self._joints.wait_for(lambda m: self._joints.count > count and m is not None
                                      and ns(m.header.stamp) != before, max(0.0, min(RESEND_AFTER_S, left)))
            if self._take_joints(m):
                if sent > 1:
                    self.node.get_logger().warning(f"osc_target answered after {sent} sends (no state within "
                                                   f"{RESEND_AFTER_S:g} s of the first)")
                return True
            if left <= RESEND_AFTER_S:
                return False
