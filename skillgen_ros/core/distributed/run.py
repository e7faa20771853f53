"""The driver of a distributed generation run: schedule ranges, collect shards, merge, report.

Same request, same result as core/generation/session.run_generation: the merged demo.hdf5 and
failed.hdf5 hold exactly the attempts a serial run would, in index order (only `timings` attributes
differ). The loop keeps every live worker busy with one range, persists each finished range before
counting it (shards.ShardStore), hands a dead worker's range to the next free worker, and on a stop
(Ctrl-C, a canceled goal) tells every worker to stop (the attempt in flight is abandoned at its next
step, generation/attempt.AttemptAborted) and keeps what they finished, so `--resume` continues from there.
"""
from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable

from ..errors import SkillGenError
from ..generation.session import Progress, RunRequest, RunResult
from .schedule import IndexScheduler
from .shards import ShardStore


@dataclass
class DistributedResult(RunResult):
    ran: list[int] = field(default_factory=list)  # indices this invocation ran (not resumed ones)
    lost_ranges: int = 0  # ranges whose worker died (re-run elsewhere)
    worker_attempts: dict = field(default_factory=dict)  # worker -> attempts it delivered
    overhead_seconds: list = field(default_factory=list)  # per range: driver round trip - worker time
    attempt_seconds: float = 0.0  # sum of the attempts' own times (this invocation)


def run_distributed(pool, req: RunRequest, resume: bool = False,
                    on_progress: Callable[[Progress, list], None] | None = None,
                    should_stop: Callable[[], str] | None = None, write_report: bool = True,
                    poll_s: float = 0.25, status_every_s: float = 1.0,
                    store: ShardStore | None = None) -> DistributedResult:
    """Run `req` on `pool` (ray_pool.RayPool or anything with its methods). on_progress(p, statuses)
    gets the aggregated progress and the workers' statuses; should_stop() -> reason stops the run."""
    store = store or ShardStore(req.output_dir).open(req, resume)
    pool.new_run()
    sched = IndexScheduler(req.first_index, req.attempts, pool.size, req.target_successes, store.done)
    out = DistributedResult(req)
    t0 = time.perf_counter()
    last_status, statuses, last_reason = 0.0, [], ""
    while not sched.complete:
        stop = should_stop() if should_stop else ""
        if stop and not out.stopped_early:
            out.stopped_early = stop
            pool.stop()
        if not out.stopped_early:
            for slot in pool.idle():
                r = sched.take()
                if r is None:
                    break
                pool.submit(slot, r)
        if not pool.busy():
            if out.stopped_early:
                break
            if pool.size == 0:
                raise SkillGenError("every worker was lost; finished attempts are kept, continue with --resume",
                                    reason="WORKERS_LOST")
        for slot, r, payload in pool.poll(poll_s):
            if payload is None:
                sched.release(r)
                out.lost_ranges += 1
                continue
            if not payload.records and not out.stopped_early:  # never loop on a worker that runs nothing
                raise SkillGenError(f"worker {payload.worker} returned range {r.first}..{r.end - 1} without running it",
                                    reason="WORKER_FAILED")
            store.add(payload)
            sched.finish(r, payload.indices)
            out.ran += sorted(payload.indices)
            out.worker_attempts[payload.worker] = out.worker_attempts.get(payload.worker, 0) + len(payload.records)
            out.attempt_seconds += payload.attempt_seconds
            if payload.records:
                last_reason = payload.records[-1].reason.value
        now = time.perf_counter()
        if on_progress and (now - last_status >= status_every_s or sched.complete):
            statuses, last_status = pool.statuses(), now
            on_progress(_progress(sched, statuses, req, now - t0, last_reason), statuses)
    out.wall_seconds = time.perf_counter() - t0
    out.overhead_seconds = list(getattr(pool, "overhead", []))
    return _finish(out, store, sched, req, write_report)


def _progress(sched: IndexScheduler, statuses: list, req: RunRequest, elapsed: float, last: str) -> Progress:
    """Finished attempts over all workers (journaled + those in running ranges)."""
    kept = sched.kept()
    running = sum(s.attempts for s in statuses if s.range)
    done = len(kept) + running
    succ = sum(sched.done[i] for i in kept) + sum(s.successes for s in statuses if s.range)
    remaining = req.attempts - done if not req.target_successes else \
        min(req.attempts - done, (req.target_successes - succ) / max(succ / max(done, 1), 1e-3))
    return Progress(done, succ, req.attempts, succ / done if done else 0.0,
                    elapsed / done * max(remaining, 0) if done else 0.0,
                    last or next((s.last_reason for s in statuses if s.last_reason), ""))


def _finish(out: DistributedResult, store: ShardStore, sched: IndexScheduler, req: RunRequest,
            write_report: bool) -> DistributedResult:
    kept = sched.kept()
    out.results = [store.records[i] for i in kept]
    out.failures = Counter(r.reason.value for r in out.results if not r.success)
    out.dataset_path, out.failed_path = store.merge(kept)
    if write_report and out.results and not out.stopped_early:  # reports are never overwritten: once, at the end
        from ..dataset.report import RunSummary, write_report as _write_report

        cfg = req.config()
        summary = RunSummary.from_results(req.task, req.variant, req.method, out.results, req.augment,
                                          out.wall_seconds, {"dataset": out.dataset_path, "failed": out.failed_path},
                                          profile=cfg.profile)
        out.report_path = _write_report(req.output_dir, [summary])
    return out
