"""Soak (issue 19; a benchmark, not a test): N attempts through the datagen graph with the recorder
on. Reports every node process's RSS and open file descriptors after warm-up (the first finished
attempt) and at the end (goal: RSS growth <= 10%; see growth_figures), and the run's success rate with its 95% Wilson
interval (to compare with the in-process run of the same seed: bench/datagen).

    PYTHONPATH=$PWD python bench/soak/run.py --attempts 1000 [--task Square --variant D0 --seed 0]
    PYTHONPATH=$PWD python bench/soak/run.py --attempts 5 --out bench/results/soak_smoke.json   # smoke

Writes bench/results/soak.json (or --out), with the command and machine info; the run's own
dataset, report and bag stay under a fresh output directory (--output).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402
from skillgen_ros import rosenv  # noqa: E402,F401  (loopback discovery before rclpy)


def _nodes(launcher_pid: int) -> dict:
    """{node label: (rss MiB, open fds)} of the launcher's children (one process per node/container)."""
    import psutil

    out = {}
    for k in psutil.Process(launcher_pid).children():
        try:
            cmd = k.cmdline()
            exe = next((Path(c).name for c in cmd if "skillgen_ros" in c or "/bin/" in c and "python" not in c),
                       Path(cmd[0]).name if cmd else str(k.pid))
            out[f"{exe}[{k.pid}]"] = (round(k.memory_info().rss / 2**20, 1), k.num_fds())
        except psutil.Error:
            pass
    return out


def _wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    if n == 0:
        return 0.0, 0.0
    p, d = k / n, 1 + z * z / n
    c, h = (p + z * z / (2 * n)) / d, z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return round(c - h, 4), round(c + h, 4)


def _growth(a: dict, b: dict) -> dict:
    return {k: round(100.0 * (b[k] - a[k]) / a[k], 1) for k in a if k in b and a[k] and k != "attempts"}


def growth_figures(warm: dict, series: list[dict], end: dict) -> dict:
    """RSS growth per node: over the attempts (after the first attempt -> the last sample taken
    during the run), over the run's last 90% (first sample -> last), and to after the run (the
    end adds the report's one-off cost: matplotlib and its fonts, ~30 MiB in datagen)."""
    last = series[-1] if series else end
    out = {"rss_growth_percent": _growth(warm, last), "rss_growth_sampled_at_attempt": last.get("attempts"),
           "rss_growth_percent_after_first_tenth": _growth(series[0], last) if series else {},
           "rss_growth_percent_after_report": _growth(warm, end)}
    out["max_rss_growth_percent"] = max(out["rss_growth_percent"].values(), default=0.0)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--attempts", type=int, default=1000)
    ap.add_argument("--task", default="Square")
    ap.add_argument("--variant", default="D0")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", default="", help="run directory (default out/soak_<time>)")
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "soak.json"))
    ap.add_argument("--startup-timeout", type=float, default=300.0)
    a = ap.parse_args()
    from skillgen_ros.cli.launcher import graph_client
    from skillgen_ros.client import SkillGenClient

    if "ROS_DOMAIN_ID" not in os.environ:  # a domain of our own (lock-file lease), not the default 0
        from skillgen_ros.testing.domains import acquire_domain

        lease = acquire_domain()
        os.environ["ROS_DOMAIN_ID"] = str(lease.id)
    run_dir = os.path.abspath(a.output or os.path.join("out", f"soak_{time.strftime('%Y%m%d-%H%M%S')}"))
    roots = ["--ros-args", "-p", f"writable_roots:=['{run_dir}']"]
    t0 = time.monotonic()
    with graph_client("datagen", SkillGenClient, "datagen 'generate'", a.startup_timeout, ros_args=roots) as (g, c):
        assert c.generate(task=a.task, variant=a.variant, method="skillgen", attempts=a.attempts, seed=a.seed,
                          output_dir=run_dir, record_bag=True, video_attempts=0, timeout=120)
        while not c.is_done() and (c.feedback() is None or c.feedback().attempts < 1):
            time.sleep(1.0)  # polling a long run's progress, not synchronisation
        warm = _nodes(g.pid)
        series, step = [], max(1, a.attempts // 10)
        while not c.is_done():
            fb = c.feedback()
            if fb is not None and fb.attempts >= step * (len(series) + 1):  # RSS every tenth of the run
                series.append({"attempts": int(fb.attempts), **{k: v[0] for k, v in _nodes(g.pid).items()}})
            time.sleep(2.0)
        end = _nodes(g.pid)
        res = c.result(timeout=60)
    doc = {"command": "PYTHONPATH=$PWD python bench/soak/run.py " + " ".join(sys.argv[1:]),
           "command_issue_size": "PYTHONPATH=$PWD python bench/soak/run.py --attempts 1000 --out bench/results/soak_1000.json",
           "machine": machine_info(), "task": a.task, "variant": a.variant, "seed": a.seed,
           "attempts": int(res.attempts), "successes": int(res.successes), "reason": res.reason,
           "success_rate": round(res.successes / max(1, res.attempts), 4),
           "wilson95": _wilson(int(res.successes), int(res.attempts)),
           "rss_mib_after_warmup": {k: v[0] for k, v in warm.items()}, "rss_mib_end": {k: v[0] for k, v in end.items()},
           "rss_mib_series": series, **growth_figures({k: v[0] for k, v in warm.items()}, series,
                                                      {k: v[0] for k, v in end.items()}),
           "fds_after_warmup": {k: v[1] for k, v in warm.items()}, "fds_end": {k: v[1] for k, v in end.items()},
           "bag": res.bag_path, "dataset": res.dataset_path, "wall_seconds": round(time.monotonic() - t0, 1)}
    Path(a.out).write_text(json.dumps(doc, indent=2) + "\n")
    print(json.dumps({k: v for k, v in doc.items() if k != "machine"}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
