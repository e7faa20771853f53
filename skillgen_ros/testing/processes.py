"""Node processes a test starts: own process group, log file, stop that always ends them.

Each node runs in its own session (process group), so a stop reaches everything it started (a
container, a launcher's children), and its output goes to a log file, never a pipe (a chatty node
must not block on a full pipe buffer). Stopping is what `ros2 launch` does: SIGINT, then SIGTERM,
then SIGKILL to the whole group, each with a budget. Nothing is left behind when the test fails
(fixture teardown), when pytest exits without teardown (atexit), or when pytest itself is killed
(the kernel sends the node SIGTERM when its parent dies: PR_SET_PDEATHSIG).
"""
from __future__ import annotations

import atexit
import ctypes
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
import threading
import time
from pathlib import Path

_PR_SET_PDEATHSIG = 1
try:
    _prctl = ctypes.CDLL(None, use_errno=True).prctl  # resolved here: nothing to look up after fork
except (OSError, AttributeError):  # not Linux: atexit and teardown still apply
    _prctl = None

_LIVE: set["RosProcess"] = set()
_LIVE_LOCK = threading.Lock()


def die_with_parent(parent: int):
    """A Popen preexec_fn: the child gets SIGTERM when `parent` (the caller, os.getpid()) dies."""
    def _pre_exec() -> None:  # runs in the child between fork and exec: no imports, no allocation
        _prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:  # the parent died before prctl took effect
            os._exit(1)
    return _pre_exec if _prctl is not None else None


def node_command(exe: str) -> list[str]:
    """How to start one of the package's executables: its console script (bin/, or the ament
    layout lib/skillgen_ros/), else the entry point through this interpreter."""
    for d in (sysconfig.get_path("scripts"), str(Path(sys.prefix) / "bin"),
              str(Path(sys.prefix) / "lib" / "skillgen_ros")):
        found = shutil.which(exe, path=d)
        if found:
            return [found]
    from importlib.metadata import entry_points

    for ep in entry_points(group="console_scripts"):
        if ep.name == exe and ep.value.startswith("skillgen_ros."):
            mod, fn = ep.value.split(":")
            return [sys.executable, "-c", f"import sys; from {mod} import {fn}; sys.exit({fn}())"]
    raise FileNotFoundError(f"no executable '{exe}' of skillgen_ros is installed")


def process_env(domain: int, log_dir: Path | None = None, **extra) -> dict:
    """The environment of a node started by a test: loopback discovery in `domain`, unbuffered
    output, rcl's log files in `log_dir`, one math thread (rosenv.node_environment)."""
    from skillgen_ros import rosenv  # here, not at plugin load: importing rosenv sets os.environ's ROS defaults

    env = rosenv.node_environment(dict(os.environ))
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    if log_dir is not None:
        env["ROS_LOG_DIR"] = str(log_dir)
    env.update({k: str(v) for k, v in extra.items()})
    return env


class RosProcess:
    """One started process; `stop()` ends it and everything in its process group."""

    def __init__(self, label: str, cmd: list[str], env: dict, log_path: Path, cwd: Path | None = None):
        self.label = label
        self.cmd = cmd
        self.log_path = Path(log_path)
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=self._log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, start_new_session=True,
                                     preexec_fn=die_with_parent(os.getpid()))
        self.pid = self.proc.pid
        with _LIVE_LOCK:
            _LIVE.add(self)

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    @property
    def returncode(self) -> int | None:
        return self.proc.poll()

    def output(self) -> str:
        """Everything the process has written so far."""
        try:
            return self.log_path.read_bytes().decode(errors="replace")
        except OSError:
            return ""

    def _exited(self) -> bool:
        """True once the process has exited, without reaping it: its group ID stays reserved, so
        a last SIGKILL to the group cannot reach a stranger."""
        if self.proc.returncode is not None:
            return True
        try:
            return os.waitid(os.P_PID, self.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
        except ChildProcessError:
            return True

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def stop(self, timeout: float = 10.0, term_timeout: float = 5.0) -> int:
        """SIGINT (a node's clean stop: a recorder closes its bag), SIGTERM after `timeout` s,
        SIGKILL after `term_timeout` more; every signal goes to the whole process group. Returns
        the exit status."""
        if self.proc.returncode is None:
            for sig, budget in ((signal.SIGINT, timeout), (signal.SIGTERM, term_timeout), (signal.SIGKILL, 5.0)):
                if self._exited():
                    break
                self._signal_group(sig)
                end = time.monotonic() + budget
                while not self._exited() and time.monotonic() < end:
                    time.sleep(0.02)  # polling the process table, the state we wait on
            self._signal_group(signal.SIGKILL)  # whatever it started and left behind
            self.proc.wait()
        self._log.close()
        with _LIVE_LOCK:
            _LIVE.discard(self)
        return self.proc.returncode

    def __repr__(self) -> str:
        return f"RosProcess({self.label!r}, pid={self.pid}, rc={self.returncode})"


def live_processes() -> list[RosProcess]:
    with _LIVE_LOCK:
        return list(_LIVE)


def stop_all(timeout: float = 3.0) -> None:
    """Stop every process still running (pytest ending without teardown)."""
    for p in live_processes():
        p.stop(timeout=timeout, term_timeout=2.0)


atexit.register(stop_all)
