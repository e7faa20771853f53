"""A graph-mode distributed worker: its own node graph in its own ROS_DOMAIN_ID, driven by goals.

Each worker leases a ROS domain on its host (the same lock files as the test plugin's leases,
testing/domains.py, so two workers, or a worker and a test, never share one), starts the `datagen`
graph there with loopback-only discovery (`skillgen launch datagen`, the graph `skillgen generate`
uses), and runs each index range as one Generate goal (first_index, attempts) into a temp dir. The
graph dies with the worker (PR_SET_PDEATHSIG on the launcher); a graph that dies under a worker
ends the worker's process, so Ray restarts it and the driver re-runs the range (node lost).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from skillgen_ros import rosenv
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.generation.session import Progress
from skillgen_ros.core.validation import USE_DEFAULT
from skillgen_ros.testing.domains import LOCK_DIR, VALID_IDS, DomainLease, NoFreeDomainError, _try_lock
from skillgen_ros.testing.processes import die_with_parent

GRAPH_DIED_EXIT = 70  # a worker whose graph died exits with this (Ray restarts it)


def lease_domain(ids, start: int = 0) -> DomainLease:
    """A free ROS domain from `ids` on this host (round-robin from `start`), held while the worker lives."""
    ids = list(ids) or [i for i in VALID_IDS if i != int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)]
    for k in range(len(ids)):
        d = ids[(start + k) % len(ids)]
        fd = _try_lock(d)
        if fd is not None:
            return DomainLease(d, fd)
    raise NoFreeDomainError(f"every ROS domain of {ids[0]}..{ids[-1]} is held on this host (locks in {LOCK_DIR})")


class GraphRunner:
    def __init__(self, spec, req, worker: str):
        self.lease = lease_domain(spec.domain_ids, os.getpid())
        env = rosenv.ros_environment(os.environ)  # this worker process's own environment
        env["ROS_DOMAIN_ID"] = str(self.lease.id)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        params = ["--ros-args", "-p", f"datagen:observation_source:={req.observation_source}",
                  "-p", f"datagen:action_noise:={req.action_noise}",
                  "-p", "datagen:write_report:=false"]  # the driver writes the run's report
        self.proc = subprocess.Popen([sys.executable, "-m", "skillgen_ros.cli.main", "launch", spec.graph, *params],
                                     env=dict(env), start_new_session=True, preexec_fn=die_with_parent(os.getpid()))
        from skillgen_ros.client import SkillGenClient

        self.client = SkillGenClient(domain_id=self.lease.id, node_name=f"skillgen_{worker}")
        end = time.monotonic() + spec.startup_timeout
        while not self.client.wait_for_server(1.0):
            if self.proc.poll() is not None or time.monotonic() > end:
                self.close()
                raise SkillGenError(f"worker {worker}'s graph in ROS domain {self.lease.id} did not come up",
                                    reason="GRAPH_NOT_READY")

    def run(self, req, on_progress, should_stop) -> None:
        c = self.client
        c._feedback = None
        ok = c.generate(task=req.task, variant=req.variant, method=req.method, attempts=req.attempts,
                        target_successes=0, seed=req.seed, first_index=req.first_index, augment=req.augment,
                        augment_translation=req.augment_translation if req.augment else USE_DEFAULT,
                        augment_rotation_deg=req.augment_rotation_deg if req.augment else USE_DEFAULT,
                        selection=req.selection, source_demos=req.source_demos, output_dir=req.output_dir,
                        record_bag=False, video_attempts=0, initiation_candidates=req.initiation_candidates,
                        profile=req.profile)
        if not ok:
            raise SkillGenError("the worker's datagen rejected the goal (busy)", reason="REJECTED")
        canceled, seen = False, 0
        while not c.is_done():
            if self.proc.poll() is not None:
                print(f"graph died (exit {self.proc.returncode}); ending this worker", file=sys.stderr, flush=True)
                os._exit(GRAPH_DIED_EXIT)
            fb = c.feedback()
            if fb is not None and fb.attempts != seen:
                seen = fb.attempts
                on_progress(Progress(fb.attempts, fb.successes, req.attempts, fb.success_rate, fb.eta_seconds,
                                     fb.last_reason))
            if not canceled and should_stop():
                c.cancel()
                canceled = True
            time.sleep(0.05)
        res = c.result(timeout=60)
        if not res.accepted or res.reason not in ("OK", "CANCELED"):
            raise SkillGenError(f"worker graph: {res.message}", reason=res.reason or "WORKER_FAILED")

    def close(self) -> None:
        try:
            self.client.close()
        except Exception:  # noqa: BLE001 -- closing what may be half built
            pass
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
        self.lease.release()
