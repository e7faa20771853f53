"""bench/hsp/shards: a dataset's generation shards, one at a time or several side by side (--gen-workers).

An attempt depends only on (run seed, attempt index), so a dataset of N demos is "the first N
successes in attempt order" however the attempts are split. One worker generates shard after shard,
each stopping at `--shard` successes (the resume granularity). With W > 1 workers each new shard is
a fixed range of attempts (about `--shard` successes at the rate so far), W of them at once in a
process pool, recorded in index order as they finish; the merge then keeps the first N successes,
so the dataset is the one a single worker would have written. A shard recorded by an earlier
session whose out/ is gone is regenerated (W at a time) and must reproduce its recorded counts.

Why not Ray (issue 21's distributed runner): these are a handful of long, independent shards in one
process tree, with nothing to schedule across machines; a ProcessPoolExecutor is enough.
"""
from __future__ import annotations

import math
import multiprocessing
import shutil
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PRIOR_RATE = 0.3  # the first parallel batch's guess at the success rate (then: the rate so far)


@dataclass(frozen=True)
class ShardJob:
    """One shard: attempts [first, first + attempts) of (task, variant, method) with the run's seed."""

    task: str
    variant: str
    method: str
    augment: bool
    seed: int
    first: int
    attempts: int
    want: int  # stop at this many successes (0: run every attempt: a fixed shard)
    out: str


def generate_shard(job: ShardJob, env=None, demos=None) -> dict:
    """Run one shard into job.out (started over if a previous try left files); its record."""
    from skillgen_ros.core.generation.session import RunRequest, run_generation
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    spec = get_task(job.task)
    if demos is None:
        demos = load_source_demos(expand_bag_paths([str(ROOT / "bags" / job.task)]), spec)
    own = env is None
    env = env or SimGenerationEnv(SimEnvConfig(perception="ground_truth", video=False, seed=job.seed))
    shutil.rmtree(job.out, ignore_errors=True)
    t = time.time()
    try:
        r = run_generation(env, demos, spec, RunRequest(task=job.task, variant=job.variant, method=job.method,
                                                        augment=job.augment, attempts=job.attempts,
                                                        target_successes=job.want, seed=job.seed,
                                                        first_index=job.first, output_dir=job.out, video_attempts=0),
                           write_report=False, keep_timings=False)
    finally:
        if own:
            env.close()
    rec = {"dir": job.out, "first_index": job.first, "attempts": r.attempts, "successes": r.successes,
           "seconds": time.time() - t}
    return {**rec, "fixed": True} if not job.want else rec


def _take_count(sh: dict, successes: int, why: str) -> None:
    """The record takes a shard's actual success count, keeping the recorded one under `regenerated_from`."""
    print(f"  {sh['dir']}: {why}, recorded {sh['successes']}; the record takes {successes}", flush=True)
    sh["regenerated_from"] = {"successes": sh["successes"], "seconds": sh.get("seconds")}
    sh["successes"] = successes


def reconcile(shards: list[dict]) -> bool:
    """A recorded shard whose file holds another number of demos than its record (a regeneration that was
    written but not recorded: an earlier version stopped there) takes the file's count, as _regenerate does.
    True when a record changed."""
    changed = False
    for sh in shards:
        f = Path(sh["dir"]) / "demo.hdf5"
        if sh["successes"] and f.exists() and (n := len(demo_indices([f]))) != sh["successes"]:
            _take_count(sh, n, f"its file holds {n} demos")
            changed = True
    return changed


def _regenerate(shards: list[dict], job_of, run) -> bool:
    """Shards recorded by a session whose out/ is gone: redo their attempt ranges (attempts depend only on
    (seed, index)). Another CPU's numerics can change a contact-rich attempt's outcome (Threading D1's BC
    shard_000: 83/500 recorded on an AMD EPYC, 70/500 regenerated on an Intel Xeon), so a different count
    replaces the record's successes, the old count kept under `regenerated_from`; the shard keeps its range
    (`attempts`), so later shards' ranges stay disjoint. True when a record changed (the caller saves it)."""
    missing = [sh for sh in shards if sh["successes"] and not (Path(sh["dir"]) / "demo.hdf5").exists()]
    for sh in missing:
        print(f"  {sh['dir']} is missing; regenerating its {sh['attempts']} attempts", flush=True)
    jobs = [job_of(sh["first_index"], sh["attempts"], 0 if sh.get("fixed") else sh["successes"], sh["dir"])
            for sh in missing]
    changed = False
    for sh, r in zip(missing, run(jobs)):
        if r["successes"] != sh["successes"]:
            _take_count(sh, r["successes"], f"regenerated {r['successes']}/{r['attempts']}")
            sh["seconds"], changed = r["seconds"], True
    return changed


def next_batch(shards: list[dict], demos: int, shard: int, workers: int, cap_factor: int) -> list[tuple[int, int, int]]:
    """(first attempt, attempts, want) of the next shards: one shard stopping at `shard` successes,
    or `workers` fixed ranges sized to give about `shard` successes each at the rate so far (the last
    batch: together about the successes still needed, so no worker idles through the tail)."""
    done = sum(s["successes"] for s in shards)
    first = sum(s["attempts"] for s in shards)
    need = demos - done
    if need <= 0:
        return []
    want = min(shard, need)
    if workers <= 1:
        return [(first, want * cap_factor, want)]
    rate = done / first if done else PRIOR_RATE  # first = the attempts so far
    size = max(1, math.ceil(want / max(rate, 1e-3)))
    count = min(workers, math.ceil(need / max(1, size * rate)))
    if count < workers:  # the tail (fewer than a shard per worker to go): its attempts split over every worker
        size, count = max(1, math.ceil(need / max(rate, 1e-3) / workers)), workers
    return [(first + k * size, size, 0) for k in range(count)]


def demo_indices(paths) -> list[int]:
    """Attempt indices of the demos in these shard files."""
    import h5py

    out = []
    for p in paths:
        with h5py.File(p, "r", locking=False) as f:
            out += [int(f["data"][n].attrs.get("index", -1)) for n in f["data"]]
    return sorted(out)


def generate(shards: list[dict], root: Path, job_of, demos: int, shard: int, workers: int, cap_factor: int,
             save) -> list[str]:
    """Fill `shards` (the dataset's record, saved by `save()` after each shard) until it holds `demos`
    successes; returns the shard files to merge. job_of(first, attempts, want, out) -> ShardJob."""
    pool = (ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
            if workers > 1 else None)
    local = {}

    def run(jobs):
        """The jobs' records as each finishes, in job order (a later shard waits for an earlier one)."""
        if pool is not None:
            yield from pool.map(generate_shard, jobs)
            return
        if "env" not in local and jobs:  # one env for every shard of this dataset
            from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
            local["env"] = SimGenerationEnv(SimEnvConfig(perception="ground_truth", video=False, seed=jobs[0].seed))
        for j in jobs:
            yield generate_shard(j, env=local["env"])

    try:
        if reconcile(shards) | _regenerate(shards, job_of, run):
            save()
        barren = 0  # attempts since the last success: a tail batch of a few attempts may well have none
        while batch := next_batch(shards, demos, shard, workers, cap_factor):
            jobs = [job_of(first, n, want, str(root / f"shard_{len(shards) + k:03d}"))
                    for k, (first, n, want) in enumerate(batch)]
            for rec in run(jobs):
                shards.append(rec)
                save()
            got = sum(s["successes"] for s in shards[-len(jobs):])
            barren = 0 if got else barren + sum(s["attempts"] for s in shards[-len(jobs):])
            if barren >= shard * cap_factor:
                raise SystemExit(f"{jobs[0].task} {jobs[0].method}: no successes in the last {barren} "
                                 "attempts; giving up")
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
        if "env" in local:
            local["env"].close()
    return [str(Path(s["dir"]) / "demo.hdf5") for s in shards if s["successes"]]


def first_n_keep(paths, n: int):
    """keep(index) for merge_datasets: the first n successes in attempt order (a parallel batch overshoots)."""
    idx = demo_indices(paths)
    cutoff = idx[n - 1] if len(idx) >= n else math.inf
    return lambda i: i <= cutoff

