"""`skillgen run` and `skillgen launch`: start package executables the way ros2 run/launch would.

Executables are resolved through the ament index (<prefix>/lib/skillgen_ros/<exe>), exactly as
`ros2 run` does, and every child gets the loopback-only ROS environment and one math thread
(rosenv.node_environment). `launch` starts a graph's nodes as separate processes, forwards
Ctrl-C/SIGTERM to them, and if one dies on its own it names that node, stops the rest and exits
non-zero (with `--respawn` it starts the node again instead, like launch's respawn=True). A node still running 15 s after the stop is named, asked for its stacks (SIGUSR1) and
terminated, like ros2 launch's SIGTERM/SIGKILL escalation. With a log dir (the `skillgen launch`
default, `logs/<graph>_<UTC time>/`; `skillgen generate` uses the run's output dir) each node's
output goes to a file of its own and the terminal shows only its warnings and errors
(cli/node_logs.py); `--verbose` streams every node's output as before.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from skillgen_ros import rosenv
from skillgen_ros.shm import clean_zombie_files
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.graphs import PACKAGE, UnknownNodeError, load_graph, node_executables, processes


def resolve_executable(exe: str) -> Path:
    """prefix/lib/skillgen_ros/<exe> from the ament index; UNKNOWN_NODE if absent."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    known = node_executables()
    if exe not in known:
        raise UnknownNodeError(f"'{exe}' is not an executable of {PACKAGE}; known: {', '.join(known)}")
    try:
        prefix = Path(get_package_prefix(PACKAGE))
    except PackageNotFoundError as e:  # not installed into the ament index: run bootstrap
        raise UnknownNodeError(f"{PACKAGE} is not in the ament index ({e}); run scripts/bootstrap.sh") from e
    path = prefix / "lib" / PACKAGE / exe
    if not os.access(path, os.X_OK):
        raise UnknownNodeError(f"{path} is missing or not executable; run scripts/bootstrap.sh")
    return path


def _hold_stop_signals() -> None:
    """In a starting node (before exec): SIGINT/SIGTERM stay pending, not lost and not raised, until
    nodes/entry.py has its quiet handlers (issue 19: a Ctrl-C while the interpreter imported the
    entry module printed a KeyboardInterrupt traceback; the blocked mask survives exec)."""
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})


def run(exe: str, args: list[str]) -> int:
    path = resolve_executable(exe)
    env = rosenv.node_environment(dict(os.environ))
    os.execve(str(path), [str(path), *args], env)
    return 0  # not reached


RESPAWN_MAX = 10  # restarts per node before --respawn gives up on it (a crash loop is a failure)


def default_log_dir(graph: str) -> str:
    """logs/<graph>_<UTC second>_<pid>: two graphs launched in the same second (two Ray graph-mode workers)
    no longer share, and interleave, one set of node logs."""
    return os.path.join("logs", f"{graph}_{time.strftime('%Y%m%dT%H%M%S', time.gmtime())}_{os.getpid()}")


def launch(graph: str, extra_ros_args: list[str] | None = None, poll: float = 0.1, stop_timeout: float = 15.0,
           respawn: bool = False, log_dir: str | None = None) -> int:
    """Run a graph until Ctrl-C or a node dies; a node still running `stop_timeout` s after the
    stop is named, has its Python stacks dumped (SIGUSR1, runtime.py) and is terminated. With
    `respawn` (launch's respawn=True) a node that dies is started again, up to RESPAWN_MAX times.
    With `log_dir` each node's output goes to <log_dir>/<node>.log and only its warnings and
    errors reach the terminal; without, every node streams to the terminal."""
    nodes = load_graph(graph)
    logs = None
    if log_dir:
        from skillgen_ros.cli.node_logs import NodeLogs

        logs = NodeLogs(log_dir)
        print(f"[launch] {graph}: node logs in {log_dir} (warnings and errors shown here; --verbose streams all)",
              file=sys.stderr, flush=True)
    clean_zombie_files()  # what killed ROS processes left in /dev/shm (skillgen_ros/shm.py)
    g = _Supervisor(rosenv.node_environment(dict(os.environ)), logs, respawn)
    old = {s: signal.signal(s, g.forward) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        g.start_all(nodes, extra_ros_args or [])
        return g.supervise(poll, stop_timeout)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for _, p in g.procs:
            if p.poll() is None:
                p.kill()
        if logs is not None:
            logs.close()


class _Supervisor:
    """A launched graph's processes: started, respawned or stopped as their exits and Ctrl-C say.
    `forward` is the SIGINT/SIGTERM handler: it can run between any two lines of the rest."""

    def __init__(self, env: dict, logs, respawn: bool):
        self.env, self.logs, self.respawn = env, logs, respawn
        self.procs: list[tuple[str, subprocess.Popen]] = []
        self.cmds: dict[str, list[str]] = {}
        self.restarts: dict[str, int] = {}
        self.stopping = False

    def forward(self, signum, _frame=None) -> None:
        self.stopping = True
        for _, p in self.procs:
            if p.poll() is None:
                p.send_signal(signum)

    def _popen(self, label: str, cmd: list[str]) -> subprocess.Popen:
        if self.logs is None:
            return subprocess.Popen(cmd, env=self.env, preexec_fn=_hold_stop_signals)
        with self.logs.open(label) as f:  # the child keeps its own descriptor
            return subprocess.Popen(cmd, env=self.env, preexec_fn=_hold_stop_signals, stdout=f,
                                    stderr=subprocess.STDOUT)

    def start_all(self, nodes, extra_ros_args: list[str]) -> None:
        for proc in processes(nodes):
            if self.stopping:  # Ctrl-C while starting: start no more
                break
            cmd = [str(resolve_executable(proc.exe)), *proc.args, *extra_ros_args]
            if self.logs is None:
                print(f"[launch] starting {proc.label}: {' '.join(cmd)}", file=sys.stderr, flush=True)
            child = self._popen(proc.label, cmd)
            self.procs.append((proc.label, child))
            self.cmds[proc.label] = cmd
            if self.stopping:  # the signal came while this one was starting: it missed the forward
                child.send_signal(signal.SIGINT)

    def _check_exits(self) -> tuple[str, int] | None:
        """Respawn the nodes that died (with --respawn, within RESPAWN_MAX); the first one that
        may not be respawned, as (name, exit code), stops the graph."""
        for i, (name, p) in enumerate(self.procs):
            rc = p.poll()
            if rc is None:
                continue
            if not (self.respawn and self.restarts.get(name, 0) < RESPAWN_MAX):
                return name, rc
            self.restarts[name] = self.restarts.get(name, 0) + 1
            print(f"[launch] node '{name}' exited with code {rc}; respawning it "
                  f"({self.restarts[name]}/{RESPAWN_MAX})", file=sys.stderr, flush=True)
            self.procs[i] = (name, self._popen(name, self.cmds[name]))
            if self.stopping:  # Ctrl-C came while it started: forward() saw the dead one
                self.procs[i][1].send_signal(signal.SIGINT)
        return None

    def _stop_for(self, failed: tuple[str, int]) -> None:
        print(f"[launch] node '{failed[0]}' exited with code {failed[1]}; stopping the graph",
              file=sys.stderr, flush=True)
        if self.logs is not None:
            print(f"[launch] the end of its log {self.logs.path(failed[0])}:\n  "
                  + "\n  ".join(self.logs.tail(failed[0])), file=sys.stderr, flush=True)
        self.forward(signal.SIGINT)

    def supervise(self, poll: float, stop_timeout: float) -> int:
        """Until every node has exited (after a stop, or one node's death): the exit code."""
        failed: tuple[str, int] | None = None
        stop_deadline: float | None = None
        escalated: list[str] = []
        while True:
            alive = [(name, p) for name, p in self.procs if p.poll() is None]
            if not self.stopping:
                failed = self._check_exits()
                if failed:
                    self._stop_for(failed)
            if not alive:
                break
            if self.stopping and stop_deadline is None:
                stop_deadline = time.monotonic() + stop_timeout
            if stop_deadline is not None and time.monotonic() > stop_deadline:
                escalated = _escalate(alive)
                if self.logs is not None:
                    for name in escalated:
                        print(f"[launch] {name}'s stacks are in {self.logs.path(name)}", file=sys.stderr, flush=True)
                break
            time.sleep(poll)
        _wait_all(self.procs, timeout=10.0)
        if failed:
            return failed[1] if failed[1] > 0 else 1
        bad = [(n, p.returncode) for n, p in self.procs
               if n in escalated or p.returncode not in (0, -signal.SIGINT, -signal.SIGTERM)]
        for n, rc in bad:
            print(f"[launch] node '{n}' exited with code {rc}", file=sys.stderr)
        return 1 if bad else 0


def _escalate(alive: list[tuple[str, subprocess.Popen]]) -> list[str]:
    """What ros2 launch does to a node that ignores SIGINT (SIGTERM, then SIGKILL via _wait_all),
    plus its stacks on stderr, so a hang is diagnosable from a CI log."""
    for name, p in alive:
        print(f"[launch] node '{name}' did not stop after Ctrl-C; its stacks, then SIGTERM:", file=sys.stderr, flush=True)
        try:
            p.send_signal(signal.SIGUSR1)
            time.sleep(0.5)
            p.send_signal(signal.SIGTERM)
        except ProcessLookupError:
            pass
    return [name for name, _ in alive]


def _wait_all(procs, timeout: float) -> None:
    end = time.monotonic() + timeout
    for _, p in procs:
        try:
            p.wait(max(0.0, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@contextmanager
def graph_client(graph: str, make_client, server: str, startup_timeout: float, ros_args: list[str] | None = None,
                 respawn: bool = False, log_dir: str | None = None):
    """Launch `graph` (`skillgen launch`) in its own session, yield an action client once `server`
    answers, and stop the graph on exit (SIGINT, which the launcher forwards to every node once;
    SIGKILL to the session after 30 s). GRAPH_DIED / GRAPH_NOT_READY if it never comes up.
    ros_args ("--ros-args", "-p", "node:name:=value", ...) reach every node, as `skillgen launch`'s do;
    `respawn` restarts a node that dies (`--respawn`). With `log_dir` the nodes log there (only
    warnings and errors reach the terminal); without, they stream to the terminal (`--verbose`)."""
    logging = ["--log-dir", log_dir] if log_dir else ["--verbose"]
    proc = subprocess.Popen([sys.executable, "-m", "skillgen_ros.cli.main", "launch", graph, *logging,
                             *(["--respawn"] if respawn else []), *(ros_args or [])],
                            env=rosenv.ros_environment(dict(os.environ)), start_new_session=True)
    client = None
    try:
        client = make_client()
        end = time.monotonic() + startup_timeout
        while not client.wait_for_server(1.0) and time.monotonic() < end:
            if proc.poll() is not None:
                raise SkillGenError(f"the {graph} graph stopped during start-up (exit {proc.returncode})",
                                    reason="GRAPH_DIED")
        if not client.wait_for_server(0.1):
            raise SkillGenError(f"the {graph} graph did not come up ({server} action missing)",
                                reason="GRAPH_NOT_READY")
        yield proc, client
    finally:
        try:
            if client is not None:
                client.close()
        finally:  # the graph is stopped even if closing the client fails
            _stop_graph(proc)


def _stop_graph(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
