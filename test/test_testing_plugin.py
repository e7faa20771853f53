"""The pytest plugin skillgen_ros.testing, tested as users run it: inner pytest sessions (pytester,
separate processes) with real nodes. Covers docs/testing.md's example, clean-up after a failing
and after a killed session, two sessions side by side, and the entry point in a fresh venv."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import psutil
import pytest

from conftest import REPO
from skillgen_ros.testing import wait_for

INNER = ["-p", "skillgen_ros.testing", "-p", "no:cacheprovider", "-q"]  # -p: until the entry point is installed


def _group_members(pgids) -> list[psutil.Process]:
    """Live processes in any of these process groups (a node and whatever it started)."""
    out = []
    for p in psutil.process_iter(["pid", "status"]):
        try:
            if os.getpgid(p.pid) in pgids and p.info["status"] != psutil.STATUS_ZOMBIE:
                out.append(p)
        except (ProcessLookupError, psutil.NoSuchProcess):
            pass
    return out


def _docs_example() -> str:
    text = (REPO / "docs" / "testing.md").read_text()
    return re.search(r"<!-- this block runs as a test.*?-->\n```python\n(.*?)```", text, re.S).group(1)


def test_docs_example_runs(pytester):
    pytester.makepyfile(test_user=_docs_example())
    result = pytester.runpytest_subprocess(*INNER, timeout=180)
    result.assert_outcomes(passed=1)


FAILING = '''
import json, os, pytest
from pathlib import Path

OUT = Path(os.environ["PLUGIN_TEST_OUT"])


@pytest.mark.ros_keep_logs
def test_fails_on_purpose(graph, tmp_path):
    g = graph("mock_record", recorder={"topics": ["joint_states", "ee_pose"]})
    OUT.joinpath("failing.json").write_text(json.dumps(
        {"pids": [p.pid for p in g.processes], "artifacts": str(g.artifacts), "tmp_path": str(tmp_path)}))
    assert g.process("mock_driver").alive and g.process("recorder").alive
    assert False, "fails on purpose"


@pytest.mark.ros_keep_logs
def test_passes(mock_driver):
    OUT.joinpath("passing.json").write_text(json.dumps(
        {"pids": [mock_driver.process.pid], "artifacts": str(mock_driver.graph.artifacts)}))
'''


def test_failing_test_leaves_no_process_and_keeps_its_logs_and_bag(pytester, monkeypatch):
    monkeypatch.setenv("PLUGIN_TEST_OUT", str(pytester.path))
    pytester.makepyfile(test_inner=FAILING)
    result = pytester.runpytest_subprocess(*INNER, timeout=180)
    result.assert_outcomes(failed=1, passed=1)
    failing = json.loads((pytester.path / "failing.json").read_text())
    passing = json.loads((pytester.path / "passing.json").read_text())
    assert not _group_members(set(failing["pids"] + passing["pids"])), "node processes left behind"
    kept = Path(failing["artifacts"])
    assert kept == Path(failing["tmp_path"]) / "ros"
    logs = {p.name: p.read_text() for p in kept.glob("*.log")}
    assert any(name.endswith("mock_driver.log") and "mock_driver up" in text for name, text in logs.items()), logs
    assert any(name.endswith("recorder.log") for name in logs), logs
    assert (kept / "bags" / "recorder" / "metadata.yaml").is_file(), "the recorder's bag was not finalized and kept"
    assert any((kept / "ros_log").rglob("*.log")), "rcl log files go to the artifact directory"
    out = result.stdout.str()
    assert "skillgen_ros nodes" in out and "mock_driver up" in out and str(kept) in out  # the report names them
    assert not Path(passing["artifacts"]).exists(), "a passing test's logs are not kept"


def test_killed_pytest_leaves_no_node_behind(pytester, monkeypatch):
    """The worst timeout: the pytest process is SIGKILLed mid-test, so no teardown or atexit runs;
    the kernel stops the nodes (PR_SET_PDEATHSIG)."""
    monkeypatch.setenv("PLUGIN_TEST_OUT", str(pytester.path))
    pytester.makepyfile(test_killed='''
import json, os, signal
from pathlib import Path


def test_killed(mock_driver):
    Path(os.environ["PLUGIN_TEST_OUT"], "killed.json").write_text(json.dumps([mock_driver.process.pid]))
    os.kill(os.getpid(), signal.SIGKILL)
''')
    result = pytester.runpytest_subprocess(*INNER, timeout=180)
    assert result.ret == -signal.SIGKILL
    pids = set(json.loads((pytester.path / "killed.json").read_text()))
    assert wait_for(lambda: not _group_members(pids), 30), _group_members(pids)


SIDE = '''
import os
from pathlib import Path

from std_msgs.msg import String
from skillgen_ros.testing import wait_for


def test_side(ros_domain, ros_node):
    side, sync = os.environ["SIDE"], Path(os.environ["SYNC_DIR"])
    other = "b" if side == "a" else "a"
    got = {"own": 0, "other": 0}
    for who in (side, other):
        key = "own" if who == side else "other"
        ros_node.create_subscription(String, f"/probe_{who}", lambda m, k=key: got.__setitem__(k, got[k] + 1), 10)
    pub = ros_node.create_publisher(String, f"/probe_{side}", 10)
    sync.joinpath(f"domain_{side}").write_text(str(ros_domain))
    assert wait_for(lambda: sync.joinpath(f"domain_{other}").exists(), 120)
    heard = {"at_start": got["own"]}

    def step():  # publish until both sides have heard 40 of their own messages with the other one up
        pub.publish(String(data=side))
        if got["own"] - heard["at_start"] >= 40:
            sync.joinpath(f"heard_{side}").touch()
        return sync.joinpath(f"heard_{side}").exists() and sync.joinpath(f"heard_{other}").exists()

    assert wait_for(step, 120, period=0.05)
    assert ros_node.count_publishers(f"/probe_{side}") == 1  # discovery works in this domain...
    assert ros_node.count_publishers(f"/probe_{other}") == 0  # ...and the other session is not in it
    assert got["other"] == 0, got
'''


def test_two_pytest_processes_get_different_domains_and_do_not_hear_each_other(pytester):
    """Each session publishes on its own topic and listens on the other's while both run; same
    domain, they would hear each other (the subscriptions to the other topic exist in both)."""
    test = pytester.makepyfile(test_side=SIDE)
    sessions = {side: subprocess.Popen([sys.executable, "-m", "pytest", *INNER, str(test)], cwd=pytester.path,
                                       env={**os.environ, "SIDE": side, "SYNC_DIR": str(pytester.path)},
                                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                for side in "ab"}
    outs = {}
    try:
        for side, p in sessions.items():
            outs[side] = p.communicate(timeout=240)[0]
    finally:
        for p in sessions.values():
            p.kill()
    for side, p in sessions.items():
        assert p.returncode == 0, outs[side]
    domains = {int((pytester.path / f"domain_{s}").read_text()) for s in "ab"}
    assert len(domains) == 2, domains
