"""One distributed worker: runs index ranges of a request and returns each as a shard payload.

A worker holds its environment for the whole run (built once: the in-process SimGenerationEnv,
or a runner that starts its own node graph in its own ROS_DOMAIN_ID, skillgen_ros/graph_worker.py),
runs a range with the ordinary run loop (core/generation/session.run_generation, or a Generate goal
to its graph), and sends the range's files back as bytes. It knows nothing of Ray: ray_pool wraps
it in an actor (threaded, so `status` and `stop` answer while a range runs).
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import threading
import time
from dataclasses import dataclass

from ..generation.session import Progress, RunRequest
from .schedule import IndexRange
from .shards import ShardPayload, pack_shard, relocate_source_demos, unpack_dir

MODES = ("in_process", "graph")


@dataclass(frozen=True)
class WorkerSpec:
    """How every worker of a run builds its environment."""

    mode: str = "in_process"
    perception: str = "estimate"  # in_process: SimEnvConfig.perception
    startup_timeout: float = 120.0  # graph: seconds for a worker's graph to answer
    domain_ids: tuple[int, ...] = ()  # graph: ROS_DOMAIN_IDs workers on one host lease from (() = 1..101)
    graph: str = "datagen"  # graph: the graphs.yaml entry a worker launches


@dataclass(frozen=True)
class WorkerStatus:
    worker: str
    pid: int
    host: str
    range: tuple[int, int] | None  # the range running now
    attempts: int  # finished in the running range
    successes: int
    total_attempts: int  # over the whole run, this worker process
    total_successes: int
    last_reason: str
    domain: int = -1  # graph mode: the ROS_DOMAIN_ID of the worker's graph


class InProcessRunner:
    """The in-process env, built once per worker."""

    def __init__(self, spec: WorkerSpec, req: RunRequest):
        from ..generation.sim_env import SimEnvConfig, SimGenerationEnv
        from ..skills.bag_demos import expand_bag_paths, load_source_demos
        from ..tasks import get_task

        self.task = get_task(req.task)
        self.demos = load_source_demos(expand_bag_paths([req.source_demos]), self.task)
        self.env = SimGenerationEnv(SimEnvConfig(perception=spec.perception, seed=req.seed, video=False))

    def run(self, req: RunRequest, on_progress, should_stop) -> None:
        from ..generation.session import run_generation

        run_generation(self.env, self.demos, self.task, req, on_progress=on_progress, should_stop=should_stop,
                       write_report=False)

    def close(self) -> None:
        self.env.close()


def make_runner(spec: WorkerSpec, req: RunRequest, worker: str):
    if spec.mode == "in_process":
        return InProcessRunner(spec, req)
    from ...graph_worker import GraphRunner  # rclpy: only a graph-mode worker imports it

    return GraphRunner(spec, req, worker)


def _ignore_sigint() -> None:
    """A terminal's Ctrl-C reaches every process of its group, local Ray workers included; the
    driver stops workers itself (run_range returns the finished prefix), so they do not die of it."""
    import signal

    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: nothing to do
        pass


class RangeWorker:
    def __init__(self, worker: str, spec: WorkerSpec, req: RunRequest, demos_tar: bytes):
        _ignore_sigint()
        self.worker, self.spec = worker, spec
        self.tmp = tempfile.mkdtemp(prefix=f"skillgen_{worker}_")
        demos, self.origin = unpack_dir(demos_tar, self.tmp)
        self.req = dataclasses.replace(req, source_demos=demos, video_attempts=0,
                                       target_successes=0)
        self._stopped: set[str] = set()  # runs told to stop (a pool serves several runs: test, resume)
        self._lock = threading.Lock()
        self._range: tuple[int, int] | None = None
        self._done = self._succ = self._tot = self._tot_succ = 0
        self._last = ""
        self.runner = make_runner(spec, self.req, worker)

    def ready(self) -> int:
        return os.getpid()

    def stop(self, run: str = "") -> None:
        """End run `run`'s range now (the attempt in flight is abandoned at its next step and not
        returned); none of its ranges starts after this."""
        with self._lock:
            self._stopped.add(run)

    def status(self) -> WorkerStatus:
        import socket

        with self._lock:
            lease = getattr(self.runner, "lease", None)
            return WorkerStatus(self.worker, os.getpid(), socket.gethostname(), self._range, self._done,
                                self._succ, self._tot, self._tot_succ, self._last, lease.id if lease else -1)

    def _progress(self, p: Progress) -> None:
        with self._lock:
            self._tot += p.attempts - self._done
            self._tot_succ += p.successes - self._succ
            self._done, self._succ, self._last = p.attempts, p.successes, p.last_reason

    def run_range(self, first: int, end: int, run: str = "") -> ShardPayload:
        """Attempts first..end-1 of run `run` (fewer when stopped: the finished prefix), as a payload."""
        r = IndexRange(first, end)
        out = os.path.join(self.tmp, f"range_{first}_{end}_{time.monotonic_ns()}")
        with self._lock:
            self._range, self._done, self._succ = (first, end), 0, 0
        t0 = time.perf_counter()
        try:
            if run not in self._stopped:
                req = dataclasses.replace(self.req, first_index=first, attempts=end - first, output_dir=out)
                self.runner.run(req, self._progress, lambda: "CANCELED" if run in self._stopped else "")
            relocate_source_demos(out, self.req.source_demos, self.origin)
            return pack_shard(out, r, self.worker, time.perf_counter() - t0)
        finally:
            shutil.rmtree(out, ignore_errors=True)
            with self._lock:
                self._range = None

    def close(self) -> None:
        self.runner.close()
        shutil.rmtree(self.tmp, ignore_errors=True)
