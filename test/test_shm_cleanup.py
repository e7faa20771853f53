"""skillgen_ros/shm.py: Fast DDS files a killed process left in /dev/shm are removed, held ones never."""
import fcntl
import os

from skillgen_ros.shm import clean_zombie_files


def test_only_files_no_live_process_holds_are_removed(tmp_path):
    seg_live, seg_dead = "fastrtps_0123456789abcdef", "fastrtps_fedcba9876543210"
    port_live, port_dead = "fastrtps_port7001", "fastrtps_port24163"
    for f in (seg_live, f"{seg_live}_el", seg_dead, f"{seg_dead}_el", port_live, f"{port_live}_sl",
              f"sem.{port_live}_mutex", port_dead, f"{port_dead}_el", f"sem.{port_dead}_mutex",
              "lttng-ust-wait-6", "fastrtps_port9_orphan"):
        (tmp_path / f).write_bytes(b"")
    for f in os.listdir(tmp_path):  # killed a while ago
        os.utime(tmp_path / f, (1e9, 1e9))
    held = []
    for lock, mode in ((f"{seg_live}_el", fcntl.LOCK_EX), (f"{port_live}_sl", fcntl.LOCK_SH)):
        fd = os.open(tmp_path / lock, os.O_RDONLY)  # what the owning process does while it lives
        fcntl.flock(fd, mode | fcntl.LOCK_NB)
        held.append(fd)
    try:
        got = clean_zombie_files(tmp_path)
    finally:
        for fd in held:
            os.close(fd)
    assert (got.removed, got.in_use) == (2, 2)
    assert sorted(os.listdir(tmp_path)) == sorted([
        seg_live, f"{seg_live}_el", port_live, f"{port_live}_sl", f"sem.{port_live}_mutex",
        "lttng-ust-wait-6", "fastrtps_port9_orphan"])  # other files and names are never touched


def test_a_missing_directory_is_nothing_to_clean(tmp_path):
    got = clean_zombie_files(tmp_path / "none")
    assert (got.removed, got.in_use) == (0, 0)


def test_fresh_files_are_kept_though_not_held_yet(tmp_path):
    """A starting process has created its port but may not hold the lock yet: a launch beside it (two Ray
    graph workers) must not remove it."""
    for f in ("fastrtps_port7002", "fastrtps_port7002_el", "fastrtps_0123456789abcdef", "fastrtps_0123456789abcdef_el"):
        (tmp_path / f).write_bytes(b"")
    os.utime(tmp_path / "fastrtps_0123456789abcdef", (1e9, 1e9))   # the segment old, its lock fresh: kept
    got = clean_zombie_files(tmp_path)
    assert (got.removed, got.in_use) == (0, 2) and len(os.listdir(tmp_path)) == 4
    got = clean_zombie_files(tmp_path, min_age_s=0.0)
    assert (got.removed, got.in_use) == (2, 0) and os.listdir(tmp_path) == []
