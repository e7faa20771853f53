"""Shared pytest fixtures.

Every test that starts a ROS context gets its own ROS_DOMAIN_ID (`ros_domain`), and every ROS
process runs loopback-only (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST), so tests never hear each
other and never send traffic off this machine.
"""
from __future__ import annotations

import contextlib
import itertools
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from skillgen_ros import rosenv

REPO = Path(__file__).resolve().parents[1]
VENV_BIN = Path(sys.prefix) / "bin"

# Domain IDs 0..101 and 215..232 are valid for Fast DDS on one host; spread workers apart.
# SKILLGEN_TEST_DOMAIN_BASE pins a run to its own block of 10 IDs (two suites on one machine).
_PINNED = os.environ.get("SKILLGEN_TEST_DOMAIN_BASE")
_BASE = int(_PINNED) if _PINNED else 10 + (os.getpid() % 8) * 10
_ids = itertools.count()


def next_domain_id() -> int:
    if _PINNED:
        return _BASE + next(_ids) % 10
    return 1 + (_BASE + next(_ids)) % 100


@pytest.fixture
def ros_domain(monkeypatch) -> int:
    """A fresh ROS_DOMAIN_ID for this test, set in os.environ for in-process rclpy and children."""
    dom = next_domain_id()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(dom))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return dom


def node_env(domain: int, **extra) -> dict:
    env = rosenv.ros_environment(dict(os.environ))
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    env.update({k: str(v) for k, v in extra.items()})
    return env


class NodeProcess:
    """A node started as its own process (the way `ros2 run` would), stopped with SIGINT. Its output
    goes to a temporary file, not a pipe: a chatty node must never block on a full pipe buffer."""

    def __init__(self, exe: str, domain: int, args=(), params: str | None = None, **env):
        cmd = [str(VENV_BIN / exe), *args]
        if params:
            cmd += ["--ros-args", "--params-file", params]
        self.exe = exe
        self.log = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(cmd, env=node_env(domain, **env), stdout=self.log,
                                     stderr=subprocess.STDOUT, cwd=REPO)

    def output(self) -> str:
        """Everything the node has written so far."""
        return os.pread(self.log.fileno(), 1 << 24, 0).decode(errors="replace")

    def stop(self, timeout: float = 10.0) -> str:
        if self.proc.poll() is None:
            self.proc.send_signal(2)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.output()


@pytest.fixture
def start_node(ros_domain):
    """start_node(exe, *args, params=...) -> NodeProcess; all are stopped after the test."""
    procs: list[NodeProcess] = []

    def _start(exe: str, *args, params: str | None = None, **env) -> NodeProcess:
        p = NodeProcess(exe, ros_domain, args, params, **env)
        procs.append(p)
        return p

    yield _start
    for p in procs:
        p.stop()


def wait_for(predicate, timeout: float = 10.0, period: float = 0.05) -> bool:
    """Poll `predicate` until true or timeout; returns its last truthiness."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(period)
    return bool(predicate())


@contextlib.contextmanager
def client_node(domain: int, name: str, executor_cls=None, spin: bool = False):
    """(node, executor) in a context of their own on `domain`; the executor (single-threaded by
    default) spins in a background thread if `spin`, else the test spins it. Torn down on exit."""
    import threading

    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    try:
        node = rclpy.create_node(name, context=ctx)
        ex = (executor_cls or SingleThreadedExecutor)(context=ctx)
        ex.add_node(node)
        if spin:
            threading.Thread(target=ex.spin, daemon=True).start()
        try:
            yield node, ex
        finally:
            ex.shutdown()
            node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)


@pytest.fixture
def ros_node(ros_domain, request):
    """An rclpy node in this process, on the test's domain, spun in a background thread."""
    with client_node(ros_domain, f"{request.module.__name__.split('.')[-1]}_node", spin=True) as (node, _):
        yield node
