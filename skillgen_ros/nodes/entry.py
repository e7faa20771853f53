"""Console-script entry points of the node executables: Ctrl-C is quiet from the first instant.

A node's imports (rclpy, numba, pybullet, open3d) take from half a second to seconds. A Ctrl-C in
that window (a launch stopped while it starts) used to raise KeyboardInterrupt inside an import
and print its traceback. The console script imports only this module, which imports nothing
heavy, installs the quiet stop handlers (runtime.run_nodes keeps the same event), then imports
the node; a stop asked for meanwhile ends the process at once with status 0.
"""
from __future__ import annotations

import importlib
import signal
import threading

STOP = threading.Event()  # set by SIGINT/SIGTERM from the first instant of the process


def quiet_stop_signals() -> threading.Event:
    """SIGINT/SIGTERM set STOP instead of raising KeyboardInterrupt (runtime.py says why)."""
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda _signum, _frame: STOP.set())
    return STOP


def _run(node: str) -> int:
    quiet_stop_signals()
    module = importlib.import_module(f"skillgen_ros.nodes.{node}")
    return 0 if STOP.is_set() else module.main()


def sim_driver() -> int:
    return _run("sim_driver")


def mock_driver() -> int:
    return _run("mock_driver")


def perception() -> int:
    return _run("perception")


def planner() -> int:
    return _run("planner")


def skill_replay() -> int:
    return _run("skill_replay")


def datagen() -> int:
    return _run("datagen")


def hsp() -> int:
    return _run("hsp")


def recorder() -> int:
    return _run("recorder")


def player() -> int:
    return _run("player")


def teleop() -> int:
    return _run("teleop")


def container() -> int:
    return _run("container")
