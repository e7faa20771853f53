"""`skillgen generate --workers N [--address A]`: one generation request over N Ray workers.

The driver (this process) schedules attempt-index ranges over the workers, writes the shards they
send back under <output>/shards/, and merges them in index order into demo.hdf5 / failed.hdf5 and
report.md: the same dataset a serial run with the same seed writes (docs/distributed.md). Ctrl-C
stops every worker, which abandons the attempt it is in at its next step; `--resume` with the same --output continues the run
without re-running a finished index. Ray is imported only on this path.
"""
from __future__ import annotations

import os
import signal
import sys

from skillgen_ros.core.errors import SkillGenError


def parse_domains(spec: str) -> tuple[int, ...]:
    """"A-B" or "A,B,C" -> domain ids (graph-mode workers lease theirs from these)."""
    if not spec:
        return ()
    try:
        if "-" in spec:
            a, b = (int(x) for x in spec.split("-"))
            ids = tuple(range(a, b + 1))
        else:
            ids = tuple(int(x) for x in spec.split(","))
    except ValueError:
        raise SkillGenError(f"--domain-ids wants A-B or A,B,..., got {spec!r}", reason="INVALID_ARGUMENT") from None
    if not ids or min(ids) < 0 or max(ids) > 232:
        raise SkillGenError(f"--domain-ids must lie in 0..232, got {spec!r}", reason="INVALID_ARGUMENT")
    return ids


class _StopOnSigint:
    """First Ctrl-C: stop the run (each worker abandons its attempt in flight); a second one: interrupt."""

    def __init__(self):
        self.reason = ""

    def __enter__(self):
        def on_sigint(_s, _f):
            if self.reason:
                raise KeyboardInterrupt
            self.reason = "CANCELED"
            print("\nstopping: every worker abandons the attempt it is in (Ctrl-C again to abort) ...",
                  file=sys.stderr)
        self._old = signal.signal(signal.SIGINT, on_sigint)
        return self

    def __exit__(self, *exc):
        signal.signal(signal.SIGINT, self._old)


def run_distributed_cli(a, req) -> int:
    from tqdm import tqdm

    from skillgen_ros.cli.generate import _print_result
    from skillgen_ros.core.distributed.ray_pool import RayPool, check_address
    from skillgen_ros.core.distributed.run import run_distributed
    from skillgen_ros.core.distributed.shards import ShardStore, pack_dir
    from skillgen_ros.core.distributed.worker import WorkerSpec
    from skillgen_ros.core.generation.session import validate_request
    from skillgen_ros.core.tasks import TASK_NAMES

    if a.workers < 1:
        raise SkillGenError(f"--workers must be >= 1, got {a.workers}", reason="INVALID_ARGUMENT")
    if a.resume and not a.output:
        raise SkillGenError("--resume needs the interrupted run's --output", reason="INVALID_ARGUMENT")
    check_address(a.address)  # INVALID_ADDRESS before anything starts
    validate_request(req, TASK_NAMES, check_output=not a.resume)
    store = ShardStore(req.output_dir).open(req, a.resume)  # OUTPUT_EXISTS / RESUME_MISMATCH before Ray starts
    spec = WorkerSpec(mode="in_process" if a.in_process else "graph", perception=a.perception,
                      startup_timeout=a.startup_timeout, domain_ids=parse_domains(a.domain_ids))
    demos = pack_dir(a.source_demos or os.path.join("bags", a.task))
    bar = tqdm(total=req.attempts, unit="attempt", dynamic_ncols=True, initial=len(store.done))
    shown: dict = {}

    def progress(p, statuses):
        bar.update(p.attempts - bar.n)
        bar.set_postfix(success=f"{p.successes}/{p.attempts}", rate=f"{100 * p.rate:.0f}%", workers=len(statuses))
        if a.verbose:
            for s in statuses:
                line = (f"{s.worker} pid {s.pid} on {s.host}{f' domain {s.domain}' if s.domain >= 0 else ''}: "
                        f"{s.total_attempts} attempts, {s.total_successes} "
                        f"successes, range {s.range or '-'}, last {s.last_reason or '-'}")
                if shown.get(s.worker) != line:
                    shown[s.worker] = line
                    bar.write(line)

    pool = RayPool(a.workers, spec, req, demos, address=a.address, dashboard=a.dashboard, verbose=a.verbose)
    try:
        with _StopOnSigint() as sig:
            run = run_distributed(pool, req, on_progress=progress, should_stop=lambda: sig.reason, store=store)
    finally:
        bar.close()
        pool.close()
    _print_result(run.attempts, run.successes, {k: v for k, v in run.failures.items() if v},
                  {"dataset": run.dataset_path, "failed": run.failed_path, "report": run.report_path,
                   "shards": str(store.dir)})
    print("workers: " + ", ".join(f"{w} {n}" for w, n in sorted(run.worker_attempts.items()))
          + (f"; {run.lost_ranges} range(s) re-run after a worker was lost" if run.lost_ranges else ""))
    if run.stopped_early:
        print(f"stopped ({run.stopped_early}): continue with `skillgen generate ... --output {req.output_dir} "
              "--resume`", file=sys.stderr)
    return 0
