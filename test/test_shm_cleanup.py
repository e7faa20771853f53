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
