"""The worker pool on Ray: local instance or an existing cluster, one actor per worker.

Ray is imported here and only here, and only when a run asks for workers > 1 or an address. A
local instance binds to 127.0.0.1 with the dashboard off unless asked (then on 127.0.0.1 too).
Each worker is a threaded actor around core/distributed/worker.RangeWorker; an actor whose
process dies (killed, OOM, its node lost) is restarted by Ray (max_restarts) and the range it was
running is handed out again by the driver (core/distributed/run.py), so Ray never re-runs a task
on its own (max_task_retries 0): the driver alone decides what runs, and records each index once.
"""
from __future__ import annotations

import os
import re
import socket
import time
from dataclasses import dataclass

from ..errors import SkillGenError
from .schedule import IndexRange
from .shards import ShardPayload

ACTOR_RESTARTS = 3  # per worker; a worker lost more often than this is dropped from the run
RESTART_TIMEOUT_S = 600.0  # a lost worker not back (env rebuilt) within this is dropped
# Ray starts its worker processes at nice 15. Beside anything at the user's priority (another
# training, a test suite) they then get ~1/28 of a core each: in-process attempts took 33-42 s
# instead of 1.5 s (bench/distributed --cancel, 2026-12-03). Our workers are the job, not
# background work: run them at the driver's priority, as Ray's own job supervisor does.
WORKER_RUNTIME_ENV = {"env_vars": {"RAY_worker_niceness": "0"}}
_ADDRESS = re.compile(r"^(?:ray://)?(\[[0-9a-fA-F:]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


class RayConnectError(SkillGenError):
    reason = "RAY_UNREACHABLE"


class WorkerLost(Exception):
    """A worker's process died while it ran a range."""


def check_address(address: str) -> tuple[str, int] | None:
    """None for "" / "auto"; (host, port) for host:port or ray://host:port; INVALID_ADDRESS otherwise."""
    if address in ("", "auto"):
        return None
    m = _ADDRESS.match(address)
    if not m or not 0 < int(m.group(2)) < 65536:
        raise SkillGenError(f"Ray address {address!r} is not 'auto', 'host:port' or 'ray://host:port'",
                            reason="INVALID_ADDRESS")
    return m.group(1).strip("[]"), int(m.group(2))


def connect(address: str = "", workers: int = 2, dashboard: bool = False, verbose: bool = False,
            timeout: float = 5.0) -> bool:
    """Start (address "") or join a Ray instance; True when this call started it (shut it down
    after). Already initialized (a test, the trainer): use that one."""
    if not address:  # Ray resolves 127.0.0.1 to the routable IP unless cluster mode is off: keep it on loopback
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    import ray

    if ray.is_initialized():
        return False
    hp = check_address(address)
    if hp is not None:  # a quick TCP check: ray.init would retry an unreachable head for a minute
        try:
            socket.create_connection(hp, timeout=timeout).close()
        except OSError as e:
            raise RayConnectError(f"cannot reach a Ray cluster at {address}: {e.strerror or e}") from None
    kw = dict(include_dashboard=dashboard, log_to_driver=verbose, logging_level="WARNING",
              configure_logging=True)
    try:
        if address:
            ray.init(address=address, **({} if address.startswith("ray://") else kw))
        else:
            # "local": a new instance even when another one runs on this host (ray.init() would join it)
            ray.init(address="local", num_cpus=max(workers, os.cpu_count() or 1), _node_ip_address="127.0.0.1",
                     dashboard_host="127.0.0.1", **kw)
    except Exception as e:  # noqa: BLE001 -- ray raises ConnectionError, RuntimeError, ValueError ...
        raise RayConnectError(f"cannot start or join Ray at {address or 'a local instance'}: "
                              f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}") from None
    return True


@dataclass
class _Slot:
    name: str
    actor: object
    ref: object = None  # the running range's result
    range: IndexRange | None = None
    started: float = 0.0
    losses: int = 0
    alive: bool = True
    probe: object = None  # after a loss: `ready` of the restarting actor; idle again once it answers
    retry_at: float = 0.0  # > 0: probe again at this time (the actor was still restarting)
    lost_at: float = 0.0


class RayPool:
    """N RangeWorker actors; submit ranges, poll finished ones, read status, stop them."""

    def __init__(self, workers: int, spec, req, demos_tar: bytes, address: str = "", dashboard: bool = False,
                 verbose: bool = False, ready_timeout: float = 600.0, should_abort=None):
        self._started = connect(address, workers, dashboard, verbose)  # before `import ray`: see connect
        import ray

        from .worker import RangeWorker

        self._ray = ray
        cls = ray.remote(RangeWorker).options(num_cpus=1, max_restarts=ACTOR_RESTARTS, max_task_retries=0,
                                              runtime_env=WORKER_RUNTIME_ENV,
                                              max_concurrency=4)
        self._tar = ray.put(demos_tar)  # held for the pool's life: a restarted actor reads it again
        self.slots = [_Slot(f"w{i}", cls.remote(f"w{i}", spec, req, self._tar)) for i in range(workers)]
        self.overhead: list[float] = []  # per range: driver-seen seconds - the worker's own
        self.run = ""  # the run being served (new_run): a stop reaches that run's ranges only
        try:
            self._await_ready(ready_timeout, should_abort)
        except BaseException:
            self.close()
            raise

    def _await_ready(self, timeout: float, should_abort=None) -> None:
        """Every worker built its env; should_abort() -> reason ends the wait (a canceled goal)."""
        ray = self._ray
        refs = {s.actor.ready.remote(): s for s in self.slots}
        end = time.monotonic() + timeout
        ready, pending = [], list(refs)
        while pending and time.monotonic() < end:
            why = should_abort() if should_abort else ""
            if why:
                raise SkillGenError(f"{why} while the workers started", reason=why)
            done, pending = ray.wait(pending, num_returns=len(pending), timeout=0.5)
            ready += done
        if pending:
            raise SkillGenError(f"{len(pending)} of {len(refs)} workers did not start in {timeout:g} s (not "
                                "enough CPUs in the cluster?)", reason="WORKERS_NOT_READY")
        for r in ready:
            try:
                ray.get(r)
            except Exception as e:  # noqa: BLE001 -- the worker's constructor raised: say why
                raise SkillGenError(f"worker {refs[r].name} failed to start: {_cause(e)}",
                                    reason=getattr(_inner(e), "reason", "WORKERS_NOT_READY")) from None

    @property
    def size(self) -> int:
        return sum(s.alive for s in self.slots)

    def idle(self) -> list[_Slot]:
        return [s for s in self.slots if s.alive and s.ref is None and s.probe is None and not s.retry_at]

    def busy(self) -> list[_Slot]:
        """Slots running a range or restarting after a loss (the driver waits for both)."""
        return [s for s in self.slots if s.ref is not None or s.probe is not None or s.retry_at]

    def new_run(self) -> None:
        """A run starts on this pool (one pool can serve several runs, one after the other)."""
        import uuid

        self.run, self.overhead = uuid.uuid4().hex, []

    def submit(self, slot: _Slot, r: IndexRange) -> None:
        slot.range, slot.started = r, time.perf_counter()
        slot.ref = slot.actor.run_range.remote(r.first, r.end, self.run)

    def poll(self, timeout: float) -> list[tuple[_Slot, IndexRange, ShardPayload | None]]:
        """Finished ranges: (slot, range, payload), payload None when the worker died (WorkerLost).
        A range that raised (a request-level error) raises here with its reason."""
        ray = self._ray
        now = time.monotonic()
        for s in self.slots:
            if s.retry_at and now >= s.retry_at:
                s.retry_at, s.probe = 0.0, s.actor.ready.remote()
        busy = {s.ref: s for s in self.slots if s.ref is not None}
        probes = {s.probe: s for s in self.slots if s.probe is not None}
        if not busy and not probes:
            time.sleep(min(timeout, 0.2)) if any(s.retry_at for s in self.slots) else None
            return []
        ready, _ = ray.wait(list(busy) + list(probes), num_returns=1, timeout=timeout)
        rest = [r for r in [*busy, *probes] if r not in ready]
        ready += ray.wait(rest, num_returns=len(rest), timeout=0)[0] if rest else []
        for ref in (r for r in ready if r in probes):
            self._recovered(probes[ref], ref)
        out = []
        for ref in (r for r in ready if r in busy):
            s = busy[ref]
            r, s.ref, s.range = s.range, None, None
            try:
                p = ray.get(ref)
                self.overhead.append(max(0.0, time.perf_counter() - s.started - p.seconds))
                out.append((s, r, p))
            except (ray.exceptions.RayActorError, ray.exceptions.WorkerCrashedError,
                    ray.exceptions.ObjectLostError):
                s.losses += 1
                s.alive = s.losses <= ACTOR_RESTARTS
                s.probe, s.lost_at = (s.actor.ready.remote() if s.alive else None), time.monotonic()
                out.append((s, r, None))
            except ray.exceptions.RayTaskError as e:
                raise SkillGenError(f"worker {s.name} failed: {_cause(e)}",
                                    reason=getattr(_inner(e), "reason", "WORKER_FAILED")) from None
        return out

    def _recovered(self, s: _Slot, ref) -> None:
        """A lost worker's probe answered: restarted (idle again), still restarting, or gone."""
        ray = self._ray
        s.probe = None
        try:
            ray.get(ref)
        except ray.exceptions.ActorUnavailableError:  # still restarting: ask again in a second
            s.alive = time.monotonic() - s.lost_at < RESTART_TIMEOUT_S
            s.retry_at = time.monotonic() + 1.0 if s.alive else 0.0
        except Exception:  # noqa: BLE001 -- died for good (restarts used up, or its constructor fails now)
            s.alive = False

    def statuses(self, timeout: float = 0.5) -> list:
        ray = self._ray
        refs = {s.actor.status.remote(): s for s in self.slots if s.alive}
        ready, _ = ray.wait(list(refs), num_returns=len(refs), timeout=timeout)
        out = []
        for r in ready:
            try:
                out.append(ray.get(r))
            except Exception:  # noqa: BLE001 -- a dead or restarting worker has no status now
                pass
        return sorted(out, key=lambda st: st.worker)

    def stop(self) -> None:
        for s in self.slots:
            if s.alive:
                s.actor.stop.remote(self.run)

    def close(self, timeout: float = 60.0) -> None:
        """Workers close their envs (a graph worker stops its graph), then the actors go."""
        refs = [s.actor.close.remote() for s in self.slots if s.alive and s.probe is None and not s.retry_at]
        if refs:
            self._ray.wait(refs, num_returns=len(refs), timeout=timeout)
        for s in self.slots:
            try:
                self._ray.kill(s.actor, no_restart=True)
            except Exception:  # noqa: BLE001 -- already gone
                pass
        if self._started:
            self._ray.shutdown()


def _inner(e: Exception) -> Exception:
    return getattr(e, "cause", None) or e


def _cause(e: Exception) -> str:
    c = _inner(e)
    return f"{type(c).__name__}: {c.args[0] if c.args else c}"
