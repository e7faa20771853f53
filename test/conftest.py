"""Shared pytest fixtures.

The ROS fixtures (ros_domain, ros_node, graph, mock_driver, sim_driver, ros_artifacts) come from
the project's own pytest plugin, skillgen_ros.testing (docs/testing.md); the suite loads it
explicitly below, which is harmless where the installed `pytest11` entry point has already
registered it under the same name. Every test that starts a ROS context gets its own
ROS_DOMAIN_ID, and every ROS process runs loopback-only (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST),
so tests never hear each other and never send traffic off this machine.

The helpers below predate the plugin and stay for the tests that build their graphs by hand.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from skillgen_ros import rosenv

if "skillgen_ros.testing" not in sys.modules:  # not yet loaded by the entry point: mark it as pytest_plugins
    pytest.register_assert_rewrite("skillgen_ros.testing")  # would, before it is imported here (no warning)
from skillgen_ros.testing.domains import acquire_domain  # noqa: E402
from skillgen_ros.testing.processes import die_with_parent  # noqa: E402
from skillgen_ros.testing.wait import wait_for  # noqa: E402,F401  (imported from here by tests)

pytest_plugins = ["skillgen_ros.testing", "pytester"]

REPO = Path(__file__).resolve().parents[1]
_EMPTY_MODULES: list[str] = []


def pytest_collectreport(report):
    """Note a test module that collects nothing (a broken import guard, a renamed fixture)."""
    if report.passed and report.nodeid.endswith(".py") and "/test_" in "/" + report.nodeid and not report.result:
        _EMPTY_MODULES.append(report.nodeid)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """pytest-xdist's controller: collect the empty modules each worker found (they collect, it does not)."""
    _EMPTY_MODULES.extend(m for m in getattr(node, "workeroutput", {}).get("empty_modules", ())
                          if m not in _EMPTY_MODULES)


def pytest_sessionfinish(session, exitstatus):
    """An empty collection is a failure, not a pass (issue 19): no tests at all, or a test module
    that holds none (unless -k/-m chose to deselect). Under pytest-xdist a worker hands its list to
    the controller (pytest_testnodedown), whose exit status is the run's."""
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput["empty_modules"] = list(_EMPTY_MODULES)
        return
    filtered = session.config.getoption("keyword") or session.config.getoption("markexpr")
    if exitstatus == pytest.ExitCode.NO_TESTS_COLLECTED or (_EMPTY_MODULES and not filtered):
        if _EMPTY_MODULES:
            print(f"\ntest modules that collected no tests: {', '.join(_EMPTY_MODULES)}", file=sys.stderr)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


VENV_BIN = Path(sys.prefix) / "bin"

_module_leases: list = []


def next_domain_id() -> int:
    """A domain ID held (lock file, skillgen_ros.testing.domains) until the calling test module
    ends: for module-scoped graphs. SKILLGEN_TEST_DOMAIN_BASE pins the pool to ten IDs."""
    lease = acquire_domain()
    _module_leases.append(lease)
    return lease.id


@pytest.fixture(autouse=True)
def _scheduling_unchanged():
    """Fail the test that leaves this process at another scheduling policy or nice value: every node the suite
    starts afterwards inherits it. SVT-AV1 (the LeRobot export's video codec), run as root, once left pytest at
    SCHED_FIFO 99, and each later node test ran 3-6x slower on a real-time machine (2026-12-05)."""
    def now():
        return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, os.getpriority(os.PRIO_PROCESS, 0)
    before = now()
    yield
    after = now()
    if after != before:
        os.sched_setscheduler(0, before[0], os.sched_param(before[1]))  # the next tests run as they should
        pytest.fail(f"the test changed this process's (policy, rt priority, nice) from {before} to {after}")


@pytest.fixture(scope="module", autouse=True)
def _release_module_domains():
    """Frees next_domain_id()'s leases after the module's own fixtures (set up later) stopped."""
    yield
    while _module_leases:
        _module_leases.pop().release()


def node_env(domain: int, **extra) -> dict:
    env = rosenv.ros_environment(dict(os.environ))
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    env.update({k: str(v) for k, v in extra.items()})
    return env


class NodeProcess:
    """A node started as its own process (the way `ros2 run` would), stopped with SIGINT. Its output
    goes to a temporary file, not a pipe: a chatty node must never block on a full pipe buffer. The
    kernel sends it SIGTERM if pytest dies (as the plugin's nodes): a suite killed mid-run left a datagen
    graph behind in its domain, which a later test holding that domain would have met."""

    def __init__(self, exe: str, domain: int, args=(), params: str | None = None, **env):
        cmd = [str(VENV_BIN / exe), *args]
        if params:
            cmd += ["--ros-args", "--params-file", params]
        self.exe = exe
        self.log = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(cmd, env=node_env(domain, **env), stdout=self.log,
                                     stderr=subprocess.STDOUT, cwd=REPO, preexec_fn=die_with_parent(os.getpid()))

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
