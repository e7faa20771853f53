"""Run one node executable under tracemalloc (a diagnostic for bench/soak/trace.py, not a node).

    python bench/soak/traced_node.py <exe> [node args...]

With SKILLGEN_TRACE_DIR set, a file `<dir>/<exe>.take<N>` appearing makes a background thread
dump a snapshot to `<dir>/<exe>_<N>.snap` (a file trigger: an executor blocked in the wait set
would not run a Python signal handler in time).
"""
from __future__ import annotations

import os
import sys
import threading
import time
import tracemalloc
from pathlib import Path


def _watch(exe: str, out: Path) -> None:
    n = 1
    while True:
        if (out / f"{exe}.take{n}").exists():
            tracemalloc.take_snapshot().dump(str(out / f"{exe}_{n}.snap"))
            (out / f"{exe}_{n}.done").write_text("1")
            n += 1
        time.sleep(0.2)  # polling a trigger file, not synchronisation


def main() -> int:
    exe = sys.argv[1]
    out = Path(os.environ["SKILLGEN_TRACE_DIR"])
    tracemalloc.start(int(os.environ.get("SKILLGEN_TRACE_FRAMES", "6")))
    threading.Thread(target=_watch, args=(exe, out), daemon=True).start()
    sys.argv = sys.argv[1:]
    from skillgen_ros.nodes.entry import _run

    return _run(exe)


if __name__ == "__main__":
    sys.exit(main())
