"""The suite under load (issue 19's "10 runs in a row beside stress-ng --cpu 2"): run the README's test command
N times with K busy-loop processes beside it and append each run to bench/results/suite_runs.json.

stress-ng is not on these machines (not on PyPI); `--cpu K` starts K Python processes that spin, which is what
`stress-ng --cpu K` does to the scheduler. Each record says the commit (and whether the tree was dirty), the
busy processes, the pytest summary line and its counts, the wall time and the load average at the end. The
streak (consecutive passing runs under load at the newest commit's code, counted back from the last run; a
passing quiet run there is skipped) is recomputed from the records, so runs made in different sessions add up
only while the code under test is the same.

    PYTHONPATH=$PWD python bench/reliability/suite_runs.py --runs 1 --cpu 2 [-- pytest args]
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import re
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402

OUT = REPO / "bench" / "results" / "suite_runs.json"
# what the suite exercises from the repository, for code_tree and the dirty check: the package, the tests, the
# scripts, and bench/'s Python (tests import bench modules; bench/results/ and docs may change within a streak)
BENCH = "bench"  # its *.py files, at any depth
CODE_PATHS = ("skillgen_ros", "test", "scripts", f":(glob){BENCH}/**/*.py")
COUNTS = re.compile(r"(\d+) (passed|failed|error|errors|skipped|xfailed|xpassed)")


def _spin() -> None:
    while True:
        pass


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=False).stdout.strip()


def code_tree() -> str:
    """The tree hashes of what the suite exercises (package, tests, scripts) and one hash over bench/'s Python
    files, so result/README-only commits keep a streak going."""
    import hashlib

    trees = [_git("rev-parse", f"HEAD:{p}") for p in CODE_PATHS if not p.startswith(":")]
    # ls-tree takes no glob pathspec: the same set as CODE_PATHS' BENCH glob, listed from HEAD
    bench_py = [ln for ln in _git("ls-tree", "-r", "HEAD", BENCH).splitlines() if ln.endswith(".py")]
    return ":".join(trees + [hashlib.sha1("\n".join(bench_py).encode()).hexdigest()])


def summary(log: str) -> tuple[str, dict[str, int]]:
    """pytest's last summary line ('== 758 passed, 2 skipped in 1075.3s ==') and its counts."""
    lines = [ln for ln in log.splitlines() if re.search(r"\d+ (passed|failed)", ln)]
    line = lines[-1].strip("= ") if lines else ""
    counts = {}
    for n, kind in COUNTS.findall(line):
        counts["errors" if kind == "error" else kind] = int(n)
    return line, counts


def loaded(r: dict) -> bool:
    """Whether the run had load beside it: busy loops, or other work named in `beside` (records before the
    `loaded` field named a quiet run's `beside` "nothing ...")."""
    if "loaded" in r:
        return bool(r["loaded"])
    return r.get("busy_processes", 0) > 0 or bool(r.get("beside")) and not r["beside"].startswith("nothing")


def streak(runs: list[dict]) -> int:
    """Passing runs under load in a row, counted back from the newest, on the newest run's code. A passing
    quiet run on that code neither counts nor breaks the streak (the goal is 10 under load); a failing one breaks it."""
    n = 0
    for r in reversed(runs):
        if r["code_tree"] != runs[-1]["code_tree"] or r["rc"] != 0 or r["dirty"]:
            break
        n += int(loaded(r))
    return n


def run_once(cpu: int, pytest_args: list[str], log_dir: Path, beside: str = "") -> dict:
    code = {"commit": _git("rev-parse", "HEAD"), "code_tree": code_tree(),  # before: commits may land meanwhile
            "dirty": bool(_git("status", "--porcelain", "--", *CODE_PATHS))}
    spinners = [mp.Process(target=_spin, daemon=True) for _ in range(cpu)]
    for p in spinners:
        p.start()
    t0 = time.time()
    try:
        proc = subprocess.run(["bash", str(REPO / "scripts" / "test.sh"), *pytest_args], cwd=REPO,
                              capture_output=True, text=True, check=False)
    finally:
        for p in spinners:
            p.terminate()
    wall = time.time() - t0
    log = proc.stdout + proc.stderr
    log_dir.mkdir(parents=True, exist_ok=True)
    path = log_dir / f"suite_{time.strftime('%Y%m%dT%H%M%S')}.log"
    path.write_text(log)
    line, counts = summary(proc.stdout)
    failed = [ln.split(" ", 1)[1].split(" - ")[0] for ln in proc.stdout.splitlines() if ln.startswith("FAILED ")]
    return {**code, "busy_processes": cpu, "beside": beside, "loaded": bool(cpu or beside), "pytest_args": pytest_args,
            "rc": proc.returncode,
            "summary": line, "counts": counts, "failed": failed, "wall_s": round(wall, 1), "log": str(path),
            "machine": machine_info(), "finished": time.strftime("%Y-%m-%dT%H:%M:%S")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--cpu", type=int, default=2, help="busy-loop processes beside the suite (stress-ng --cpu K)")
    ap.add_argument("--beside", default="", help="other load already running (e.g. a benchmark's 2 workers), "
                    "recorded with the run; use --cpu 0 then")
    ap.add_argument("--logs", default="/tmp/suite_runs", help="where each run's full output goes")
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("pytest_args", nargs="*")
    a = ap.parse_args()
    out = Path(a.out)
    doc = json.loads(out.read_text()) if out.exists() else {
        "benchmark": "suite_runs", "goal": "10 passing runs in a row beside stress-ng --cpu 2 (issue 19)",
        "command": "PYTHONPATH=$PWD python bench/reliability/suite_runs.py --runs 1 --cpu 2", "runs": []}
    rc = 0
    for i in range(a.runs):
        r = run_once(a.cpu, a.pytest_args, Path(a.logs), a.beside)
        doc["runs"].append(r)
        doc["streak"] = streak(doc["runs"])
        out.write_text(json.dumps(doc, indent=1) + "\n")
        print(f"[suite_runs] run {i + 1}/{a.runs}: rc {r['rc']}, {r['summary']}, {r['wall_s']} s, "
              f"streak {doc['streak']}", flush=True)
        rc = rc or r["rc"]
    return rc


if __name__ == "__main__":
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    sys.exit(main())
