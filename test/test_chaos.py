"""Chaos (issue 19): during a `generate` run through the datagen graph on the simulated Panda
(`skillgen launch datagen --respawn`, the recorder on), kill -9 one process at a time: perception,
planner, the sim_driver + skill_replay container, the recorder, datagen itself.

Each kill must leave: a reason for every attempt, the one in flight included (its stage's reason
when it needed the dead node, or OK when a call safe to repeat was resent and the respawned node
answered it), both HDF5 files valid with every finished attempt once (demo.hdf5
= the successes), the bag readable up to its last chunk (recovered when the recorder died), and,
once the launcher has restarted the node, a run that goes on to new successes. Synchronisation is
on observable state only: the goal's feedback (attempt counter), the launcher's children, files.
The matrix's counts over several kills per node: bench/chaos/run.py.
"""
import os
import signal
import subprocess
import sys

import pytest

from conftest import REPO, node_env
from skillgen_ros.client import SkillGenClient
from skillgen_ros.core.generation.outcome import FailureReason
from skillgen_ros.testing import chaos

SKILLGEN = [sys.executable, "-m", "skillgen_ros.cli.main"]
SEED = 0
REASONS = {r.value for r in FailureReason}


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    from skillgen_ros.testing.domains import acquire_domain

    lease = acquire_domain()
    root = tmp_path_factory.mktemp("chaos")
    env = node_env(lease.id)
    log = open(root / "launch.log", "wb")  # the launcher's and every node's output, for a failure's post-mortem
    p = subprocess.Popen(SKILLGEN + ["launch", "datagen", "--respawn", "--ros-args", "-p",
                                     f"datagen:writable_roots:=['{root}']", *chaos.FAST_TIMEOUTS],
                         env=env, stdout=subprocess.DEVNULL, stderr=log, cwd=REPO, start_new_session=True)
    try:
        yield p, lease.id, root
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGINT)
            try:
                p.wait(60)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        log.close()
        lease.release()


def _client(dom: int) -> SkillGenClient:
    c = SkillGenClient(domain_id=dom)
    assert c.wait_for_server(600), "datagen did not come up"
    return c


@pytest.mark.parametrize("victim", chaos.VICTIMS)
def test_a_node_killed_mid_run_loses_nothing_and_the_run_goes_on(graph, victim):
    launcher, dom, root = graph
    rec = chaos.kill_mid_run(launcher.pid, lambda: _client(dom), victim, root / victim, seed=SEED,
                             stop_recording=lambda: chaos.stop_recording(dom))
    assert rec.survived, rec
    assert set(rec.reasons.values()) <= REASONS and rec.reasons, rec  # every attempt with a reason code
    assert rec.bag_messages > 0 and rec.bag_recovered == (victim == "recorder"), rec
    if victim == "datagen":  # the respawned datagen serves: go on from the next index in a new directory
        c = _client(dom)
        try:
            assert c.generate(timeout=120, seed=SEED, first_index=len(rec.reasons), output_dir=str(root / "next"),
                              **chaos.GOAL)
            res = c.result(timeout=1800)
        finally:
            c.close()
        assert res.accepted and res.reason == "OK" and res.successes == chaos.GOAL["target_successes"], res.message
        assert min(chaos.read_run(root / "next", len(rec.reasons)).reasons) == len(rec.reasons)
    else:
        assert rec.run_reason == "OK" and rec.successes_after >= 1, rec
