"""GraphCalls._await_step: a lockstep driver that stays quiet after an osc_target gets a
state_history request (which wakes a parked rclpy executor) after each quiet second, and the
step still fails with the TIMEOUT budget when nothing comes. Fakes only: no graph, no clock waits."""
from types import SimpleNamespace

from skillgen_ros.nodes.graph_calls import WAKE_AFTER_S, GraphCalls


class _Env(GraphCalls):
    def __init__(self, answers, state_timeout=10.0):
        self.t = {"state": state_timeout}
        self.waits, self.answers = [], list(answers)
        self.requests = []
        stamp = SimpleNamespace(sec=3, nanosec=500)
        self._joints = SimpleNamespace(msg=SimpleNamespace(header=SimpleNamespace(stamp=stamp)))
        client = SimpleNamespace(call_async=self.requests.append)
        self.history = SimpleNamespace(ready=lambda: True, client=client)

    def wait_for_state(self, timeout, after=-1):
        self.waits.append((timeout, after))
        return self.answers.pop(0) if self.answers else False


def test_a_prompt_driver_is_not_disturbed():
    env = _Env([True])
    assert env._await_step(7)
    assert env.waits == [(WAKE_AFTER_S, 7)] and env.requests == []


def test_a_quiet_driver_is_woken_then_its_state_taken():
    env = _Env([False, False, True])
    assert env._await_step(7)
    assert len(env.requests) == 2 and all(w[1] == 7 for w in env.waits)
    assert env.requests[0].after.sec == 3 and env.requests[0].after.nanosec == 500  # periods after the newest seen


def test_a_driver_that_never_steps_fails_within_the_budget():
    env = _Env([], state_timeout=0.0)  # no budget left: one last look, no wake, then False
    assert not env._await_step(7)
    assert env.requests == [] and env.waits == [(0.0, 7)]
