"""first_answer: readiness by an answered request (skillgen_ros/answered.py)."""
import types

import pytest

from skillgen_ros.answered import first_answer, sleep_until_done


def _futures(answer_on: int):
    from rclpy.task import Future

    sent = []

    def send():
        f = Future()
        sent.append(f)
        if len(sent) == answer_on:
            f.set_result(f"answer {len(sent)}")
        return f
    return send, sent


def test_a_lost_answer_is_resent_until_one_comes():
    send, sent = _futures(answer_on=3)
    assert first_answer(send, sleep_until_done, timeout=5.0, each=0.05) == "answer 3"
    assert len(sent) == 3 and sent[0].cancelled() and sent[1].cancelled() and not sent[2].cancelled()


def test_no_answer_gives_none_after_the_timeout(monkeypatch):
    """A stepped clock, not the wall: each wait advances it by what it was given (issue 19)."""
    import skillgen_ros.answered as answered

    now = [1000.0]
    monkeypatch.setattr(answered, "time", types.SimpleNamespace(monotonic=lambda: now[0]))

    def wait(_fut, seconds):
        now[0] += seconds

    send, sent = _futures(answer_on=0)
    assert first_answer(send, wait, timeout=0.3, each=0.1) is None
    assert len(sent) == 3 and all(f.cancelled() for f in sent) and now[0] == pytest.approx(1000.3)
