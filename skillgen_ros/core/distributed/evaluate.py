"""Policy evaluation rollouts on the Ray pool: N rollouts of one checkpoint spread over workers.

Rollout i resets with rollout_seed(seed, i) only (core/deploy/seeds.py), so rollouts split into
index ranges like generation attempts. Each range is one Ray task running core/deploy/evaluate.evaluate
over its own in-process env, with the checkpoint and the source demos sent as bytes (no shared
filesystem). A task whose worker dies is retried by Ray (max_retries); each range's result is
taken once, so every rollout index is counted exactly once, and the summary equals a serial one.
"""
from __future__ import annotations

import math
import os
import tempfile
from typing import Callable

from ..deploy.evaluate import EvalSummary, summarize
from .shards import pack_dir, unpack_dir


def _rollout_range(ckpt: bytes, demos_tar: bytes, first: int, n: int, kw: dict) -> EvalSummary:
    """One range of rollouts in a worker (its summary carries the RolloutResults)."""
    from ..deploy.evaluate import evaluate

    with tempfile.TemporaryDirectory(prefix="skillgen_eval_") as tmp:
        path = os.path.join(tmp, "policy.pt")
        with open(path, "wb") as f:
            f.write(ckpt)
        demos_dir = os.path.dirname(unpack_dir(demos_tar, tmp)[0]) if demos_tar else kw.pop("demos_dir", "bags")
        if demos_tar:  # evaluate reads <demos_dir>/<task>/: the packed dir is the task's
            os.rename(os.path.join(tmp, "demos"), os.path.join(tmp, kw["task"]))
        return evaluate(path, first_index=first, rollouts=n, demos_dir=demos_dir, **kw)


def evaluate_distributed(checkpoint_path: str, task: str, variant: str | None = None, mode: str | None = None,
                         rollouts: int = 50, seed: int = 0, workers: int = 2, address: str = "",
                         demos_dir: str = "bags", first_index: int = 0, perception: str = "ground_truth", config=None,
                         on_range: Callable[[int, EvalSummary], None] | None = None, max_chunk: int = 8) -> EvalSummary:
    """`rollouts` rollouts on `workers` Ray workers (a local instance, or the cluster at `address`)."""
    from .ray_pool import WORKER_RUNTIME_ENV, connect

    started = connect(address, workers)
    import ray

    try:
        with open(checkpoint_path, "rb") as f:
            ckpt = ray.put(f.read())
        task_dir = os.path.join(demos_dir, task)
        demos = ray.put(pack_dir(task_dir) if os.path.isdir(task_dir) else b"")
        kw = {"task": task, "variant": variant, "mode": mode, "seed": seed, "perception": perception,
              **({"config": config} if config is not None else {})}
        remote = ray.remote(num_cpus=1, max_retries=3, runtime_env=WORKER_RUNTIME_ENV)(_rollout_range)
        size = max(1, min(max_chunk, math.ceil(rollouts / (2 * workers))))
        refs = {remote.remote(ckpt, demos, i, min(size, first_index + rollouts - i), kw): i
                for i in range(first_index, first_index + rollouts, size)}
        done: dict[int, EvalSummary] = {}
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            for r in ready:
                done[refs[r]] = ray.get(r)
                if on_range:
                    on_range(refs[r], done[refs[r]])
    finally:
        if started:
            ray.shutdown()
    head = done[min(done)]  # variant and mode as the checkpoint chose them
    return summarize(head.task, head.variant, head.mode, [r for i in sorted(done) for r in done[i].results])
