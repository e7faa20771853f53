"""GraphCalls._await_step: an osc_target the driver does not answer within RESEND_AFTER_S is sent
again (the same message: the driver applies a stamp once), a state equal to the one we had (the
driver's answer to a resend it had applied) is not taken as the new one, and the step fails once
the state budget is spent. Fakes only: no graph, no clock waits."""
from types import SimpleNamespace

from skillgen_ros.nodes.graph_calls import RESEND_AFTER_S, GraphCalls


def _js(sec: int):
    return SimpleNamespace(header=SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=0)))


class _Joints:
    """LatestMessage's wait_for over a script: each wait delivers the next scripted message (or none)."""

    def __init__(self, script):
        self.script, self.count, self.msg, self.waits = list(script), 0, None, []

    def wait_for(self, accept, timeout):
        self.waits.append(timeout)
        if self.script:
            m = self.script.pop(0)
            if m is not None:
                self.msg, self.count = m, self.count + 1
        return self.msg if accept(self.msg) else None


class _Env(GraphCalls):
    def __init__(self, script, state_timeout=10.0):
        self.t = {"state": state_timeout}
        self._joints = _Joints(script)
        self.sent = []
        self.osc_pub = SimpleNamespace(publish=self.sent.append)
        self.node = SimpleNamespace(get_logger=lambda: SimpleNamespace(warning=lambda _m: None))
        self.taken = []

    def _take_joints(self, m) -> bool:
        if m is None:
            return False
        self.taken.append(m)
        return True


def test_a_prompt_driver_gets_one_send():
    env = _Env([_js(2)])
    assert env._await_step("target", _js(1), 0)
    assert env.sent == ["target"] and env._joints.waits == [RESEND_AFTER_S]


def test_a_quiet_driver_gets_the_same_target_again():
    env = _Env([None, None, _js(2)])
    assert env._await_step("target", _js(1), 0)
    assert env.sent == ["target"] * 3 and env.taken[-1].header.stamp.sec == 2


def test_the_state_we_had_again_is_not_the_new_state():
    env = _Env([_js(1), _js(2)])  # a repeat of the snapshot's period, then the stepped one
    assert env._await_step("target", _js(1), 0)
    assert [m.header.stamp.sec for m in env.taken] == [2] and len(env.sent) == 2


def test_a_driver_that_never_answers_fails_within_the_budget():
    env = _Env([], state_timeout=0.0)
    assert not env._await_step("target", _js(1), 0)
    assert env.sent == ["target"] and env.taken == []
