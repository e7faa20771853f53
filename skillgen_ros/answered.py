"""Readiness by an answered request, not by discovery alone.

`wait_for_server` / `wait_for_service` return once *we* have matched the server. Discovery is
asymmetric: the server may not yet have matched our response reader, and rmw_fastrtps drops a
response it cannot deliver within the writer's max blocking time (100 ms). On a loaded 2-core CI
host a first goal's answer was lost this way twice (no answer in 30 s and in 120 s). So a client
that must not lose its first real request sends a probe that is safe to repeat until one is answered.

Our action servers treat a goal with an empty `task` as that probe: they reject it at once and run
nothing (datagen `generate`, skill_replay `replay_skill`).
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:  # no rclpy import at module load: usable before rosenv has set the environment
    from rclpy.task import Future


def first_answer(send: Callable[[], Future], wait: Callable[[Future, float], None], timeout: float,
                 each: float = 3.0):
    """The result of the first of repeated `send()`s answered within `each` s, or None after `timeout`.

    `wait(future, seconds)` waits (spinning, or sleeping while another thread spins); only for
    requests whose repeats do no harm."""
    end = time.monotonic() + timeout
    while True:
        fut = send()
        wait(fut, max(0.05, min(each, end - time.monotonic())))
        if fut.done():
            return fut.result()
        fut.cancel()
        if time.monotonic() >= end:
            return None


def sleep_until_done(fut: Future, seconds: float) -> None:
    """`wait` for a future that another thread's executor completes."""
    end = time.monotonic() + seconds
    while not fut.done() and time.monotonic() < end:
        time.sleep(0.01)


def detached(fut: Future) -> Future:
    """A future that completes with `fut`, but whose cancel() leaves `fut` pending.

    For goals sent as readiness probes to an action server: `first_answer` cancels a probe that
    was not answered in time, and cancelling rclpy's own goal future drops its record of the
    request, so the server's late answer is logged as "Ignoring unexpected goal response. There may
    be more than one action server" on the user's terminal (issue 24). Left pending, the late answer
    completes the abandoned future quietly."""
    from rclpy.task import Future as _Future

    out = _Future()

    def copy(f):
        if out.done():
            return
        try:
            out.set_result(f.result())
        except Exception as e:  # noqa: BLE001 - the request's own error, handed on
            out.set_exception(e)

    fut.add_done_callback(copy)
    return out
