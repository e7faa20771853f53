"""The one way every node process starts and stops.

`run_node(factory)` does what ros2/demos do: `rclpy.init` inside a context manager, an explicit
executor, Ctrl-C and external shutdown caught, no traceback on exit, and exit status 0 for a
clean stop. Bad parameters (`ParameterError`) exit 2 with a one-line reason instead of a trace.
"""
from __future__ import annotations

import sys
from typing import Callable

from skillgen_ros import rosenv  # noqa: F401  (sets loopback discovery before rclpy loads)

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor

from skillgen_ros.core.errors import SkillGenError


def run_node(factory: Callable[[], "rclpy.node.Node"], args=None, threads: int = 4) -> int:
    args = sys.argv if args is None else args
    try:
        with rclpy.init(args=args):
            try:
                node = factory()
            except SkillGenError as e:
                print(f"[{getattr(factory, '__name__', 'node')}] {e}", file=sys.stderr)
                return 2
            executor = MultiThreadedExecutor(num_threads=threads)
            executor.add_node(node)
            try:
                executor.spin()
            finally:
                executor.shutdown()
                node.destroy_node()
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    return 0


def not_implemented(name: str, issue: str) -> int:
    """Honest placeholder exit for a node a later issue fills in."""
    print(f"{name}: not implemented yet ({issue})", file=sys.stderr)
    return 3
