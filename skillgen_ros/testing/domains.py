"""ROS_DOMAIN_ID allocation across pytest processes on one machine.

A domain is taken by holding an exclusive `flock` on `<tmp>/skillgen_ros_domains/<id>.lock`. The
kernel drops the lock when its file is closed or its process dies (even by SIGKILL), so there are
no stale locks, and two pytest processes (or xdist workers, or two suites side by side) never hold
the same ID. The lock is per open file, so a second lease in the same process is refused too.

The pool is every ID Fast DDS can use on one host without meeting the kernel's ephemeral port
range (0..101 and 215..232; 0, ROS's default, is left to the user's own graphs), or, when
SKILLGEN_TEST_DOMAIN_BASE is set, the ten IDs from that base: a suite pinned there cannot disturb
another one pinned elsewhere. Leases are handed out round-robin, so consecutive tests of one
process do not reuse the domain their predecessor's participants have only just left.
"""
from __future__ import annotations

import fcntl
import os
import tempfile
import threading
import time
from pathlib import Path

from skillgen_ros.core.errors import SkillGenError

BASE_ENV = "SKILLGEN_TEST_DOMAIN_BASE"
PINNED_SIZE = 10
VALID_IDS = (*range(1, 102), *range(215, 233))
LOCK_DIR = Path(tempfile.gettempdir()) / "skillgen_ros_domains"


class NoFreeDomainError(SkillGenError):
    reason = "NO_FREE_DOMAIN"


def domain_pool(env: dict | None = None) -> list[int]:
    """The IDs this process may use: SKILLGEN_TEST_DOMAIN_BASE's ten, or every usable ID."""
    env = os.environ if env is None else env
    base = env.get(BASE_ENV)
    if not base:
        return list(VALID_IDS)
    try:
        b = int(base)
    except ValueError:
        raise NoFreeDomainError(f"{BASE_ENV}={base!r} is not an integer", reason="INVALID_PARAMETER") from None
    ids = list(range(b, b + PINNED_SIZE))
    if b < 0 or not all(i in VALID_IDS or i == 0 for i in ids):
        raise NoFreeDomainError(f"{BASE_ENV}={b}: IDs {b}..{b + PINNED_SIZE - 1} must lie in 0..101 or "
                                "215..232 (Fast DDS ports beyond collide with ephemeral ports)",
                                reason="INVALID_PARAMETER")
    return ids


class DomainLease:
    """One held domain ID; `release()` (or process exit) frees it for every process."""

    def __init__(self, domain_id: int, fd: int):
        self.id = domain_id
        self._fd: int | None = fd

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the file drops the flock
            self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> "DomainLease":
        return self

    def __exit__(self, *_exc) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DomainLease({self.id}, held={self.held})"


def _try_lock(domain_id: int) -> int | None:
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    fd = os.open(LOCK_DIR / f"{domain_id}.lock", os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())  # who holds it, for a human looking at the dir
    return fd


class DomainAllocator:
    """Round-robin over the pool, skipping IDs another lease (any process) holds."""

    def __init__(self):
        self._lock = threading.Lock()
        self._cursor: int | None = None

    def acquire(self, timeout: float = 60.0, poll: float = 0.1) -> DomainLease:
        """A free domain; waits up to `timeout` s for another process to free one, then raises
        NO_FREE_DOMAIN naming the pool (waiting on the lock files' state, not on time)."""
        ids = domain_pool()
        end = time.monotonic() + timeout
        with self._lock:
            if self._cursor is None:
                self._cursor = os.getpid() % len(ids)
            while True:
                for k in range(len(ids)):
                    i = (self._cursor + k) % len(ids)
                    fd = _try_lock(ids[i])
                    if fd is not None:
                        self._cursor = i + 1
                        return DomainLease(ids[i], fd)
                if time.monotonic() >= end:
                    raise NoFreeDomainError(f"all {len(ids)} ROS domains {ids[0]}..{ids[-1]} are held by other "
                                            f"tests (locks in {LOCK_DIR}) for {timeout:g} s")
                time.sleep(poll)


ALLOCATOR = DomainAllocator()  # one per process: every fixture and next_domain_id() share it


def acquire_domain(timeout: float = 60.0) -> DomainLease:
    return ALLOCATOR.acquire(timeout)
