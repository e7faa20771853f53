"""A clean terminal: each node's output to a file of its own, only its warnings and errors on screen.

`skillgen generate`, `skillgen launch` and `skillgen demos record` start nodes whose INFO lines
(the planner logs every plan_to_pose) would otherwise interleave with the progress bar. Each
node's stdout and stderr go to `<log dir>/<node>.log` (appended, so a respawned node continues
its file); a thread follows the files and copies to the terminal, prefixed with the node's name,
the lines that need a person: ROS log lines of severity WARN, ERROR or FATAL and Python
tracebacks. A node writes straight to its file, so a slow or stopped terminal never blocks it.
`--verbose` (log_dir None) keeps today's behaviour: every node streams to the terminal.
"""
from __future__ import annotations

import re
import sys
import threading
from pathlib import Path

# rcutils' console format "[{severity}] [{time}] [{name}]: {message}"
ALERT = re.compile(r"^\[(WARN|ERROR|FATAL)\]")
TRACEBACK = "Traceback (most recent call last):"


class _Followed:
    def __init__(self, label: str, path: Path):
        self.label, self.path = label, path
        self.offset = path.stat().st_size if path.exists() else 0
        self.partial = ""
        self.in_traceback = False


def alert_lines(lines, state: _Followed | None = None) -> list[str]:
    """The lines of a node's output a person must see: WARN/ERROR/FATAL log lines and whole tracebacks."""
    state = state or _Followed("", Path("/nonexistent"))
    out = []
    for line in lines:
        if state.in_traceback:
            out.append(line)
            if line and not line[0].isspace():  # the exception line ends the traceback
                state.in_traceback = False
        elif line.startswith(TRACEBACK):
            state.in_traceback = True
            out.append(line)
        elif ALERT.match(line):
            out.append(line)
    return out


class NodeLogs:
    """Per-node log files under `log_dir`, and a follower that shows their alerts on `out`."""

    def __init__(self, log_dir, out=None, poll: float = 0.2):
        self.dir = Path(log_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.out = out or sys.stderr
        self.poll = poll
        self._files: dict[str, _Followed] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._follow, name="node_logs", daemon=True)
        self._thread.start()

    def path(self, label: str) -> Path:
        return self.dir / f"{re.sub(r'[^A-Za-z0-9_.-]+', '_', label).strip('_')}.log"

    def open(self, label: str):
        """A file for a node's stdout and stderr (Popen(stdout=f, stderr=subprocess.STDOUT)); the caller closes it."""
        p = self.path(label)
        f = open(p, "ab", buffering=0)
        with self._lock:
            self._files.setdefault(label, _Followed(label, p))
        return f

    def tail(self, label: str, n: int = 15) -> list[str]:
        """The last n lines of a node's log (for the message when it dies)."""
        try:
            return self.path(label).read_text(errors="replace").splitlines()[-n:]
        except OSError:
            return []

    def _drain(self) -> None:
        with self._lock:
            followed = list(self._files.values())
        for f in followed:
            try:
                with open(f.path, "rb") as fh:
                    fh.seek(f.offset)
                    data = fh.read()
            except OSError:
                continue
            if not data:
                continue
            f.offset += len(data)
            text = f.partial + data.decode("utf-8", "replace")
            *lines, f.partial = text.split("\n")
            for line in alert_lines(lines, f):
                self.out.write(f"[{f.label}] {line}\n")
            self.out.flush()

    def _follow(self) -> None:
        while not self._stop.wait(self.poll):
            self._drain()

    def close(self) -> None:
        """Stop following, after showing what the nodes wrote last."""
        self._stop.set()
        self._thread.join(timeout=5)
        self._drain()
