"""`skillgen run` / `skillgen launch`: resolution, Ctrl-C forwarding, a dying node, clear errors."""
import os
import signal
import subprocess
import sys
from pathlib import Path

import psutil
import yaml

from conftest import REPO, node_env, wait_for

SKILLGEN = [sys.executable, "-m", "skillgen_ros.cli.main"]


def _run(args, env, timeout=60):
    return subprocess.run(SKILLGEN + args, env=env, capture_output=True, text=True, timeout=timeout, cwd=REPO)


def test_unknown_graph_and_node_give_one_line_errors(ros_domain, tmp_path):
    env = node_env(ros_domain)
    r = _run(["launch", "no_such_graph"], env)
    assert r.returncode == 2 and "UNKNOWN_GRAPH" in r.stderr and "Traceback" not in r.stderr
    r = _run(["run", "no_such_node"], env)
    assert r.returncode == 2 and "UNKNOWN_NODE" in r.stderr and "Traceback" not in r.stderr
    bad = tmp_path / "graphs.yaml"
    bad.write_text("graphs:\n  broken:\n    nodes:\n      - exe: warp_drive\n")
    r = _run(["launch", "broken"], node_env(ros_domain, SKILLGEN_GRAPHS=bad))
    assert r.returncode == 2 and "UNKNOWN_NODE" in r.stderr and "warp_drive" in r.stderr


def test_invalid_params_file_is_a_clear_error(ros_domain, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("mock_driver: [this is: not a params file\n")
    r = _run(["run", "mock_driver", "--ros-args", "--params-file", str(bad)], node_env(ros_domain))
    assert r.returncode == 2 and "INVALID_PARAMETER" in r.stderr and "Traceback" not in r.stderr
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("mock_driver:\n  ros__parameters:\n    control_hz: fast\n")
    r = _run(["run", "mock_driver", "--ros-args", "--params-file", str(wrong)], node_env(ros_domain))
    assert r.returncode == 2 and "INVALID_PARAMETER" in r.stderr and "Traceback" not in r.stderr
    release = tmp_path / "release.yaml"
    for bad in ("settle_steps: -1", "unjam_step: 0.0", "follow: .nan"):
        release.write_text(f"datagen:\n  ros__parameters:\n    release:\n      {bad}\n")
        r = _run(["run", "datagen", "--ros-args", "--params-file", str(release)], node_env(ros_domain))
        named = bad.split(":")[0] + "="  # the message names the bad setting, not just the whole config
        assert r.returncode == 2 and "INVALID_PARAMETER" in r.stderr and named in r.stderr, (bad, r.stderr)
        assert sum(f"{k}=" in r.stderr for k in ("settle_steps", "unjam_step", "follow")) == 1, r.stderr


def _children(p):
    return psutil.Process(p.pid).children()


def _bags(cwd: Path) -> list[Path]:
    return sorted(cwd.glob("bags/rec_*"))


def _finalized(bag: Path) -> bool:
    """The recorder's own word that it closed the bag (metadata.yaml custom_data), not just a file."""
    try:
        meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return False
    return meta["custom_data"].get("skillgen.finalized") == "true"


def test_launch_forwards_ctrl_c_to_every_node(ros_domain, tmp_path):
    p = subprocess.Popen(SKILLGEN + ["launch", "mock_record"], env=node_env(ros_domain),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                         start_new_session=True)
    try:
        assert wait_for(lambda: len(_children(p)) == 2, 20)
        kids = _children(p)
        assert wait_for(lambda: _bags(tmp_path), 120), "the recorder never started recording"  # nodes are up
        p.send_signal(signal.SIGINT)
        assert p.wait(30) == 0, p.stderr.read()
        bags = _bags(tmp_path)
        assert len(bags) == 1 and _finalized(bags[0])  # the recorder finalized its bag
        assert not any(k.is_running() and k.status() != psutil.STATUS_ZOMBIE for k in kids)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)


def test_ctrl_c_during_start_up_stops_the_graph_cleanly(ros_domain, tmp_path):
    """Ctrl-C while the launcher or its nodes are still starting: once it hung the launcher (a node
    started after the forward never got it) and aborted the recorder (its io executor still
    spinning at exit), and a Ctrl-C while a node was still importing its modules printed a
    KeyboardInterrupt traceback (nodes/entry.py). Several moments of start-up; each must end at
    once, exit 0, no traceback, bag finalized."""
    stages = {  # moments of start-up, each an observable state rather than a delay
        "first node spawned": lambda p, cwd: len(_children(p)) >= 1,  # the launcher's handler is in place
        "nodes spawned": lambda p, cwd: len(_children(p)) == 2,
        "a node importing rclpy": lambda p, cwd: any(_loading(k.pid, "rclpy") for k in _children(p)),
        "recording": lambda p, cwd: bool(_bags(cwd)),
    }
    for k, (stage, reached) in enumerate(stages.items()):
        cwd = tmp_path / str(k)
        cwd.mkdir()
        p = subprocess.Popen(SKILLGEN + ["launch", "mock_record"], env=node_env(ros_domain), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, cwd=cwd, start_new_session=True)
        try:
            assert wait_for(lambda: _alive_children_ok(p) and reached(p, cwd), 120, 0.002), stage
            p.send_signal(signal.SIGINT)
            rc = p.wait(30)
            err = p.stderr.read()
            assert rc == 0 and "terminate called" not in err and "Traceback" not in err, (stage, rc, err)
            assert all(_finalized(b) for b in _bags(cwd)), stage  # any bag begun is finalized
            if stage == "recording":
                assert len(_bags(cwd)) == 1  # and here there is one: the check above is not vacuous
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)


def _alive_children_ok(p) -> bool:
    try:
        _children(p)
        return True
    except psutil.NoSuchProcess:
        return False


def _loading(pid: int, marker: str) -> bool:
    """The process has mapped a shared library whose path contains `marker` (it is importing)."""
    try:
        return any(marker in m.path for m in psutil.Process(pid).memory_maps())
    except (psutil.NoSuchProcess, psutil.AccessDenied):
        return False


def test_ctrl_c_while_a_node_imports_its_modules_is_a_quiet_stop(ros_domain):
    """The node executables make Ctrl-C quiet before their slow imports (nodes/entry.py): stopped
    while it loads (rclpy's native module just mapped, the node not yet built), a node exits 0
    without a traceback. (Importing the node module directly, as the console script once did,
    died of the KeyboardInterrupt there: exit -2 and a traceback.)"""
    exe = Path(sys.prefix) / "bin" / "mock_driver"  # the console script, as ros2 run starts it
    for attempt in range(2):
        p = subprocess.Popen([str(exe)], env=node_env(ros_domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, start_new_session=True)
        try:
            assert wait_for(lambda: _loading(p.pid, "rclpy"), 20, 0.002), "never loaded rclpy"
            p.send_signal(signal.SIGINT)
            rc = p.wait(30)
            err = p.stderr.read()
            assert rc == 0 and "Traceback" not in err and "KeyboardInterrupt" not in err, (attempt, rc, err)
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)


def test_ctrl_c_while_the_launcher_starts_a_node_reaches_it_and_starts_no_more(ros_domain, tmp_path, monkeypatch):
    """The launcher race, made deterministic: Ctrl-C lands while the first node's Popen runs (before
    it is in the list the forward walks). That node must still get it, and the second never start."""
    from skillgen_ros.cli import launcher

    started = []
    real_popen = subprocess.Popen

    def popen_then_ctrl_c(cmd, **kw):
        child = real_popen(cmd, **kw)
        started.append(child)
        os.kill(os.getpid(), signal.SIGINT)  # handled by the launcher's handler at the next bytecode
        return child

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(launcher.subprocess, "Popen", popen_then_ctrl_c)
    assert launcher.launch("mock_record", stop_timeout=20.0) == 0
    assert len(started) == 1 and started[0].poll() is not None


def test_a_node_that_ignores_ctrl_c_is_named_dumped_and_terminated():
    from skillgen_ros.cli.launcher import _escalate

    stubborn = ("import faulthandler, signal, time\n"
                "faulthandler.register(signal.SIGUSR1, all_threads=True)\n"
                "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
                "def waiting_forever():\n    print('up', flush=True)\n    time.sleep(60)\nwaiting_forever()\n")
    p = subprocess.Popen([sys.executable, "-c", stubborn], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "up"  # printed from inside waiting_forever: its frame is live
        p.send_signal(signal.SIGINT)
        assert _escalate([("stubborn", p)]) == ["stubborn"]
        assert p.wait(10) == -signal.SIGTERM
        assert "waiting_forever" in p.stderr.read()  # its stack, for the CI log
    finally:
        if p.poll() is None:
            p.kill()


def test_launch_names_the_node_that_died_and_stops_the_rest(ros_domain, tmp_path):
    p = subprocess.Popen(SKILLGEN + ["launch", "mock_record"], env=node_env(ros_domain),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                         start_new_session=True)
    try:
        assert wait_for(lambda: len(_children(p)) == 2, 20)
        assert wait_for(lambda: _bags(tmp_path), 120), "the graph never came up"  # the recorder records
        victim = next(k for k in _children(p) if "mock_driver" in " ".join(k.cmdline()))
        others = [k for k in _children(p) if k.pid != victim.pid]
        victim.kill()
        rc = p.wait(30)
        err = p.stderr.read()
        assert rc != 0 and "'mock_driver'" in err, err
        assert all(not k.is_running() or k.status() == psutil.STATUS_ZOMBIE for k in others)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)


def test_container_runs_several_nodes_in_one_process(ros_domain, tmp_path):
    """Two composed nodes answer as separate nodes; node-targeted parameters reach only their node;
    an unknown node name is a one-line error."""
    from conftest import client_node

    r = _run(["run", "container", "mock_driver", "warp_drive"], node_env(ros_domain))
    assert r.returncode == 2 and "UNKNOWN_NODE" in r.stderr and "Traceback" not in r.stderr
    p = subprocess.Popen(SKILLGEN + ["run", "container", "mock_driver", "skill_replay", "--ros-args",
                                     "--params-file", str(REPO / "params" / "mock_driver.yaml"),
                                     "-p", "mock_driver:control_hz:=7.0", "-p", "skill_replay:feedback_hz:=3.0"],
                         env=node_env(ros_domain), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         cwd=REPO, start_new_session=True)
    try:
        from rclpy.parameter_client import AsyncParameterClient

        with client_node(ros_domain, "container_probe") as (node, ex):
            assert wait_for(lambda: {"mock_driver", "skill_replay"} <= set(node.get_node_names()), 30)
            got = {}
            for name in ("mock_driver", "skill_replay"):
                cli = AsyncParameterClient(node, name)
                assert cli.wait_for_services(timeout_sec=20)
                fut = cli.get_parameters(["control_hz" if name == "mock_driver" else "feedback_hz"])
                ex.spin_until_future_complete(fut, timeout_sec=20)
                got[name] = fut.result().values[0].double_value
            assert got == {"mock_driver": 7.0, "skill_replay": 3.0}
        assert len(psutil.Process(p.pid).children(recursive=True)) == 0  # one process, no helpers
    finally:
        os.killpg(p.pid, signal.SIGINT)
        p.wait(30)


def test_respawn_restarts_a_killed_node_and_the_graph_goes_on(ros_domain, tmp_path):
    """`skillgen launch --respawn`: a node killed with SIGKILL is started again (a new process of the
    same node), the rest keep running, and Ctrl-C still stops everything cleanly with the bag finalized."""
    p = subprocess.Popen(SKILLGEN + ["launch", "mock_record", "--respawn"], env=node_env(ros_domain),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                         start_new_session=True)
    try:
        assert wait_for(lambda: len(_children(p)) == 2 and _bags(tmp_path), 120), "the graph never came up"
        victim = next(k for k in _children(p) if "mock_driver" in " ".join(k.cmdline()))
        recorder = next(k for k in _children(p) if k.pid != victim.pid)
        victim.kill()

        def respawned() -> bool:
            kids = []
            for k in _children(p):
                try:
                    if k.status() != psutil.STATUS_ZOMBIE and "mock_driver" in " ".join(k.cmdline()):
                        kids.append(k)
                except psutil.Error:  # the killed one, gone or not yet reaped
                    pass
            return bool(kids) and all(k.pid != victim.pid for k in kids)
        assert wait_for(respawned, 60), "mock_driver was not respawned"
        assert p.poll() is None and recorder.is_running()  # the rest of the graph went on
        p.send_signal(signal.SIGINT)
        assert p.wait(60) == 0, p.stderr.read()
        err = p.stderr.read()
        assert "respawning it (1/" in err, err
        assert len(_bags(tmp_path)) == 1 and _finalized(_bags(tmp_path)[0])
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
