"""nodes/runtime.py: a node stops on Ctrl-C even when rclpy's own signal handler misses it.

CI once saw the perception node sit in rcl_wait for the launcher's whole 15 s stop budget after a
SIGINT (stack dump: the executor's wait, nothing running), then stop at once on SIGTERM. The spin
loop now wakes every STOP_CHECK_S to look at entry.STOP, which our handler sets, and shuts the context
down itself when rclpy's handler has not within RCLPY_GRACE_S. These tests take rclpy's handler out
(the miss, made certain) and require the stop anyway."""
from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from conftest import REPO, node_env

_NODE = r"""
import sys
from skillgen_ros.nodes.entry import quiet_stop_signals
quiet_stop_signals()
import rclpy, rclpy.signals
from rclpy.node import Node
from skillgen_ros.nodes.runtime import run_node

def factory():
    rclpy.signals.uninstall_signal_handlers()  # rclpy no longer sees SIGINT/SIGTERM; ours does
    n = Node("runtime_probe")
    print("READY", flush=True)
    return n

sys.exit(run_node(factory, executor=sys.argv[1]))
"""


@pytest.mark.parametrize("executor", ["single", "multi"])
def test_a_node_stops_on_sigint_that_rclpy_never_saw(ros_domain, executor):
    p = subprocess.Popen([sys.executable, "-c", _NODE, executor], cwd=REPO, env=node_env(ros_domain),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "READY", p.stderr.read()
        p.send_signal(signal.SIGINT)
        # a hang guard, not a timing goal: before the fix the process never exited
        assert p.wait(timeout=120) == 0, p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()


def test_spin_until_stopped_returns_once_stop_is_set_from_a_callback(ros_domain):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from skillgen_ros.nodes.entry import StopFlag
    from skillgen_ros.nodes.runtime import spin_until_stopped

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node("runtime_probe_inproc", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        stop, ticks = StopFlag(), []

        def tick():
            ticks.append(1)
            if len(ticks) == 3:
                stop.set()
        node.create_timer(0.01, tick)
        spin_until_stopped(ex, stop, check_s=0.05, grace_s=0.2)
        # nobody else shut the context down: after the grace it did, as rclpy's handler would have
        assert len(ticks) >= 3 and not rclpy.ok(context=ctx)
        ex.shutdown()
        node.destroy_node()
    finally:
        ctx.try_shutdown()


_REENTER = r"""
import signal, sys
from skillgen_ros.nodes.entry import quiet_stop_signals
import threading
if sys.argv[1] == "event":  # what entry.STOP was: the regression this test must catch
    ev = threading.Event()
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *_: ev.set())
else:
    quiet_stop_signals()
handler, lines = signal.getsignal(signal.SIGTERM), []

def tracer(frame, event, arg):  # a second signal lands on the second line the handler's set() runs
    if frame.f_code.co_name == "set" and event == "line":
        lines.append(1)
        if len(lines) == 2:
            handler(signal.SIGTERM, None)
    return tracer

sys.settrace(tracer)
handler(signal.SIGTERM, None)
sys.settrace(None)
print("SURVIVED", flush=True)
"""


@pytest.mark.parametrize("kind,survives", [("stop_flag", True), ("event", False)])
def test_the_stop_handler_survives_a_second_signal_inside_itself(kind, survives):
    """A node whose pytest was SIGKILLed hung in four nested threading.Event.set() frames: a second
    signal inside the first handler's set() waited on the lock that set() held. The `event` case shows
    that this test catches that (it hangs, and is killed); entry.STOP must survive it."""
    p = subprocess.Popen([sys.executable, "-c", _REENTER, kind], cwd=REPO, stdout=subprocess.PIPE, text=True)
    try:
        out, _ = p.communicate(timeout=120 if survives else 5)  # a hang guard; the event case never ends
    except subprocess.TimeoutExpired:
        p.kill()
        out, _ = p.communicate()
    assert ("SURVIVED" in out) == survives, out


_SHUT_AFTER_BUILD = r"""
import sys
from skillgen_ros.nodes.entry import quiet_stop_signals
quiet_stop_signals()
import rclpy
from rclpy.node import Node
from skillgen_ros.nodes.runtime import run_node

def factory():
    n = Node("runtime_probe")
    rclpy.shutdown()  # what rclpy's SIGINT handler does if Ctrl-C lands right after the node is built
    return n

sys.exit(run_node(factory, executor=sys.argv[1]))
"""


@pytest.mark.parametrize("executor", ["single", "multi"])
def test_ctrl_c_between_the_node_and_its_executor_is_a_clean_stop(ros_domain, executor):
    """Suite run 11: `skillgen launch` Ctrl-C'd right after "mock_driver up" exited 1, the executor's
    constructor failing on the shut-down context ("failed to create guard_condition")."""
    r = subprocess.run([sys.executable, "-c", _SHUT_AFTER_BUILD, executor], cwd=REPO, env=node_env(ros_domain),
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
