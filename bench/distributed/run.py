"""Distributed generation benchmark (issue 21; not in the test suite).

Scaling: the same request (task, variant, seed, attempts) on 1 and on 2 Ray workers, in-process and
in graph mode (each worker its own node graph in its own ROS_DOMAIN_ID, perception estimating
poses). Reported per cell: attempts/hour and demos/hour over the wall time of the run (workers up,
and warmed by one attempt each: warmup_s), demos/hour per worker and per core the machine was
really busy (/proc/stat over the run, so a graph worker's several processes count), efficiency at
N workers = rate(N) / (N * rate(1)), and Ray's overhead per attempt (driver round trip of a range
minus the worker's own time for it, per attempt, as a share of an attempt's time). On a 2-core
machine only 1 vs 2 workers can be measured.

Cluster check (--cluster N): a simulated N-node cluster on this machine (ray.cluster_utils.Cluster,
one CPU per node), one node killed after a third of the attempts; the run must still hold each
index exactly once, with the dataset identical to a serial run of the same request.

Cancel (--cancel): a 2-worker run stopped once a sixth of its attempts are done, timed from the
stop to the last worker's range coming back (workers_stopped: the issue's goal, within one
attempt's time) and to run_distributed's return (stop_latency: that plus the merge of the kept
ranges), both also in attempts. Since a stop abandons the attempt in flight (AttemptAborted), the
workers' part is a step's time plus Ray's round trip, not the rest of an attempt.

Each finished cell is written to bench/results/distributed.json at once with the command that
reruns it; a rerun skips cells already there (--force reruns).

    python bench/distributed/run.py --attempts 16 --modes in_process graph --workers 1 2
    python bench/distributed/run.py --cluster 3 --attempts 300
    python bench/distributed/run.py --cancel --attempts 48
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")  # loopback only (ray_pool.connect)

from bench.machine import machine_info  # noqa: E402
from skillgen_ros.core.distributed.run import run_distributed  # noqa: E402
from skillgen_ros.core.distributed.shards import pack_dir  # noqa: E402
from skillgen_ros.core.distributed.worker import WorkerSpec  # noqa: E402
from skillgen_ros.core.generation.session import RunRequest  # noqa: E402

OUT = ROOT / "bench" / "results" / "distributed.json"


def _request(a, out: str) -> RunRequest:
    return RunRequest(task=a.task, variant=a.variant, seed=a.seed, attempts=a.attempts, video_attempts=0,
                      output_dir=out, source_demos=str(ROOT / "bags" / a.task))


def _cpu_jiffies() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine (/proc/stat): the cores a run really kept busy."""
    f = [int(x) for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    idle = f[3] + f[4]  # idle + iowait
    return sum(f) - idle, sum(f)


def _pool(a, mode: str, workers: int, prefix: str):
    """(temp dir, the request writing under it, a pool of `workers` in `mode`) for one cell."""
    from skillgen_ros.core.distributed.ray_pool import RayPool

    tmp = tempfile.mkdtemp(prefix=prefix)
    req = _request(a, os.path.join(tmp, "run"))
    spec = WorkerSpec(mode=mode, perception=a.perception, domain_ids=tuple(range(*a.domains)),
                      startup_timeout=300.0)
    return tmp, req, RayPool(workers, spec, req, pack_dir(req.source_demos))


def scaling_cell(a, mode: str, workers: int) -> dict:
    # 1/5/15-min load before the cell: the previous cell's own load decays in it; more than that is other load
    load_before = [round(x, 2) for x in os.getloadavg()]
    t_up = time.perf_counter()
    tmp, req, pool = _pool(a, mode, workers, "bench_distributed_")
    up = time.perf_counter() - t_up
    try:
        # One warm-up attempt per worker, as benchmarks warm up: a worker's first range pays for
        # building the task's scene, parsing the demos and compiling kernels (about 5 s in a graph),
        # which a run pays once; reported as warmup_s, outside the timed run.
        t_w = time.perf_counter()
        run_distributed(pool, dataclasses.replace(req, attempts=workers, output_dir=os.path.join(tmp, "warm")),
                        write_report=False)
        warm = time.perf_counter() - t_w
        b0, t0 = _cpu_jiffies()
        run = run_distributed(pool, req, write_report=False)
        b1, t1 = _cpu_jiffies()
    finally:
        pool.close()
        shutil.rmtree(tmp, ignore_errors=True)
    busy_cores = os.cpu_count() * (b1 - b0) / max(t1 - t0, 1)  # everything on the machine, Ray's own processes too
    per_attempt = run.attempt_seconds / max(run.attempts, 1)
    overhead = sum(run.overhead_seconds) / max(run.attempts, 1)
    return {"mode": mode, "workers": workers, "attempts": run.attempts, "successes": run.successes,
            "wall_s": round(run.wall_seconds, 2), "startup_s": round(up, 2), "warmup_s": round(warm, 2),
            "attempts_per_hour": round(3600 * run.attempts / run.wall_seconds, 1),
            "demos_per_hour": round(3600 * run.successes / run.wall_seconds, 1),
            "demos_per_hour_per_core": round(3600 * run.successes / run.wall_seconds / min(workers, os.cpu_count()), 1),
            "busy_cores": round(busy_cores, 2),
            "demos_per_hour_per_busy_core": round(3600 * run.successes / run.wall_seconds / max(busy_cores, 1e-3), 1),
            "attempt_s_mean": round(per_attempt, 3), "ray_overhead_s_per_attempt": round(overhead, 4),
            "ray_overhead_share": round(overhead / per_attempt, 4) if per_attempt else None,
            "worker_attempts": run.worker_attempts, "load_avg_before": load_before}


def cancel_cell(a, mode: str, workers: int = 2) -> dict:
    """The issue's "cancel stops all workers within one attempt's time": stop a run once a sixth of
    its attempts are done and time it from the stop to the last worker's range coming back."""
    tmp, req, pool = _pool(a, mode, workers, "bench_cancel_")
    stop = {}
    pool = _TimedPool(pool)

    def progress(p, _st):
        if not stop and p.attempts >= max(a.attempts // 6, workers):
            stop.update(t=time.perf_counter(), attempts=p.attempts)

    try:
        run = run_distributed(pool, req, on_progress=progress, status_every_s=0.0, write_report=False,
                              should_stop=lambda: "CANCELED" if stop else "")
        t_end = time.perf_counter()
    finally:
        pool.close()
        shutil.rmtree(tmp, ignore_errors=True)
    mean = run.attempt_seconds / max(run.attempts, 1)
    # the median attempt: a worker's first attempts include one-time warm-up (numba compiling the
    # perception kernels on a fresh machine took ~160 s), which a mean would count as "an attempt"
    per_attempt = float(np.median([r.timings.get("total", 0.0) for r in run.results])) if run.results else mean
    latency = t_end - stop["t"]  # until run_distributed returned: the workers' stop + the merge
    stopped = max(pool.last_payload - stop["t"], 0.0)  # until the last worker's range came back
    return {"mode": mode, "workers": workers, "stopped_early": run.stopped_early, "attempts": run.attempts,
            "attempts_at_stop": stop["attempts"], "attempts_after_stop": run.attempts - stop["attempts"],
            "stop_latency_s": round(latency, 3), "attempt_s_mean": round(mean, 3),
            "attempt_s_median": round(per_attempt, 3),
            "stop_latency_in_attempts": round(latency / per_attempt, 3) if per_attempt else None,
            "workers_stopped_s": round(stopped, 3),
            "workers_stopped_in_attempts": round(stopped / per_attempt, 3) if per_attempt else None}


class _TimedPool:
    """The pool, noting when the last range came back (the workers' side of a stop, before the merge)."""

    def __init__(self, pool):
        self._pool, self.last_payload = pool, 0.0

    def __getattr__(self, name):
        return getattr(self._pool, name)

    def poll(self, timeout):
        got = self._pool.poll(timeout)
        if got:
            self.last_payload = time.perf_counter()
        return got


def cluster_cell(a) -> dict:
    """N simulated nodes, one killed mid-run: exactly-once and identical to serial."""
    import ray
    from ray.cluster_utils import Cluster

    from skillgen_ros.core.distributed.ray_pool import RayPool

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    nodes = [cluster.add_node(num_cpus=1) for _ in range(a.cluster - 1)]
    ray.init(address=cluster.address, include_dashboard=False, log_to_driver=False)
    tmp = tempfile.mkdtemp(prefix="bench_cluster_")
    req = _request(a, os.path.join(tmp, "run"))
    pool = RayPool(a.cluster, WorkerSpec(mode="in_process", perception=a.perception), req,
                   pack_dir(req.source_demos))
    killed = []

    def kill_a_node(p, _st):
        if not killed and p.attempts >= a.attempts // 3:
            cluster.remove_node(nodes[-1], allow_graceful=False)
            killed.append(p.attempts)

    try:
        run = run_distributed(pool, req, on_progress=kill_a_node, write_report=False)
    finally:
        pool.close()
        ray.shutdown()
        cluster.shutdown()
    same = _same_as_serial(a, req, tmp) if a.compare_serial else None
    shutil.rmtree(tmp, ignore_errors=True)
    return {"nodes": a.cluster, "attempts": run.attempts, "indices_once": sorted(r.index for r in run.results)
            == list(range(a.attempts)), "node_killed_at_attempt": killed[0] if killed else None,
            "lost_ranges": run.lost_ranges, "identical_to_serial": same, "wall_s": round(run.wall_seconds, 1)}


def _same_as_serial(a, req, tmp) -> bool:
    import dataclasses

    import h5py
    import numpy as np

    from skillgen_ros.core.generation.session import run_generation
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    task = get_task(a.task)
    env = SimGenerationEnv(SimEnvConfig(perception=a.perception, seed=a.seed, video=False))
    ser = dataclasses.replace(req, output_dir=os.path.join(tmp, "serial"))
    run_generation(env, load_source_demos(expand_bag_paths([req.source_demos]), task), task, ser, write_report=False)
    env.close()
    for name in ("demo.hdf5", "failed.hdf5"):
        with h5py.File(os.path.join(req.output_dir, name)) as x, h5py.File(os.path.join(ser.output_dir, name)) as y:
            ax, ay = {}, {}
            x.visititems(lambda k, v: ax.__setitem__(k, v[()]) if isinstance(v, h5py.Dataset) else None)
            y.visititems(lambda k, v: ay.__setitem__(k, v[()]) if isinstance(v, h5py.Dataset) else None)
            if sorted(ax) != sorted(ay) or not all(np.array_equal(ax[k], ay[k]) for k in ax):
                return False
    return True


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="Square")
    ap.add_argument("--variant", default="D0")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--attempts", type=int, default=16)
    ap.add_argument("--modes", nargs="+", default=["in_process", "graph"])
    ap.add_argument("--workers", nargs="+", type=int, default=[1, 2])
    ap.add_argument("--perception", default="estimate", choices=["estimate", "ground_truth"])
    ap.add_argument("--domains", nargs=2, type=int, default=[80, 100],
                    help="graph workers' ROS domain ids [lo, hi): inside testing.domains.VALID_IDS (Fast DDS ports below the ephemeral range)")
    ap.add_argument("--cluster", type=int, default=0, help="run the N-node cluster check instead")
    ap.add_argument("--cancel", action="store_true", help="time a stop of a 2-worker run in each --modes instead")
    ap.add_argument("--compare-serial", action="store_true", help="cluster check: also run serially and compare")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args(argv)
    rerun = " ".join(["python", "bench/distributed/run.py", *(sys.argv[1:] if argv is None else argv)])
    out = json.loads(Path(a.out).read_text()) if Path(a.out).exists() else {"benchmark": "distributed", "cells": {}}
    out["machine"] = machine_info()

    def save(key, cell):
        cell.update(rerun=rerun, measured=time.strftime("%Y-%m-%d"), task=a.task, variant=a.variant, seed=a.seed,
                    perception=a.perception)
        out["cells"][key] = cell
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(out, indent=1, sort_keys=True))
        print(key, json.dumps(cell), flush=True)

    if a.cluster:
        key = f"cluster{a.cluster}/{a.task}/{a.variant}/n{a.attempts}"
        if a.force or key not in out["cells"]:
            save(key, cluster_cell(a))
        return 0
    if a.cancel:
        for mode in a.modes:
            key = f"cancel/{mode}/w2/{a.task}/{a.variant}/{a.perception}/n{a.attempts}/seed{a.seed}"
            if a.force or key not in out["cells"]:
                save(key, cancel_cell(a, mode))
        out["summary"] = summarize(out["cells"])
        Path(a.out).write_text(json.dumps(out, indent=1, sort_keys=True))
        return 0

    def key(mode, w):
        return f"{mode}/w{w}/{a.task}/{a.variant}/{a.perception}/n{a.attempts}/seed{a.seed}"

    for mode in a.modes:
        for w in a.workers:
            if a.force or key(mode, w) not in out["cells"]:
                save(key(mode, w), scaling_cell(a, mode, w))
    for mode in a.modes:  # efficiency at each N against the same mode's 1 worker, same seed
        base = out["cells"].get(key(mode, 1))
        for w in a.workers:
            c = out["cells"].get(key(mode, w))
            if base and c and w > 1:
                c["efficiency"] = round(c["attempts_per_hour"] / (w * base["attempts_per_hour"]), 3)
    out["summary"] = summarize(out["cells"])
    Path(a.out).write_text(json.dumps(out, indent=1, sort_keys=True))
    return 0


def summarize(cells: dict) -> dict:
    """Per (mode, workers, task, variant, perception, attempts): mean and range over the seeds run."""
    import statistics

    groups: dict[str, list] = {}
    for k, c in cells.items():
        if "/seed" in k and "mode" in c:
            groups.setdefault(k.rsplit("/seed", 1)[0], []).append(c)
    out = {}
    for g, cs in sorted(groups.items()):
        row = {"seeds": sorted(c["seed"] for c in cs)}
        for f in ("efficiency", "attempts_per_hour", "demos_per_hour_per_busy_core", "ray_overhead_share",
                  "busy_cores", "attempt_s_mean", "stop_latency_s", "stop_latency_in_attempts"):
            v = [c[f] for c in cs if c.get(f) is not None]
            if v:
                row[f] = {"mean": round(statistics.fmean(v), 4), "min": min(v), "max": max(v)}
        out[g] = row
    return out


if __name__ == "__main__":
    sys.exit(main())
