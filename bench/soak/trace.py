"""Where does a node's memory grow? (issue 19's soak: measure, don't guess.)

Starts the datagen graph (graphs.yaml, without the recorder) with the chosen processes under
tracemalloc (bench/soak/traced_node.py), runs one `generate` goal, snapshots the traced processes
after `--warm` attempts and again `--tail` attempts before the end (the run's objects still alive),
and prints the allocation sites whose live size grew most, with each process's RSS at both points.

    PYTHONPATH=$PWD python bench/soak/trace.py --attempts 60 --warm 10 [--traced container datagen]
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from skillgen_ros import rosenv  # noqa: E402


def _rss(pid: int) -> float:
    import psutil

    return round(psutil.Process(pid).memory_info().rss / 2**20, 1)


def _snap(out: Path, exes: list[str], n: int, timeout: float = 300.0) -> None:
    for e in exes:
        (out / f"{e}.take{n}").write_text("1")
    end = time.monotonic() + timeout
    while not all((out / f"{e}_{n}.done").exists() for e in exes) and time.monotonic() < end:
        time.sleep(0.5)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--attempts", type=int, default=60)
    ap.add_argument("--warm", type=int, default=10)
    ap.add_argument("--tail", type=int, default=2)
    ap.add_argument("--traced", nargs="+", default=["container", "datagen"])
    ap.add_argument("--top", type=int, default=12)
    ap.add_argument("--frames", type=int, default=6)
    a = ap.parse_args()
    from skillgen_ros.client import SkillGenClient
    from skillgen_ros.cli.launcher import resolve_executable
    from skillgen_ros.graphs import load_graph, processes
    from skillgen_ros.testing.domains import acquire_domain

    lease = acquire_domain()
    out = Path(tempfile.mkdtemp(prefix="skillgen_trace_"))
    env = rosenv.node_environment(dict(os.environ))
    env.update(ROS_DOMAIN_ID=str(lease.id), SKILLGEN_TRACE_DIR=str(out), SKILLGEN_TRACE_FRAMES=str(a.frames),
               PYTHONUNBUFFERED="1")
    procs = {}
    for p in processes([n for n in load_graph("datagen") if n.exe != "recorder"]):
        cmd = ([sys.executable, str(REPO / "bench" / "soak" / "traced_node.py"), p.exe] if p.exe in a.traced
               else [str(resolve_executable(p.exe))]) + list(p.args)
        procs[p.exe] = subprocess.Popen(cmd, env=env, stdout=open(out / f"{p.exe}.log", "wb"), stderr=subprocess.STDOUT)
    os.environ["ROS_DOMAIN_ID"] = str(lease.id)
    client = SkillGenClient(domain_id=lease.id)
    try:
        assert client.wait_for_server(600), "datagen did not come up"
        assert client.generate(task="Square", variant="D0", method="skillgen", attempts=a.attempts, seed=0,
                               output_dir=str(out / "run"), video_attempts=0, timeout=120)

        def at(n):
            while not client.is_done() and (client.feedback() is None or client.feedback().attempts < n):
                time.sleep(1.0)  # polling a long run's progress
        at(a.warm)
        rss0 = {e: _rss(procs[e].pid) for e in procs}
        _snap(out, a.traced, 1)
        at(a.attempts - a.tail)
        rss1 = {e: _rss(procs[e].pid) for e in procs}
        _snap(out, a.traced, 2)
        n0, n1 = a.warm, client.feedback().attempts
        client.result(timeout=900)
    finally:
        client.close()
        for p in procs.values():
            p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
        lease.release()
    print(f"RSS MiB at attempt {n0} -> {n1}: " + ", ".join(f"{e} {rss0[e]} -> {rss1[e]}" for e in procs))
    for e in a.traced:
        s0, s1 = (tracemalloc.Snapshot.load(str(out / f"{e}_{k}.snap")) for k in (1, 2))
        total = sum(s.size for s in s1.statistics("filename")) - sum(s.size for s in s0.statistics("filename"))
        print(f"\n== {e}: traced Python heap {total / 2**20:+.2f} MiB over {n1 - n0} attempts")
        for st in s1.compare_to(s0, "traceback")[:a.top]:
            print(f"{st.size_diff / 2**10:+9.1f} KiB {st.count_diff:+7d} blocks")
            for line in st.traceback.format()[-2 * a.frames:]:
                print("      " + line)
    print(f"\nsnapshots and logs: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
