"""skillgen_ros.testing.domains: lock-file ROS_DOMAIN_ID leases, unique across processes."""
from __future__ import annotations

import subprocess
import sys

import pytest

from skillgen_ros.testing import domains


@pytest.fixture
def lock_dir(tmp_path, monkeypatch):
    """A private lock directory: these tests hold whole pools without touching the real one."""
    monkeypatch.setattr(domains, "LOCK_DIR", tmp_path)
    return tmp_path


def test_pinned_pool_is_ten_ids_and_leases_are_unique_round_robin(lock_dir, monkeypatch):
    monkeypatch.setenv(domains.BASE_ENV, "70")
    alloc = domains.DomainAllocator()
    leases = [alloc.acquire(timeout=0.0) for _ in range(10)]
    assert sorted(lease.id for lease in leases) == list(range(70, 80))
    with pytest.raises(domains.NoFreeDomainError) as e:  # all ten held: a clear error, not a clash
        alloc.acquire(timeout=0.0)
    assert e.value.reason == "NO_FREE_DOMAIN" and "70..79" in str(e.value)
    freed = leases[3].id
    leases[3].release()
    again = domains.DomainAllocator().acquire(timeout=0.0)  # another allocator (as another process would)
    assert again.id == freed
    for lease in leases + [again]:
        lease.release()
    nxt = [alloc.acquire(timeout=0.0) for _ in range(2)]  # round robin: not the ID released last
    assert nxt[0].id != nxt[1].id
    for lease in nxt:
        lease.release()


def test_a_domain_held_by_another_process_is_skipped_until_that_process_dies(lock_dir, monkeypatch):
    monkeypatch.setenv(domains.BASE_ENV, "70")
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys; from skillgen_ros.testing import domains as d; d.LOCK_DIR = "
         f"__import__('pathlib').Path({str(lock_dir)!r}); ls = [d.acquire_domain(0.0) for _ in range(9)]; "
         "print(' '.join(str(x.id) for x in ls), flush=True); sys.stdin.read()"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        held = {int(x) for x in holder.stdout.readline().split()}
        assert len(held) == 9
        mine = domains.DomainAllocator().acquire(timeout=0.0)
        assert mine.id not in held and 70 <= mine.id < 80
        with pytest.raises(domains.NoFreeDomainError):
            domains.DomainAllocator().acquire(timeout=0.0)
        holder.kill()  # the kernel drops a dead process's locks: nothing stale
        holder.wait()
        assert domains.DomainAllocator().acquire(timeout=5.0).id in held
        mine.release()
    finally:
        holder.kill()
        holder.wait()


def test_unpinned_pool_avoids_ephemeral_port_domains_and_a_bad_base_is_refused(monkeypatch):
    monkeypatch.delenv(domains.BASE_ENV, raising=False)
    pool = domains.domain_pool()
    assert 0 not in pool and max(i for i in pool if i < 200) == 101 and min(i for i in pool if i > 101) == 215
    for bad in ("abc", "95", "-3"):
        monkeypatch.setenv(domains.BASE_ENV, bad)
        with pytest.raises(domains.NoFreeDomainError) as e:
            domains.domain_pool()
        assert e.value.reason == "INVALID_PARAMETER"


def test_ros_domain_fixture_sets_the_environment(ros_domain):
    import os

    assert os.environ["ROS_DOMAIN_ID"] == str(ros_domain)
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    pinned = os.environ.get(domains.BASE_ENV)
    if pinned:
        assert int(pinned) <= ros_domain < int(pinned) + 10
