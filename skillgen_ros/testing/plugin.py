"""The pytest plugin's hooks and fixtures (see skillgen_ros/testing/__init__.py and docs/testing.md).

Imports nothing from ROS at load time: the plugin is active in every pytest session where
skillgen_ros is installed, and a session that uses none of its fixtures must not pay for rclpy.
"""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest

from skillgen_ros.testing.domains import acquire_domain

KEEP_MARK = "ros_keep_logs"
_TAIL_LINES = 30


def pytest_addoption(parser):
    group = parser.getgroup("skillgen_ros", "skillgen_ros ROS fixtures")
    group.addoption("--ros-keep-logs", action="store_true", default=None,
                    help="keep a failing test's node logs and bags in its tmp_path/ros (as the ros_keep_logs marker)")
    group.addoption("--ros-ready-timeout", type=float, default=None,
                    help="seconds a graph fixture waits for its nodes to answer (default 60)")
    parser.addini("ros_keep_logs", type="bool", default=False, help="as --ros-keep-logs")
    parser.addini("ros_ready_timeout", default="60", help="as --ros-ready-timeout")


def pytest_configure(config):
    for line in (f"{KEEP_MARK}: keep this test's node logs and bags in tmp_path/ros if it fails",
                 "mock_driver(**parameters): parameter overrides for the mock_driver fixture",
                 "sim_driver(task='', variant='D0', seed=0, **parameters): the sim_driver fixture's initial "
                 "scene and parameter overrides"):
        config.addinivalue_line("markers", line)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Remember each phase's report (teardown needs to know if the test failed) and put the end
    of every node's log into a failing test's report."""
    outcome = yield
    rep = outcome.get_result()
    setattr(item, f"_skillgen_ros_rep_{rep.when}", rep)
    artifacts = getattr(item, "_skillgen_ros_artifacts", None)
    if rep.failed and artifacts is not None and artifacts.processes:
        rep.sections.append((f"skillgen_ros nodes ({rep.when})", artifacts.summary(_TAIL_LINES)))


def _test_failed(item) -> bool:
    return any(getattr(getattr(item, f"_skillgen_ros_rep_{w}", None), "failed", False) for w in ("setup", "call"))


def _ready_timeout(config) -> float:
    opt = config.getoption("--ros-ready-timeout", None)
    return float(opt if opt is not None else config.getini("ros_ready_timeout"))


class RosArtifacts:
    """Where a test's node logs, rcl log files and bags go; kept only if asked for and it failed."""

    def __init__(self, path: Path, keep: bool):
        self.path, self.keep = path, keep
        self.processes: list = []

    def summary(self, lines: int) -> str:
        out = []
        for p in self.processes:
            text = p.output().rstrip().splitlines()
            state = "running" if p.alive else f"exited {p.returncode}"
            out.append(f"--- {p.label} (pid {p.pid}, {state}), log {p.log_path}:")
            out.extend(text[-lines:])
        if self.keep:
            out.append(f"node logs and bags are kept in {self.path}")
        return "\n".join(out)


@pytest.fixture
def ros_domain(monkeypatch) -> int:
    """A ROS_DOMAIN_ID no other test on this machine holds (lock files; SKILLGEN_TEST_DOMAIN_BASE
    pins the pool to ten IDs), set in os.environ with loopback-only discovery for in-process rclpy
    and children; restored and freed after the test."""
    lease = acquire_domain()
    try:
        monkeypatch.setenv("ROS_DOMAIN_ID", str(lease.id))
        monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        yield lease.id
    finally:
        lease.release()


@pytest.fixture
def ros_artifacts(request) -> RosArtifacts:
    """The test's artifact directory: tmp_path/ros when logs are to be kept (marker ros_keep_logs,
    --ros-keep-logs or ini ros_keep_logs), else a temporary directory; removed after a passing test."""
    keep = bool(request.node.get_closest_marker(KEEP_MARK)) or bool(
        request.config.getoption("--ros-keep-logs") or request.config.getini("ros_keep_logs"))
    path = request.getfixturevalue("tmp_path") / "ros" if keep else Path(tempfile.mkdtemp(prefix="skillgen_ros_test_"))
    path.mkdir(parents=True, exist_ok=True)
    art = RosArtifacts(path, keep)
    request.node._skillgen_ros_artifacts = art
    yield art
    if not (keep and _test_failed(request.node)):
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def ros_node(ros_domain, request):
    """An rclpy node in this process on the test's domain, its executor spinning in a background
    thread: create clients, publishers and subscriptions on it; futures complete by themselves."""
    from skillgen_ros.testing.handles import spinning_node

    with spinning_node(ros_domain, f"test_{request.node.name}") as node:
        yield node


@pytest.fixture
def graph(ros_domain, ros_node, ros_artifacts, request):
    """graph(name, graphs_file=None, namespace="", timeout=None, env=None, **node_parameters) starts a
    graphs.yaml graph (or one from `graphs_file`) in the test's domain and returns a GraphHandle
    once every node answers; everything it started is stopped after the test, pass or fail."""
    from skillgen_ros.testing.handles import launch_graph

    handles = []

    def _launch(name: str, *, graphs_file=None, namespace: str = "", timeout: float | None = None,
                env: dict | None = None, **node_parameters):
        h = launch_graph(name, ros_domain, ros_node, ros_artifacts.path, graphs_file=graphs_file,
                         namespace=namespace, timeout=timeout or _ready_timeout(request.config), env=env,
                         on_start=ros_artifacts.processes.append, **node_parameters)
        handles.append(h)
        return h

    yield _launch
    try:
        for h in reversed(handles):
            h.stop()
    finally:
        from skillgen_ros.testing.processes import stop_all

        for p in ros_artifacts.processes:  # whatever a failed stop above left running
            if p.alive:
                stop_all()
                break


def _driver_kwargs(request, fixture: str) -> dict:
    kw = {}
    marker = request.node.get_closest_marker(fixture)
    if marker is not None:
        kw.update(marker.kwargs)
    kw.update(getattr(request, "param", None) or {})  # indirect parametrization
    return kw


def _driver(graph, ros_node, request, exe: str, graph_name: str, params: dict):
    from skillgen_ros.testing.handles import DriverHandle

    namespace = params.pop("namespace", "")
    g = graph(graph_name, namespace=namespace, **{exe: params})
    return DriverHandle(g, ros_node, exe, _ready_timeout(request.config))


@pytest.fixture
def mock_driver(graph, ros_node, request):
    """The mock driver (params/mock_driver.yaml; overrides from @pytest.mark.mock_driver(**params)
    or indirect parametrization) in the test's domain, once its services, actions and topics
    answer. Yields a DriverHandle; stopped after the test."""
    handle = _driver(graph, ros_node, request, "mock_driver", "mock", _driver_kwargs(request, "mock_driver"))
    yield handle
    handle.close()


@pytest.fixture
def sim_driver(graph, ros_node, request):
    """The simulated Panda (pybullet), as mock_driver; `task`, `variant` and `seed` (marker
    sim_driver(...) or indirect parametrization) choose its initial scene, and the fixture also
    waits for that scene's ground-truth object poses."""
    kw = _driver_kwargs(request, "sim_driver")
    task, variant, seed = kw.pop("task", ""), kw.pop("variant", "D0"), kw.pop("seed", 0)
    if task:
        kw.update(initial_task=task, initial_variant=variant, initial_seed=int(seed))
    handle = _driver(graph, ros_node, request, "sim_driver", "sim", kw)
    if task:
        try:
            handle.wait_ground_truth(_ready_timeout(request.config))
        except BaseException:
            handle.close()
            raise
    yield handle
    handle.close()
