"""Pull-model subscriptions: read the newest message of a topic only when you need it.

A node that needs "the current joint state" or "the latest cloud" once per request should not be
woken for every message: in lockstep the driver publishes hundreds of periods a second, and on a
2-core machine each wakeup of a Python executor costs about a millisecond of someone's time.
`LatestMessage` keeps a depth-1 KEEP_LAST reader on a private node that no executor spins; the
middleware retains the newest sample, and `latest()` / `wait_newer()` take it on demand from the
caller's thread (straight from the reader's handle, then through the executor only to wait: see
`_take`). The topic name is resolved by the owner (its namespace and every remap that
applies to it, node-targeted ones included), and the private node takes no command-line
arguments, so a `__node:=` rename meant for the owner does not also rename it.

`wait_future` is the same idea for an rclpy future (a service answer, an action result): a worker
thread blocks on it while the executor's threads complete it.
"""
from __future__ import annotations

import itertools
import threading
import time
import weakref

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile

_ids = itertools.count()
_LIVE: "weakref.WeakSet[LatestMessage]" = weakref.WeakSet()  # readers close_all() shuts down


class LatestMessage:
    def __init__(self, owner: Node, msg_type, topic: str, qos: QoSProfile | None = None):
        base = qos or QoSProfile(depth=1)
        profile = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=base.reliability,
                             durability=base.durability)
        self._node = rclpy.create_node(f"{owner.get_name()}_pull_{next(_ids)}", namespace=owner.get_namespace(),
                                       context=owner.context, start_parameter_services=False,
                                       use_global_arguments=False)
        self.topic = owner.resolve_topic_name(topic)
        self._sub = self._node.create_subscription(msg_type, self.topic, self._on_msg, profile)
        self._exec = SingleThreadedExecutor(context=owner.context)
        self._exec.add_node(self._node)
        self._lock = threading.Lock()  # one puller at a time
        self.msg = None
        self.count = 0  # messages taken so far
        self._closed = False
        _LIVE.add(self)

    def _on_msg(self, msg) -> None:
        self.msg = msg
        self.count += 1

    def _take(self) -> bool:
        """Take the reader's newest sample, if one is waiting, straight from its handle.

        Not through the executor alone: a spin_once(0) right after one that took a message wakes on
        the executor's own guard condition (its handler triggers it) and takes nothing, so every other
        read returned the message taken the call before (perception posed Coffee Prep's drawer at the
        previous look's joint values: shut while it was open)."""
        sub = self._sub
        with sub.handle:
            got = sub.handle.take_message(sub.msg_type, sub.raw)
        if got is None:
            return False
        self._on_msg(got[0])
        return True

    def _drain(self, timeout: float) -> None:
        """Take what is waiting; with nothing waiting and a timeout, wait up to it for a sample."""
        if self._take() or timeout <= 0.0:
            return
        self._exec.spin_once(timeout_sec=timeout)  # its callback takes a sample that arrives; or it woke early
        self._take()

    def snapshot(self) -> tuple[object, int]:
        """(newest message, count) after taking whatever is waiting: call before sending a command
        whose effect you will wait for with wait_newer(count, ...)."""
        with self._lock:
            self._drain(0.0)
            return self.msg, self.count

    def wait_for(self, accept, timeout: float):
        """The newest message once `accept(msg)` holds for it (msg may be None), taking messages
        as they come for up to `timeout` s; None if it never does."""
        with self._lock:
            end = time.monotonic() + timeout
            self._drain(0.0)
            while not accept(self.msg) and time.monotonic() < end:
                self._drain(max(0.0, end - time.monotonic()))
            return self.msg if accept(self.msg) else None

    def latest(self, timeout: float = 0.0):
        """The newest message (waiting up to `timeout` s if none has ever arrived), or None."""
        return self.wait_for(lambda m: m is not None, timeout)

    def wait_newer(self, count: int, timeout: float):
        """The first message taken after the `count`-th one, or None after `timeout` s."""
        return self.wait_for(lambda _m: self.count > count, timeout)

    def destroy(self) -> None:
        if self._closed:
            return
        self._closed = True
        _LIVE.discard(self)
        self._exec.shutdown()
        self._node.destroy_node()


def close_all() -> None:
    """Shut down every reader still open; runtime.run_nodes calls it before rclpy.shutdown. An
    executor left open past shutdown prints an InvalidHandle traceback from Executor.__del__ when
    it is collected (its SIGINT guard condition died with the context): CI once failed on that."""
    for reader in list(_LIVE):
        try:
            reader.destroy()
        except Exception:  # noqa: BLE001 - the context may already be shutting down
            pass


def wait_future(fut, timeout: float) -> bool:
    """Block the calling (non-executor) thread until an rclpy future is done; False on timeout.
    An event, not polling: the answer is seen the moment the executor sets it."""
    done = threading.Event()
    fut.add_done_callback(lambda _f: done.set())
    return done.wait(timeout)
