"""answered.detached: a probe's cancel leaves the real request pending, so its late answer is matched
quietly instead of logged as an 'unexpected goal response' on the user's terminal (issue 24)."""
from rclpy.task import Future

from skillgen_ros.answered import detached, first_answer, sleep_until_done


def test_cancelling_the_detached_future_leaves_the_request_pending():
    real = Future()
    out = detached(real)
    out.cancel()
    assert out.cancelled() and not real.cancelled() and not real.done()
    real.set_result("late answer")  # the server's answer after the probe gave up: nothing to warn about
    assert real.result() == "late answer"


def test_a_detached_future_completes_with_the_request():
    real = Future()
    out = detached(real)
    real.set_result(42)
    assert out.done() and out.result() == 42
    failed = Future()
    out = detached(failed)
    failed.set_exception(RuntimeError("boom"))
    assert isinstance(out.exception(), RuntimeError)


def test_first_answer_over_detached_probes_never_cancels_a_request():
    sent = []

    def send():
        sent.append(Future())
        if len(sent) == 3:
            sent[-1].set_result("answer")
        return detached(sent[-1])
    assert first_answer(send, sleep_until_done, timeout=5.0, each=0.05) == "answer"
    assert len(sent) == 3 and not any(f.cancelled() for f in sent)
