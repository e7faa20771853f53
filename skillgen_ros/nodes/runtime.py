"""The one way every node process starts and stops.

`run_node(factory)` does what ros2/demos do: init, an explicit executor, Ctrl-C and external
shutdown caught, no traceback on exit, exit status 0 for a clean stop, at any moment of start-up
too. Ctrl-C never raises KeyboardInterrupt here (see entry.quiet_stop_signals). SIGUSR1 dumps every
thread's stack to stderr (`skillgen launch` does that to a node that does not stop).
User mistakes exit 2 with one line "REASON: message" instead of a trace: an unparsable params
file, a parameter of the wrong type, or a `SkillGenError` (e.g. ParameterError) raised while the
node is built.
(rclpy in Jazzy has no context-manager `init`, hence the explicit try/finally.)
"""
from __future__ import annotations

import faulthandler
import signal
import sys
import time
from typing import Callable

from skillgen_ros import rosenv  # noqa: F401  (sets loopback discovery before rclpy loads)

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor

from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.nodes.entry import quiet_stop_signals
from skillgen_ros.nodes.latest import close_all as close_readers


def _fail(name: str, reason: str, msg: str) -> int:
    print(f"[{name}] {reason}: {msg}", file=sys.stderr, flush=True)
    return 2


def run_node(factory: Callable[[], "rclpy.node.Node"], args=None, threads: int = 4, name: str = "",
             executor: str = "multi") -> int:
    """executor: "multi" (MultiThreadedExecutor: nodes whose callbacks block) or "single"
    (SingleThreadedExecutor: nodes on the hot path whose long work is a coroutine). A node may
    override it with an `executor_kind` attribute decided from its parameters. rclpy's C++
    EventsExecutor would be cheaper still, but in this rclpy (7.1.5) it never answers an action
    server's goal requests."""
    return run_nodes([factory], args, threads, name or getattr(factory, "__name__", "node"), executor)


def run_nodes(factories: list[Callable[[], "rclpy.node.Node"]], args=None, threads: int = 4, name: str = "node",
              executor: str = "multi") -> int:
    """Several nodes in this process on one executor (ROS 2 composition; see nodes/container.py):
    single-threaded only if every node asks for it (`executor_kind`, else `executor`)."""
    args = sys.argv if args is None else args
    faulthandler.register(signal.SIGUSR1, all_threads=True)  # `skillgen launch` asks a hung node for its stacks
    stop = quiet_stop_signals()  # the event entry.py set up before this node's imports
    if stop.is_set():  # Ctrl-C while the node's modules were loading (entry.py)
        return 0
    try:
        rclpy.init(args=args)
    except rclpy._rclpy_pybind11.RCLError as e:  # bad --ros-args / unparsable params file
        return _fail(name, "INVALID_PARAMETER", str(e).split(", at ")[0])
    nodes = []
    try:
        try:
            for factory in factories:
                nodes.append(factory())
                if stop.is_set():  # Ctrl-C before rclpy's handler was in: it never saw it
                    return 0
        except Exception as e:  # noqa: BLE001 - sorted below
            if stop.is_set() or not rclpy.ok():
                return 0  # Ctrl-C while a node was being built: rclpy shut the context down under it
            if isinstance(e, SkillGenError):
                return _fail(name, e.reason, str(e.args[0]))
            if isinstance(e, ParameterException):  # wrong type / unset required parameter in the params file
                return _fail(name, "INVALID_PARAMETER", str(e))
            raise
        single = all(getattr(n, "executor_kind", executor) == "single" for n in nodes)
        try:
            ex = SingleThreadedExecutor() if single else MultiThreadedExecutor(num_threads=threads)
            for n in nodes:
                ex.add_node(n)
        except Exception:  # noqa: BLE001 - Ctrl-C between the node and its executor: rclpy shut the context
            if stop.is_set() or not rclpy.ok():  # down ("failed to create guard_condition"; suite run 11)
                return 0
            raise
        try:
            spin_until_stopped(ex, stop)
        except Exception:  # noqa: BLE001 - a callback's error; after Ctrl-C it is the shut-down context
            if not stop.is_set() and rclpy.ok():  # (a timer publishing as rclpy shut it down:
                raise  # "publisher's context is invalid"), which is a clean stop, not a failure
        finally:
            ex.shutdown()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        # A second Ctrl-C must not interrupt the cleanup (a recorder finalizing its bag, say). Also
        # takes rclpy's handler out of the way: without these two lines the recorder hung in
        # cleanup in about 1 of 12 start-up Ctrl-C tests, even with quiet_stop_signals.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        for n in nodes:
            try:
                n.destroy_node()
            except Exception:  # noqa: BLE001 - context may already be gone at shutdown
                pass
        close_readers()  # nodes/latest.py: their private executors must not outlive the context
        if rclpy.ok():
            rclpy.shutdown()
    return 0


STOP_CHECK_S = 0.25  # how often the spin looks at our stop flag
RCLPY_GRACE_S = 1.0  # how long after our handler saw a stop rclpy's own gets to shut the context down


def spin_until_stopped(ex, stop, check_s: float = STOP_CHECK_S, grace_s: float = RCLPY_GRACE_S) -> None:
    """`ex.spin()` until the context is shut down, waking every `check_s` s to look at `stop` (entry.STOP,
    set by our SIGINT/SIGTERM handler). rclpy's handler normally shuts the context down within
    milliseconds; CI once saw a node sit in rcl_wait for 15 s after a SIGINT (its SIGTERM then worked).
    A Python handler only runs when the main thread runs Python, so a wait with no timeout could hold
    it off forever. If the context is still up `grace_s` after the stop was seen, rclpy's handler
    missed it and this shuts the context down itself (waiting first keeps the usual order: rclpy's
    shutdown, then ours, never both at once)."""
    seen = None
    while rclpy.ok(context=ex.context):
        ex.spin_once(timeout_sec=check_s)
        if stop.is_set():
            seen = time.monotonic() if seen is None else seen
            if time.monotonic() - seen >= grace_s:
                ex.context.try_shutdown()
                return


def not_implemented(name: str, issue: str) -> int:
    """Honest placeholder exit for a node a later issue fills in."""
    print(f"{name}: not implemented yet ({issue})", file=sys.stderr)
    return 3
