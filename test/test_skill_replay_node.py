"""The skill_replay node's `replay_skill` action against the mock driver in one container:
a whole skill with feedback, cancel mid-skill, and bad goals."""
import math
import time

import pytest

from conftest import REPO, NodeProcess, client_node, next_domain_id
from skillgen_ros.answered import first_answer

SQUARE = str(REPO / "bags" / "Square")


@pytest.fixture(scope="module")
def loop():
    dom = next_domain_id()
    # realtime at 20 Hz: a skill takes seconds, so a cancel lands mid-skill
    proc = NodeProcess("container", dom, ["mock_driver", "skill_replay", "--ros-args",
                                          "--params-file", str(REPO / "params" / "mock_driver.yaml"),
                                          "--params-file", str(REPO / "params" / "skill_replay.yaml"),
                                          "-p", "mock_driver:timing_mode:=realtime", "-p", "mock_driver:cameras:=[]",
                                          "-p", "skill_replay:feedback_hz:=0.0"])
    try:
        yield dom, proc
    finally:
        proc.stop()


def _goal(**kw):
    from skillgen_interfaces.action import ReplaySkill

    g = ReplaySkill.Goal(task="Square", skill_index=0, source_demo=0, source_demos=SQUARE, action_noise=0.0, seed=3)
    g.object_pose.position.x, g.object_pose.position.y, g.object_pose.position.z = 0.5, -0.1, 0.01
    g.object_pose.orientation.w = 1.0
    for k, v in kw.items():
        setattr(g, k, v)
    return g


def _send(node, ex, client, goal, cancel_after: int = 0, timeout: float = 60.0):
    feedback = []
    sent = client.send_goal_async(goal, feedback_callback=lambda m: feedback.append(m.feedback))
    ex.spin_until_future_complete(sent, timeout_sec=30)
    handle = sent.result()
    assert handle is not None and handle.accepted
    res = handle.get_result_async()
    end = time.monotonic() + timeout
    canceled = False
    while not res.done() and time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
        if cancel_after and not canceled and len(feedback) >= cancel_after:
            handle.cancel_goal_async()
            canceled = True
    assert res.done(), "replay_skill did not finish"
    return res.result(), feedback


def test_replay_skill_streams_the_segment_and_reports_every_step(loop):
    from rclpy.action import ActionClient
    from skillgen_interfaces.action import ReplaySkill
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    n = load_source_demos(expand_bag_paths([SQUARE]), get_task("Square"))[0].skill(0).num_steps
    dom, _ = loop
    with client_node(dom, "replay_client") as (node, ex):
        client = ActionClient(node, ReplaySkill, "replay_skill")
        assert client.wait_for_server(timeout_sec=60)
        # the first answer can be lost to discovery (CI): probe (empty task, rejected unrun) until answered
        probe = first_answer(lambda: client.send_goal_async(_goal(task="")),
                             lambda f, s: ex.spin_until_future_complete(f, timeout_sec=s), timeout=60)
        assert probe is not None and not probe.accepted
        wrapped, feedback = _send(node, ex, client, _goal())
        r = wrapped.result
        assert r.success and r.reason == "OK", r.message
        assert r.steps == n and r.source_demo == 0
        assert len(r.actions) == 7 * n and len(r.actions_abs) == 8 * n and len(r.joint_positions) == 7 * n
        assert len(r.gripper_widths) == n and len(r.recovery_steps) == n
        assert [f.step for f in feedback] == list(range(1, n + 1))  # feedback_hz 0: every step
        assert all(f.total_steps == n for f in feedback)
        # noise 0: the normalized pose actions stay inside the unit box; gripper copied as is
        assert max(abs(a) for a in r.actions) <= 1.0
        assert set(r.actions_abs[7::8]) <= {-1.0, 1.0}

        # canceled after a few steps: the steps done so far come back, marked CANCELED
        wrapped, feedback = _send(node, ex, client, _goal(skill_index=1), cancel_after=5)
        r = wrapped.result
        assert not r.success and r.reason == "CANCELED", (r.reason, r.message)
        assert 5 <= r.steps < 60 and len(r.actions) == 7 * r.steps

        # bad goals: a reason each, and the node keeps serving
        for goal, reason in ((_goal(source_demo=99), "BAD_DEMO_INDEX"), (_goal(task="Nope"), "UNKNOWN_TASK"),
                             (_goal(source_demos=str(REPO / "params")), "NO_SOURCE_DEMOS")):
            wrapped, _ = _send(node, ex, client, goal)
            assert not wrapped.result.success and wrapped.result.reason == reason, wrapped.result.message
        bad = _goal()
        bad.object_pose.position.x = math.nan
        wrapped, _ = _send(node, ex, client, bad)
        assert not wrapped.result.success and wrapped.result.reason == "INVALID_INPUT", wrapped.result.reason
        wrapped, _ = _send(node, ex, client, _goal())
        assert wrapped.result.success
