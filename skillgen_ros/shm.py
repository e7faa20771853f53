"""Fast DDS shared-memory files that no live process holds: what a SIGKILLed ROS process leaves behind.

rmw_fastrtps (the default RMW) talks between processes on one host through shared memory. Each
port and segment in /dev/shm has a lock file (`<name>_el` or `_sl`) its owner holds with flock
while it lives. A process killed with SIGKILL (a hung node stopped by force, a chaos test, a
killed launch) leaves its files behind, and eProsima documents that such leftovers can disturb
later participants (Fast-DDS issue 1144; their tool is `fastdds shm clean`, not on PyPI). Here,
after a day of killed test runs had left 227 such ports and segments, two nodes of a fresh graph
spent 30 minutes each with their Fast DDS send thread (`dds.asyn`) at 100% of a core and never
finished starting.

`clean_zombie_files()` removes only files whose lock nobody holds, the rule Fast DDS's own tool
uses; a file a live process uses is never touched. The test harness and `skillgen launch` call it
before they start nodes. Nor is a file younger than `min_age_s` (60 s): a process that is starting
has created its lock file but may not hold it yet, and two graphs launched together (two Ray
graph-mode workers, test_distributed_action) cleaned each other's fresh ports in that gap; the
spin above came back in both nodes of one worker (2026-12-04). Pure: no rclpy.
"""
from __future__ import annotations

import fcntl
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

SHM_DIR = Path("/dev/shm")
_SEGMENT_LOCK = re.compile(r"^fastrtps_[0-9a-z]{16}_(el|sl)$")
_PORT_LOCK = re.compile(r"^fastrtps_port\d{1,5}_(el|sl)$")


@dataclass(frozen=True)
class ShmCleanup:
    removed: int  # zombie ports and segments removed
    in_use: int   # ports and segments a live process holds


def _held(lock: Path) -> bool:
    """Whether a live process holds `lock` (exclusively or shared): our exclusive try-lock fails."""
    try:
        fd = os.open(lock, os.O_RDONLY)
    except OSError:
        return True  # gone or unreadable: leave it alone
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


def _unlink(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass


MIN_AGE_S = 60.0  # s: a port or segment younger than this may belong to a process still starting


def _young(paths, now: float, min_age_s: float) -> bool:
    for p in paths:
        try:
            if now - p.stat().st_mtime < min_age_s:
                return True
        except OSError:
            pass
    return False


def clean_zombie_files(shm_dir: Path = SHM_DIR, min_age_s: float = MIN_AGE_S) -> ShmCleanup:
    """Remove the Fast DDS ports and segments in `shm_dir` whose lock files no live process holds and
    that are at least `min_age_s` old (module docstring)."""
    try:
        names = os.listdir(shm_dir)
    except OSError:
        return ShmCleanup(0, 0)  # no /dev/shm (not Linux): Fast DDS keeps its files elsewhere
    locks: dict[str, list[str]] = {}  # port or segment name -> its lock files (_el and/or _sl)
    for name in names:
        if _PORT_LOCK.match(name) or _SEGMENT_LOCK.match(name):
            locks.setdefault(name[:-3], []).append(name)
    removed = in_use = 0
    now = time.time()
    for base, lock_names in sorted(locks.items()):
        files = [shm_dir / base] + [shm_dir / n for n in lock_names]
        if _young(files, now, min_age_s) or any(_held(shm_dir / n) for n in lock_names):
            in_use += 1
            continue
        _unlink(shm_dir / base)
        if base.startswith("fastrtps_port"):
            _unlink(shm_dir / f"sem.{base}_mutex")  # the port's named semaphore
        for n in lock_names:
            _unlink(shm_dir / n)
        removed += 1
    return ShmCleanup(removed, in_use)
