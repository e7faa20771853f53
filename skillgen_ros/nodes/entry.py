"""Console-script entry points of the node executables: Ctrl-C is quiet from the first instant.

A node's imports (rclpy, numba, pybullet, open3d) take from half a second to seconds. A Ctrl-C in
that window (a launch stopped while it starts) used to raise KeyboardInterrupt inside an import
and print its traceback. The console script imports only this module, which imports nothing
heavy, installs the quiet stop handlers (runtime.run_nodes keeps the same stop flag), then imports
the node; a stop asked for meanwhile ends the process at once with status 0.
"""
from __future__ import annotations

import importlib
import signal

class StopFlag:
    """Set by SIGINT/SIGTERM. A plain bool, not a threading.Event: Event.set() takes a lock, and a second
    signal arriving inside the first handler's set() re-entered it and waited on that lock forever (a
    mock_driver whose pytest was SIGKILLed hung so, 2026-12-05: four nested set() frames)."""

    def __init__(self) -> None:
        self._set = False

    def set(self) -> None:
        self._set = True  # one attribute store: atomic under the GIL, safe to repeat and to interrupt

    def is_set(self) -> bool:
        return self._set


STOP = StopFlag()  # set by SIGINT/SIGTERM from the first instant of the process


def quiet_stop_signals() -> StopFlag:
    """SIGINT/SIGTERM set STOP instead of raising KeyboardInterrupt. runtime.run_nodes installs them
    again before rclpy.init, whose handler shuts the context down (the executor's spin returns) and
    then calls this one. A KeyboardInterrupt can land anywhere, inside rclpy's executor too: it once
    left a node handle marked in use, and destroy_node then waited forever (a launch Ctrl-C test
    hung in CI)."""
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda _signum, _frame: STOP.set())
    # `skillgen launch` starts nodes with both blocked (cli/launcher.py): one sent meanwhile is
    # delivered now, to the handlers above
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    return STOP


def _run(node: str) -> int:
    quiet_stop_signals()
    module = importlib.import_module(f"skillgen_ros.nodes.{node}")
    return 0 if STOP.is_set() else module.main()


def _entry(node: str):
    def main() -> int:
        return _run(node)

    main.__name__ = main.__qualname__ = node
    return main


# setup.py's console scripts: `<node> = skillgen_ros.nodes.entry:<node>`
sim_driver = _entry("sim_driver")
mock_driver = _entry("mock_driver")
perception = _entry("perception")
planner = _entry("planner")
skill_replay = _entry("skill_replay")
datagen = _entry("datagen")
hsp = _entry("hsp")
recorder = _entry("recorder")
player = _entry("player")
teleop = _entry("teleop")
container = _entry("container")
viewer = _entry("viewer")
